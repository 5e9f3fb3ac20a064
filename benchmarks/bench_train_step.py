"""Benchmark: one training step of our YOLO on the CPU, float32 against bfloat16 autocast (``train --amp``).

A step is what ``zebra-sim train`` does per batch: channels-last forward, loss in float32, backward, SGD step.
Random images and a few boxes (speed does not depend on the content), batch 16 at 640x640 by default. The two
precisions run interleaved in the same process, after a warm-up, and the report is the median step time of
each and their ratio. The data loader's cost is not included (it runs in the workers beside the step).

    python benchmarks/bench_train_step.py [--model n] [--imgsz 640] [--batch 16] [--repeats 8] [--json]
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import time
from collections.abc import Callable
from typing import Any

import torch

from zebra_sim_ros.detection.checkpoint import serving_layout
from zebra_sim_ros.detection.loss import DetectionLoss
from zebra_sim_ros.detection.model import ModelConfig, build_model


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--model", default="n")
    ap.add_argument("--imgsz", type=int, default=640)
    ap.add_argument("--batch", type=int, default=16)
    ap.add_argument("--repeats", type=int, default=8)
    ap.add_argument("--threads", type=int, default=os.cpu_count() or 1)
    ap.add_argument("--compile", action="store_true", help="also time bfloat16 steps of torch.compile(model)")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    torch.set_num_threads(args.threads)
    torch.manual_seed(0)
    model = serving_layout(build_model(ModelConfig(size=args.model, imgsz=args.imgsz))).train()
    criterion = DetectionLoss(model)
    opt = torch.optim.SGD(model.parameters(), lr=1e-3, momentum=0.9)
    x = torch.rand(args.batch, 3, args.imgsz, args.imgsz).contiguous(memory_format=torch.channels_last)
    s = args.imgsz
    targets = torch.tensor([[i, 0, s * 0.2 + 7 * k, s * 0.3, s * 0.2 + 7 * k + 24, s * 0.3 + 18]
                            for i in range(args.batch) for k in range(6)], dtype=torch.float32)

    def step(dtype: torch.dtype | None, net: Callable[[torch.Tensor], Any] = model) -> float:
        t0 = time.perf_counter()
        with torch.autocast("cpu", dtype=dtype or torch.bfloat16, enabled=dtype is not None):
            feats = net(x)
        loss, _ = criterion([f.float() for f in feats], targets)
        opt.zero_grad(set_to_none=True)
        loss.backward()
        opt.step()
        return time.perf_counter() - t0

    modes: dict[str, tuple[torch.dtype | None, Callable[[torch.Tensor], Any]]] = {"float32": (None, model),
                                                                    "bfloat16": (torch.bfloat16, model)}
    compile_s = None
    if args.compile:  # the same parameters through inductor; its first steps compile (timed apart)
        compiled = torch.compile(model)
        t0 = time.perf_counter()
        for _ in range(2):
            step(torch.bfloat16, compiled)
        compile_s = time.perf_counter() - t0
        modes["bfloat16+compile"] = (torch.bfloat16, compiled)
    times: dict[str, list[float]] = {k: [] for k in modes}
    for _ in range(2):  # warm-up: oneDNN picks and caches its kernels per shape and dtype
        for d, net in modes.values():
            step(d, net)
    for _ in range(args.repeats):
        for name, (d, net) in modes.items():
            times[name].append(step(d, net))
    med = {k: statistics.median(v) for k, v in times.items()}
    result = {
        "machine": f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores, torch {torch.__version__}",
        "bf16_instructions": bool(torch.cpu._is_avx512_bf16_supported() or torch.cpu._is_amx_tile_supported()),
        "model": args.model, "imgsz": args.imgsz, "batch": args.batch, "repeats": args.repeats,
        "step_s_median": {k: round(v, 3) for k, v in med.items()},
        "images_per_s": {k: round(args.batch / v, 2) for k, v in med.items()},
        "speedup_bf16": round(med["float32"] / med["bfloat16"], 2),
    }
    if compile_s is not None:
        result["compile_s"] = round(compile_s, 1)
        result["speedup_compile_over_bf16"] = round(med["bfloat16"] / med["bfloat16+compile"], 2)
    if args.json:
        print(json.dumps(result, indent=1))
    else:
        for k, v in med.items():
            print(f"{k:9s} {v * 1000:8.0f} ms per step, {args.batch / v:6.2f} images/s")
        print(f"bfloat16 autocast: {result['speedup_bf16']}x float32")
        if compile_s is not None:
            print(f"torch.compile: {result['speedup_compile_over_bf16']}x eager bfloat16, after {compile_s:.0f} s "
                  "of compilation")


if __name__ == "__main__":
    main()
