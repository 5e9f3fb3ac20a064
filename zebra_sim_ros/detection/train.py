"""Training from scratch: SGD with warm-up and a cosine schedule, EMA weights, mixed precision on GPU,
best and last checkpoints, resume, a results table and plot. Under ``torchrun`` it trains with
DistributedDataParallel (one process per GPU); the same command runs alone on a CPU or one GPU.
"""

from __future__ import annotations

import copy
import csv
import datetime
import math
import os
import sys
import time
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
import torch
from torch import nn
from torch.utils.data import DataLoader, DistributedSampler

from zebra_sim_ros.detection.checkpoint import (
    amp_dtype,
    check_imgsz,
    read_checkpoint,
    save_checkpoint,
    select_device,
    serving_layout,
)
from zebra_sim_ros.detection.config import AMP_MODES
from zebra_sim_ros.detection.data import Augment, YoloDataset, collate, generate_settings, resolve_splits
from zebra_sim_ros.detection.evaluate import make_loader, predictions, score, write_plots
from zebra_sim_ros.detection.loss import DetectionLoss
from zebra_sim_ros.detection.model import (
    OTHER_ANIMAL,
    WIDENS,
    Detector,
    ModelConfig,
    Widening,
    build_model,
    count_parameters,
    p2_tensors,
    state_digest,
    widen_state,
)
from zebra_sim_ros.errors import ParameterError


@dataclass(frozen=True)
class TrainConfig:
    """Settings of a run (all recorded in the checkpoints)."""

    data: str
    out: str
    model: str = "n"
    imgsz: int = 640
    crop: int = 0  # train on crop x crop windows around zebras of the imgsz samples (0: whole samples)
    epochs: int = 100
    batch: int = 16
    device: str = "auto"
    workers: int = 2
    lr0: float = 0.01
    lrf: float = 0.01
    momentum: float = 0.937
    weight_decay: float = 5e-4
    warmup_epochs: float = 3.0
    close_mosaic: int = 10
    seed: int = 0
    val_every: int = 1
    save_period: float = 0.0  # s: last.pt after the first epoch, the last one and any that ends this many seconds
    # after the last save (0: after every epoch); for runs of many short epochs, where saving is most of an epoch
    max_train_images: int = 0  # 0 = all
    augment: bool = True  # False: letterbox only (for overfitting tests and debugging)
    aug: Augment = field(default_factory=Augment)  # the augmentation strengths (zebra-sim train --aug-<name>)
    resume: bool = False
    init: str = ""  # start from this checkpoint's (EMA) weights with a fresh schedule; "" = random init
    amp: str = "auto"  # mixed precision of the forward pass: auto, fp16 (CUDA), bf16, off (see amp_dtype)
    dont_care: bool = True  # the sets' ignore/ boxes are neither zebra nor background in the loss (see loss.py)
    other_animals: bool = False  # a second class, other_animal: generated frames' animals of other species
    p2: bool = False  # a fourth, stride-4 output level for small zebras (ModelConfig.p2)

    def classes(self) -> tuple[str, ...]:
        """The model's class names: zebra, and other_animal with ``other_animals``."""
        return ("zebra", OTHER_ANIMAL) if self.other_animals else ("zebra",)

    def check(self) -> None:
        """Raise :class:`ParameterError` naming the first bad setting."""
        if self.epochs < 1:
            raise ParameterError("--epochs", self.epochs, ">= 1")
        if self.batch < 1:
            raise ParameterError("--batch", self.batch, ">= 1")
        check_imgsz("--imgsz", self.imgsz)
        if self.crop and not (self.crop % 32 == 0 and 64 <= self.crop < self.imgsz):
            raise ParameterError("--crop", self.crop, f"0 (off) or a multiple of 32 from 64 to below --imgsz "
                                                      f"({self.imgsz})")
        for name, value, ok, allowed in (("--workers", self.workers, self.workers >= 0, ">= 0"),
                                         ("--val-every", self.val_every, self.val_every >= 1, ">= 1"),
                                         ("--save-period", self.save_period, 0 <= self.save_period <= 86400,
                                          "0..86400 s (0: after every epoch)"),
                                         ("--close-mosaic", self.close_mosaic, self.close_mosaic >= 0, ">= 0"),
                                         ("--warmup-epochs", self.warmup_epochs, 0 <= self.warmup_epochs <= 1000,
                                          "0..1000"),
                                         ("--max-train-images", self.max_train_images, self.max_train_images >= 0,
                                          ">= 0 (0: all)"),
                                         ("--lr0", self.lr0, 0 < self.lr0 <= 1, "0 < lr0 <= 1")):
            if not ok:
                raise ParameterError(name, value, allowed)
        if self.amp not in AMP_MODES:
            raise ParameterError("--amp", self.amp, " or ".join(AMP_MODES))
        self.aug.check()
        if self.init and self.resume:
            raise ParameterError("--init", self.init, "empty when --resume is given (resume continues its own run)")


class EMA:
    """Exponential moving average of the weights, with a warm-up of the decay (as YOLO does)."""

    def __init__(self, model: Detector, decay: float = 0.9999, tau: float = 2000.0, updates: int = 0) -> None:
        self.ema: Detector = copy.deepcopy(model).eval()
        for p in self.ema.parameters():
            p.requires_grad_(False)
        self.decay, self.tau, self.updates = decay, tau, updates
        self._pairs: list[tuple[torch.Tensor, torch.Tensor]] | None = None

    @torch.no_grad()
    def update(self, model: nn.Module) -> None:
        self.updates += 1
        d = self.decay * (1 - math.exp(-self.updates / self.tau))
        if self._pairs is None:  # the tensors stay the same objects (loading a state dict copies into them)
            msd = model.state_dict()
            self._pairs = [(v, msd[k]) for k, v in self.ema.state_dict().items() if v.dtype.is_floating_point]
        for e, m in self._pairs:
            e.mul_(d).add_(m.detach(), alpha=1 - d)


# What a resumed run may change: its length, how often it validates and saves, the machine it runs on. Every other
# setting shapes the run (the schedule, the augmentation, the data) and must be what it was.
RESUME_MAY_CHANGE = ("epochs", "device", "workers", "amp", "val_every", "save_period")


def check_resume(cfg: TrainConfig, recorded: dict[str, Any], last: Path) -> None:
    """Raise :class:`ParameterError` naming the first setting of ``cfg`` that differs from the run's recorded
    ``train_args`` (other than :data:`RESUME_MAY_CHANGE`); the data are compared as resolved paths."""
    settings = asdict(cfg)
    aug = settings.pop("aug")
    recorded = {**recorded, **{f"aug_{k}": v for k, v in (recorded.get("aug") or {}).items()}}
    for name, value in (settings | {f"aug_{k}": v for k, v in aug.items()}).items():
        if name in (*RESUME_MAY_CHANGE, "resume", "init", "out") or name not in recorded:
            continue
        was = recorded[name]
        same = (Path(value).resolve() == Path(was).resolve()) if name == "data" else value == was
        if not same:
            raise ParameterError(_flag(name), value,
                                 f"{was!r}, as the run in {last.parent} was started with (--resume continues "
                                 f"that run; only {', '.join(_flag(n) for n in RESUME_MAY_CHANGE)} may change)")


def _flag(name: str) -> str:
    """The command-line flag of a :class:`TrainConfig` field."""
    return f"--{name.replace('_', '-')}"


def _is_main() -> bool:
    return int(os.environ.get("RANK", "0")) == 0


def _init_device(cfg: TrainConfig) -> tuple[torch.device, bool]:
    """This process's device, and whether it is one of several under torchrun (then the process group is up)."""
    if int(os.environ.get("WORLD_SIZE", "1")) <= 1:
        return select_device(cfg.device), False
    # Rank 0 validates while the others wait at the next step's all-reduce: allow a long validation.
    torch.distributed.init_process_group("nccl" if torch.cuda.is_available() else "gloo",
                                         timeout=datetime.timedelta(hours=2))
    local = int(os.environ.get("LOCAL_RANK", "0"))
    device = torch.device(f"cuda:{local}") if torch.cuda.is_available() else torch.device("cpu")
    if device.type == "cuda":
        torch.cuda.set_device(device)
    return device, True


def _train_set(cfg: TrainConfig, train_dir: list[Path]) -> YoloDataset:
    """The training images, augmented unless ``cfg.augment`` is off, cut to ``max_train_images``."""
    ds = YoloDataset(train_dir, cfg.imgsz, cfg.aug if cfg.augment else Augment.none(), seed=cfg.seed,
                     dont_care=cfg.dont_care, crop=cfg.crop, other_class=1 if cfg.other_animals else None)
    if cfg.max_train_images:
        ds.files = ds.files[: cfg.max_train_images]
    if cfg.other_animals or (cfg.augment and cfg.aug.background > 0):
        ds.read_other_boxes()  # once, here: the loader's workers restart each epoch and would read them again
    return ds


@dataclass
class _Start:
    """Where a run starts: epoch 0 (random or ``--init`` weights), or where the run it resumes stopped."""

    epoch: int = 0
    best: float = -1.0
    ema_updates: int = 0
    optimizer: dict[str, Any] | None = None
    ema_weights: dict[str, Any] | None = None
    init: str = ""  # the weights the run started from (a resumed run keeps what its first start recorded)
    widened: Widening | None = None  # the narrower checkpoint the weights were widened from, and the seed


def _load_weights(cfg: TrainConfig, model: Detector, out: Path, log: Any) -> _Start:
    """Load ``--init`` weights, or the resumed run's raw weights, into ``model``; where the run starts."""
    widened: Widening | None = None
    if cfg.init:
        init = read_checkpoint(cfg.init, "--init")
        size = init["config"].get("size")
        if size != cfg.model and WIDENS.get(size) != cfg.model:
            raise ParameterError("--init", cfg.init, f"a checkpoint of model size {cfg.model!r}"
                                 f"{''.join(f' or {a!r}' for a, b in WIDENS.items() if b == cfg.model)} "
                                 f"(it holds {size!r})")
        if list(init["config"].get("names", ["zebra"])) != list(model.cfg.names[: init["config"].get("nc", 1)]):
            raise ParameterError("--init", cfg.init, f"a checkpoint whose classes begin {list(model.cfg.names)} "
                                 f"(it holds {init['config'].get('names')}; --other-animals adds other_animal)")
        if init["config"].get("p2", False) and not cfg.p2:
            raise ParameterError("--init", cfg.init, "a checkpoint without the stride-4 level (it has one: "
                                 "add --p2 to train it)")
        state = init["model"]
        # a run from a widened run's checkpoint carries its record on
        widened = Widening.from_dict(init.get("widened"), "--init", cfg.init)
        if size != cfg.model:  # a narrower checkpoint: the same function in the wider model, the shares by the seed
            widened = Widening(cfg.init, str(size), cfg.seed, state_digest(state))
            state = widen_state(state, init["config"], cfg.model, cfg.seed)
            if _is_main():
                print(f"[train] --init {cfg.init}: the {size} weights widened to {cfg.model} (the same function; "
                      f"the copies' shares drawn with seed {cfg.seed})", file=log)
        grown = load_init_weights(model, state)
        if grown and _is_main():
            kept = init["config"].get("nc", 1)
            print(f"[train] --init {cfg.init}: {', '.join(model.cfg.names[:kept])} from it, "
                  f"{', '.join(model.cfg.names[kept:])} start fresh (the class outputs: {len(grown)} tensors)",
                  file=log)
        if cfg.p2 and not init["config"].get("p2", False) and _is_main():
            print(f"[train] --init {cfg.init}: strides 8-32 from it, the stride-4 level "
                  f"({', '.join(Detector.P2_MODULES)}) starts fresh", file=log)
    if not cfg.resume:
        return _Start(init=cfg.init, widened=widened)
    ckpt = read_checkpoint(out / "last.pt", "--resume")
    check_resume(cfg, ckpt.get("train_args", {}), out / "last.pt")
    model.load_state_dict(ckpt["model_raw"])
    start_epoch = ckpt["epoch"] + 1
    if start_epoch >= cfg.epochs:
        raise ParameterError("--epochs", cfg.epochs, f"more than the {start_epoch} epochs the run in {out} has done")
    widened = Widening.from_dict(ckpt.get("widened"), "--resume", str(out / "last.pt"))
    return _Start(start_epoch, ckpt.get("best_fitness", -1.0), ckpt.get("ema_updates", 0), ckpt.get("optimizer"),
                  ckpt["model"], str(ckpt.get("train_args", {}).get("init", "")), widened)


def load_init_weights(model: Detector, state: dict[str, Any]) -> list[str]:
    """Load ``--init`` weights into ``model``. A checkpoint with fewer classes (a zebra-only one into a model with
    other_animal) fills the first rows of the class outputs, whose other rows keep their fresh initialisation (the
    prior bias); a checkpoint without the stride-4 level into a model with one (``p2``) leaves that level's
    modules fresh; every other tensor must match. Returns the names of the tensors filled in part."""
    own = model.state_dict()
    if model.cfg.p2 and not p2_tensors(state):
        state = {**state, **{k: own[k] for k in p2_tensors(own)}}
    grown = []
    for k, v in state.items():
        if k in own and v.shape != own[k].shape and v.shape[1:] == own[k].shape[1:] and v.shape[0] < own[k].shape[0] \
                and k.startswith("cls_head."):
            own[k][: v.shape[0]] = v.float()
            grown.append(k)
    model.load_state_dict({**{k: v.float() for k, v in state.items() if k not in grown},
                           **{k: own[k] for k in grown}})
    return grown


def _optimizer(model: Detector, cfg: TrainConfig, state: dict[str, Any] | None) -> torch.optim.SGD:
    """SGD with Nesterov momentum; weight decay on weights only (not on biases and norm parameters)."""
    decay: list[nn.Parameter] = []
    no_decay: list[nn.Parameter] = []
    for name, p in model.named_parameters():
        (no_decay if p.ndim <= 1 or name.endswith(".bias") else decay).append(p)
    groups = [{"params": decay, "weight_decay": cfg.weight_decay}, {"params": no_decay, "weight_decay": 0.0}]
    opt = torch.optim.SGD(groups, lr=cfg.lr0, momentum=cfg.momentum, nesterov=True)
    if state is not None:
        opt.load_state_dict(state)
    return opt


def _train_loader(ds: YoloDataset, cfg: TrainConfig,
                  distributed: bool) -> tuple[DataLoader[Any], DistributedSampler[Any] | None]:
    """The shuffled, seeded batches of ``ds`` (this process's share of them under torchrun) and the sampler."""
    sampler: DistributedSampler[Any] | None = DistributedSampler(ds, seed=cfg.seed) if distributed else None
    loader = DataLoader(ds, batch_size=cfg.batch, shuffle=sampler is None, sampler=sampler, num_workers=cfg.workers,
                        collate_fn=collate, drop_last=(len(sampler) if sampler else len(ds)) >= 2 * cfg.batch,
                        generator=torch.Generator().manual_seed(cfg.seed))  # workers restart each epoch: they must see
    # the dataset's new epoch (augmentation seeds) and, for the last epochs, mosaic switched off
    return loader, sampler


@dataclass
class _Run:
    """What one training process carries from step to step and epoch to epoch."""

    cfg: TrainConfig
    out: Path
    log: Any
    device: torch.device
    model: Detector  # the raw model: the EMA's source, clipped, checkpointed as model_raw
    net: nn.Module  # the model, or its DistributedDataParallel wrapper
    ema: EMA
    opt: torch.optim.SGD
    criterion: DetectionLoss
    autocast: torch.dtype | None
    scaler: torch.amp.GradScaler
    best: float
    rows: list[dict[str, Any]]
    data_generate: dict[str, Any] | None  # the training set's generate settings (read once, kept in checkpoints)
    widened: Widening | None  # where the weights were widened from (_Start.widened), kept in checkpoints
    saved_at: float | None = None  # perf_counter time of this process's last save of last.pt (None: not yet)

    def step(self, imgs: torch.Tensor, targets: torch.Tensor) -> torch.Tensor:
        """One optimisation step on a batch (imgs (B, 3, H, W)); the loss components [box, cls, dfl] on the CPU."""
        imgs = imgs.to(self.device, non_blocking=True).contiguous(memory_format=torch.channels_last)
        targets = targets.to(self.device)
        with torch.autocast(device_type=self.device.type, dtype=self.autocast, enabled=self.autocast is not None):
            feats = self.net(imgs)
        loss, parts = self.criterion([f.float() for f in feats], targets)
        self.opt.zero_grad(set_to_none=True)
        self.scaler.scale(loss).backward()
        self.scaler.unscale_(self.opt)
        nn.utils.clip_grad_norm_(self.model.parameters(), 10.0)
        self.scaler.step(self.opt)
        self.scaler.update()
        self.ema.update(self.model)
        return parts.cpu()


def _set_lr(opt: torch.optim.SGD, cfg: TrainConfig, epoch: int, it: int, warmup: int) -> None:
    """The epoch's cosine learning rate; during the first ``warmup`` iterations a linear ramp of it and the momentum."""
    lr_cos = cfg.lr0 * (((1 - math.cos(epoch * math.pi / cfg.epochs)) / 2) * (cfg.lrf - 1) + 1)
    if it < warmup:  # linear warm-up of the learning rate and the momentum
        frac = it / warmup
        for g in opt.param_groups:
            g["lr"] = lr_cos * frac
            g["momentum"] = 0.8 + (cfg.momentum - 0.8) * frac
    else:
        for g in opt.param_groups:
            g["lr"] = lr_cos


def _train_epoch(run_: _Run, loader: DataLoader[Any], epoch: int, warmup: int) -> tuple[torch.Tensor, int]:
    """One pass over ``loader``: summed loss components [box, cls, dfl] and the number of images seen. The log's
    last line for the epoch says how much of it went to waiting for the data loader, its workers' start and end
    included (they restart each epoch); each step ends in a synchronising copy of the losses, so the rest is the
    steps themselves. Near 0 the model sets the pace; far above it the loader does, and more ``--workers`` (or
    cheaper augmentations) would train faster. Under torchrun it is the first process's share."""
    cfg, nb = run_.cfg, len(loader)
    run_.net.train()
    sums = torch.zeros(3)
    seen = 0
    t_epoch = time.perf_counter()
    waited, t_asked = 0.0, t_epoch
    for i, (imgs, targets, _) in enumerate(loader):
        waited += time.perf_counter() - t_asked
        _set_lr(run_.opt, cfg, epoch, i + nb * epoch, warmup)
        sums += run_.step(imgs, targets)
        seen += len(imgs)
        if _is_main() and (i % 10 == 0 or i == nb - 1):
            el = time.perf_counter() - t_epoch
            left = (cfg.epochs - epoch - 1) * nb + (nb - i - 1)  # steps to go; validation time not counted
            print(f"\r[train] epoch {epoch + 1}/{cfg.epochs} {i + 1}/{nb} loss box {sums[0] / (i + 1):.3f} "
                  f"cls {sums[1] / (i + 1):.3f} dfl {sums[2] / (i + 1):.3f} "
                  f"{(i + 1) * cfg.batch / max(el, 1e-9):.1f} img/s, ETA {_hms(left * el / (i + 1))}   ", end="",
                  file=run_.log, flush=True)
        t_asked = time.perf_counter()
    waited += time.perf_counter() - t_asked  # the loader's end of the epoch: its workers shut down
    if _is_main():
        el = time.perf_counter() - t_epoch
        print(f"\n[train] epoch {epoch + 1}: {el:.1f} s, {100 * waited / max(el, 1e-9):.0f}% of it waiting for the "
              f"data loader ({cfg.workers} workers)", end="", file=run_.log, flush=True)
    return sums, seen


def _end_epoch(run_: _Run, epoch: int, sums: torch.Tensor, nb: int, val_loader: DataLoader[Any] | None) -> None:
    """Validate the EMA weights (every ``val_every`` epochs and the last), add the epoch's row to results.csv,
    save last.pt (every epoch, or as ``save_period`` says, and always with a new best) and best.pt when the
    fitness improved, and redraw results.png."""
    cfg, out = run_.cfg, run_.out
    print("", file=run_.log)
    metrics: dict[str, Any] = {}
    if val_loader is not None and ((epoch + 1) % cfg.val_every == 0 or epoch == cfg.epochs - 1):
        per_image = predictions(run_.ema.ema, val_loader)
        m = score(per_image)
        metrics = m.to_dict()
        write_plots(per_image, out, prefix="val_")  # val_pr_curve.png, val_predictions.jpg: the latest validation
        print(f"[train] epoch {epoch + 1}: val P {m.precision:.3f} R {m.recall:.3f} mAP50 {m.map50:.3f} "
              f"mAP50-95 {m.map50_95:.3f}", file=run_.log)
    fitness = 0.1 * metrics.get("mAP50", 0.0) + 0.9 * metrics.get("mAP50-95", 0.0) if metrics else run_.best
    row = {"epoch": epoch + 1, "box": float(sums[0] / nb), "cls": float(sums[1] / nb), "dfl": float(sums[2] / nb),
           "lr": run_.opt.param_groups[0]["lr"], **{k: metrics.get(k, "") for k in ("precision", "recall", "mAP50",
                                                                                    "mAP50-95")}}
    run_.rows.append(row)
    with open(out / "results.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(row))
        w.writeheader()
        w.writerows(run_.rows)
    extra = {"epoch": epoch, "metrics": metrics, "train_args": asdict(cfg), "best_fitness": max(run_.best, fitness),
             "data_generate": run_.data_generate,
             **({"widened": run_.widened.to_dict()} if run_.widened is not None else {})}
    now = time.perf_counter()
    improved = bool(metrics) and fitness > run_.best
    # last.pt also goes with every new best.pt: a run resumed from it must know the best it has to beat
    if (cfg.save_period <= 0 or run_.saved_at is None or epoch == cfg.epochs - 1 or improved
            or now - run_.saved_at >= cfg.save_period):
        save_checkpoint(out / "last.pt", run_.ema.ema, model_raw=run_.model.state_dict(),
                        optimizer=run_.opt.state_dict(), ema_updates=run_.ema.updates, **extra)
        run_.saved_at = now
    if improved:
        run_.best = fitness
        half = copy.deepcopy(run_.ema.ema).half()
        save_checkpoint(out / "best.pt", half, **extra)
    results_png(run_.rows, out / "results.png")


def _hms(seconds: float) -> str:
    """``1h02m``, ``12m05s`` or ``42s``."""
    s = int(max(seconds, 0))
    if s >= 3600:
        return f"{s // 3600}h{s % 3600 // 60:02d}m"
    return f"{s // 60}m{s % 60:02d}s" if s >= 60 else f"{s}s"


def _previous_rows(cfg: TrainConfig, results_path: Path, start_epoch: int, log: Any) -> list[dict[str, Any]]:
    """The results table of the run being resumed up to the epoch its last.pt holds (rows of later epochs, written
    after the last save under ``save_period``, are trained again, and it says so); empty for a new run."""
    if not (cfg.resume and results_path.exists()):
        return []
    with open(results_path) as f:
        rows = list(csv.DictReader(f))
    kept = [r for r in rows if int(r["epoch"]) <= start_epoch]
    if len(kept) < len(rows):
        print(f"[train] {len(rows) - len(kept)} rows of results.csv after epoch {start_epoch} are trained again "
              f"(last.pt was written after epoch {start_epoch})", file=log)
    return kept


def _images_everywhere(images_seen: int, device: torch.device) -> int:
    """The images every torchrun process has trained on, summed; then leaves the process group."""
    seen = torch.tensor([images_seen], dtype=torch.int64, device=device)
    torch.distributed.all_reduce(seen)  # the images of every process
    torch.distributed.destroy_process_group()
    return int(seen.item())


def train(cfg: TrainConfig, log: Any = sys.stderr) -> dict[str, Any]:
    """Train; returns a summary (best metrics, paths, speed)."""
    cfg.check()
    device, distributed = _init_device(cfg)
    torch.manual_seed(cfg.seed)
    out = Path(cfg.out)
    out.mkdir(parents=True, exist_ok=True)
    train_dir, val_dir = resolve_splits(cfg.data, "train"), resolve_splits(cfg.data, "val")
    ds = _train_set(cfg, train_dir)
    # The checkpoint records its training frames' size beside imgsz: served, a frame of another size is scaled
    # as these were (ModelConfig.serve_size).
    names = cfg.classes()
    model_cfg = ModelConfig(size=cfg.model, nc=len(names), names=names, imgsz=cfg.imgsz, frame=ds.frame_size(),
                            p2=cfg.p2)
    # Channels-last (NHWC), as served: 1.24x faster training steps on our 2-core CPU; tensor cores want it too.
    model = serving_layout(build_model(model_cfg).to(device))
    start = _load_weights(cfg, model, out, log)
    cfg = replace(cfg, init=start.init)  # recorded in every checkpoint: where the weights came from, resumed or not
    ema = EMA(model, updates=start.ema_updates)
    if start.ema_weights is not None:
        ema.ema.load_state_dict(start.ema_weights)
    opt = _optimizer(model, cfg, start.optimizer)
    net: nn.Module = model
    if distributed:
        net = nn.parallel.DistributedDataParallel(model, device_ids=[device.index] if device.type == "cuda" else None)
    loader, sampler = _train_loader(ds, cfg, distributed)
    val_loader = make_loader(val_dir, cfg.imgsz, cfg.batch, cfg.workers) if _is_main() else None
    criterion = DetectionLoss(model)
    autocast = amp_dtype(cfg.amp, device)
    scaler = torch.amp.GradScaler("cuda", enabled=autocast == torch.float16)
    nb = len(loader)
    # Warm-up: the given epochs, at least 100 iterations on big sets, at most a tenth of a short run.
    warmup = max(round(cfg.warmup_epochs * nb), min(100, cfg.epochs * nb // 10))
    if _is_main():
        crop = f" (crops of {cfg.crop})" if cfg.crop else ""
        print(f"[train] {count_parameters(model) / 1e6:.2f} M parameters ({cfg.model}{', P2' if cfg.p2 else ''}), "
              f"{len(ds)} train images, device {device}, imgsz {cfg.imgsz}{crop}, batch {cfg.batch}, "
              f"epochs {cfg.epochs}, autocast {str(autocast).replace('torch.', '') if autocast else 'off'}", file=log)
    run_ = _Run(cfg, out, log, device, model, net, ema, opt, criterion, autocast, scaler, start.best,
                _previous_rows(cfg, out / "results.csv", start.epoch, log), generate_settings(cfg.data), start.widened)
    t_start = time.perf_counter()
    images_seen = 0
    for epoch in range(start.epoch, cfg.epochs):
        ds.epoch = epoch
        if sampler is not None:
            sampler.set_epoch(epoch)
        if cfg.augment and epoch >= cfg.epochs - cfg.close_mosaic:
            ds.augment = replace(cfg.aug, mosaic=0.0)
        sums, seen = _train_epoch(run_, loader, epoch, warmup)
        images_seen += seen
        if _is_main():
            _end_epoch(run_, epoch, sums, nb, val_loader)
    seconds = time.perf_counter() - t_start
    world = torch.distributed.get_world_size() if distributed else 1
    if distributed:
        images_seen = _images_everywhere(images_seen, device)
    last = run_.rows[-1] if run_.rows else {}
    return {"out": str(out), "best": str(out / "best.pt"), "last": str(out / "last.pt"), "epochs": cfg.epochs,
            "seconds": round(seconds, 1), "processes": world, "images_seen": images_seen,
            "train_images_per_s": round(images_seen / max(seconds, 1e-9), 2),
            "final": {k: last.get(k) for k in ("mAP50", "mAP50-95", "precision", "recall")},
            "best_fitness": round(run_.best, 4)}


def results_png(rows: list[dict[str, Any]], path: Path) -> None:
    """Loss components and mAP per epoch, drawn with OpenCV."""
    import cv2

    w, h, m = 900, 360, 50
    img = np.full((h, w, 3), 255, np.uint8)
    half = w // 2
    panels = [("loss (box, cls, dfl)", ["box", "cls", "dfl"], (m, half - 20)),
              ("val mAP50, mAP50-95", ["mAP50", "mAP50-95"], (half + m, w - 20))]
    colours = [(200, 80, 0), (0, 140, 0), (0, 0, 200)]
    for title, keys, (x0, x1) in panels:
        cv2.rectangle(img, (x0, 30), (x1, h - m), (0, 0, 0), 1)
        cv2.putText(img, title, (x0, 22), cv2.FONT_HERSHEY_SIMPLEX, 0.5, (0, 0, 0), 1, cv2.LINE_AA)
        series = [[float(r[k]) for r in rows if str(r.get(k, "")) not in ("", "None")] for k in keys]
        top = max([max(s) for s in series if s] + [1e-9])
        if keys[0].startswith("mAP"):
            top = 1.0
        for s, col, k in zip(series, colours, keys, strict=False):
            if len(s) >= 1:
                xs = np.linspace(x0, x1, max(len(s), 2))[: len(s)]
                ys = h - m - np.array(s) / top * (h - m - 30)
                pts = np.stack([xs, ys], 1).astype(np.int32)
                cv2.polylines(img, [pts], False, col, 2, cv2.LINE_AA)
                cv2.putText(img, f"{k} {s[-1]:.3f}", (x0 + 5, 45 + 15 * keys.index(k)), cv2.FONT_HERSHEY_SIMPLEX,
                            0.4, col, 1, cv2.LINE_AA)
        cv2.putText(img, f"epochs: {len(rows)}", (x0, h - m + 20), cv2.FONT_HERSHEY_SIMPLEX, 0.4, (0, 0, 0), 1)
    cv2.imwrite(str(path), img)
