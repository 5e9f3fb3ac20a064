"""Benchmark: detector inference latency per 640x640 image on the CPU, ours in torch against onnxruntime.

For the nano and small models (random weights: latency does not depend on them): median milliseconds of one
forward pass (batch 1, decode included, NMS excluded) in torch as the detector serves it (batch norms folded,
channels-last), in torch with the default NCHW layout, and in onnxruntime on the same exported model, in the
same run, interleaved, with the same thread count. Goal: nano under 80 ms; torch within 1.3x of onnxruntime.

    python benchmarks/bench_detect.py [--repeats 30] [--threads 2] [--json]
"""

from __future__ import annotations

import argparse
import copy
import json
import os
import platform
import statistics
import tempfile
import time
from collections.abc import Callable
from functools import partial
from pathlib import Path

import torch

from zebra_sim_ros.detection.checkpoint import save_checkpoint, serving_layout
from zebra_sim_ros.detection.export import export_onnx
from zebra_sim_ros.detection.model import ModelConfig, build_model, count_parameters


def served(model: torch.nn.Module, x: torch.Tensor) -> object:
    """A forward pass as ``detect`` runs one: the batch turned channels-last first."""
    return model(x.contiguous(memory_format=torch.channels_last))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=30)
    ap.add_argument("--threads", type=int, default=os.cpu_count() or 1)
    ap.add_argument("--imgsz", type=int, default=640)
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    import onnxruntime as ort

    torch.set_num_threads(args.threads)
    results = {}
    x = torch.rand(1, 3, args.imgsz, args.imgsz)
    with tempfile.TemporaryDirectory() as tmp:
        for size in ("n", "s"):
            model = build_model(ModelConfig(size=size, imgsz=args.imgsz)).eval()
            save_checkpoint(Path(tmp) / f"{size}.pt", model)
            model.fuse()  # as load_model serves it
            nchw = copy.deepcopy(model)
            model = serving_layout(model)
            onnx_path = export_onnx(Path(tmp) / f"{size}.pt", Path(tmp) / f"{size}.onnx")
            so = ort.SessionOptions()
            so.intra_op_num_threads = args.threads
            sess = ort.InferenceSession(str(onnx_path), so, providers=["CPUExecutionProvider"])
            xn = x.numpy()
            times_t: list[float] = []
            times_n: list[float] = []
            times_o: list[float] = []
            with torch.inference_mode():
                for _ in range(3):
                    model(x.contiguous(memory_format=torch.channels_last))
                    nchw(x)
                    sess.run(None, {"images": xn})
                runs: list[tuple[list[float], Callable[[], object]]] = [
                    (times_t, partial(served, model, x)),  # the layout change is timed
                    (times_n, partial(nchw, x)), (times_o, partial(sess.run, None, {"images": xn}))]
                for i in range(args.repeats):  # interleaved in a rotating order, with a pause before each run:
                    for times, run in runs[i % 3:] + runs[:i % 3]:  # onnxruntime's threads spin after a run and
                        time.sleep(0.1)                              # would slow (2x) whatever runs right after
                        t0 = time.perf_counter()
                        run()
                        times.append(time.perf_counter() - t0)
            mt, mo = statistics.median(times_t) * 1000, statistics.median(times_o) * 1000
            mn = statistics.median(times_n) * 1000
            results[size] = {"parameters_m": round(count_parameters(model) / 1e6, 2), "torch_ms": round(mt, 1),
                             "torch_nchw_ms": round(mn, 1), "onnxruntime_ms": round(mo, 1),
                             "ratio_torch_over_onnx": round(mt / mo, 2)}
            print(f"{size}: torch {mt:.1f} ms (NCHW {mn:.1f} ms), onnxruntime {mo:.1f} ms, ratio {mt / mo:.2f} "
                  f"({count_parameters(model) / 1e6:.1f} M parameters)")
    if args.json:
        print(json.dumps({"benchmark": "detector_latency", "imgsz": args.imgsz, "threads": args.threads,
                          "torch": torch.__version__, "onnxruntime": ort.__version__,
                          "machine": f"{platform.machine()} cpus={os.cpu_count()}", "results": results}))


if __name__ == "__main__":
    main()
