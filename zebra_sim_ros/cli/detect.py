"""``zebra-sim train``, ``zebra-sim val`` and ``zebra-sim export``: our YOLO's command line."""

from __future__ import annotations

import argparse
import os
from dataclasses import fields
from pathlib import Path
from typing import Any

from zebra_sim_ros.cli.common import Summary, add_json_flag, count_option, detector_options
from zebra_sim_ros.errors import ParameterError
from zebra_sim_ros.params import add_option, spec_of


def register(sub: Any) -> None:
    """Add ``train``, ``val`` and ``export``."""
    from zebra_sim_ros.detection.config import DetectorConfig

    t = sub.add_parser("train", help="train our YOLO from scratch on a YOLO-format dataset",
                       description="Train from scratch. Under torchrun (torchrun --nproc_per_node N -m "
                                   "zebra_sim_ros.cli train ...) it trains with DistributedDataParallel.")
    t.add_argument("--data", required=True, help="dataset.yaml (train and val folders)")
    t.add_argument("--model", default="n", help="n (nano, 3.0 M parameters) or s (small, 11.1 M)")
    t.add_argument("--imgsz", type=int, default=640, help="training image size, px (multiple of 32)")
    t.add_argument("--crop", type=int, default=0, help="train on crop x crop px windows around zebras, cut from "
                   "the imgsz samples at their scale (multiple of 32, below --imgsz): fewer pixels per step for the "
                   "same zebra sizes; validation stays on whole frames at --imgsz (0: off)")
    t.add_argument("--epochs", type=int, default=100)
    t.add_argument("--batch", type=int, default=16, help="batch size (per process under torchrun)")
    t.add_argument("--device", default="auto", help="auto, cpu, cuda or cuda:N")
    t.add_argument("--workers", type=int, default=2, help="data loading processes")
    t.add_argument("--lr0", type=float, default=0.01, help="initial learning rate")
    t.add_argument("--warmup-epochs", type=float, default=3.0, help="epochs of linear learning-rate and "
                   "momentum warm-up (at least 100 steps, or a tenth of a run shorter than 1,000 steps)")
    t.add_argument("--close-mosaic", type=int, default=10, help="last epochs without mosaic")
    t.add_argument("--val-every", type=int, default=1, help="validate every N epochs (and after the last)")
    t.add_argument("--save-period", type=float, default=0.0, metavar="S",
                   help="write last.pt after the first epoch, the last, and any that ends S seconds or more after "
                        "the last write (0: after every epoch); for runs of many short epochs")
    t.add_argument("--max-train-images", type=int, default=0, help="use only the first N training images (0: all)")
    t.add_argument("--seed", type=int, default=0)
    t.add_argument("--amp", default="auto", help="mixed precision: auto (fp16 on CUDA, bf16 on CPUs with bf16 "
                   "instructions, else off), fp16, bf16 or off")
    t.add_argument("--dont-care", action=argparse.BooleanOptionalAction, default=True,
                   help="the sets' ignore/ boxes (zebras dropped by the label filters) are neither zebra nor "
                   "background in the loss; --no-dont-care trains them as background")
    t.add_argument("--other-animals", action="store_true",
                   help="a second class, other_animal: the animals of other species in generated frames (read from "
                   "each frame's annotations/); detected and published as other_animal, never scored as zebras. "
                   "With --init from a zebra-only checkpoint the new class starts fresh")
    t.add_argument("--p2", action="store_true",
                   help="a fourth output level at stride 4 for the smallest zebras (1.6-2.1x the serving time at "
                   "the same size). With --init from a three-level checkpoint the other levels keep its weights and "
                   "the new one starts fresh")
    add_augment_options(t)
    t.add_argument("--out", type=Path, required=True, help="run folder: best.pt, last.pt, results.csv, results.png")
    t.add_argument("--resume", action="store_true", help="continue the run in --out from last.pt")
    t.add_argument("--init", default="", help="start from this checkpoint's weights (fresh schedule), e.g. to "
                   "train in stages; a nano checkpoint into --model s is widened (the same function, shares drawn "
                   "with --seed); default: random initialisation")
    add_json_flag(t)
    t.set_defaults(func=cmd_train)

    tv = sub.add_parser("train-verifier", help="train the zebra-or-not crop verifier (the detector's --verifier) from "
                        "scratch on generated datasets",
                        description="Crops of every animal (zebras, other species) and of background in the frames "
                        "of generated datasets (their annotations/ say which animal is a zebra), a small network "
                        "trained on them under photometric augmentations; see zebra_sim_ros/detection/verify_train.py.")
    from zebra_sim_ros.detection.config import SPLITS, TrainVerifierConfig, VerifierConfig

    d = {f.name: f.default for c in (VerifierConfig, TrainVerifierConfig) for f in fields(c)}  # declared once, there
    tv.add_argument("--data", nargs="+", required=True, help="folders written by zebra-sim generate")
    for flag, kind, text in (
            ("--epochs", int, "passes over the crops"),
            ("--batch", int, "crops per step"),
            ("--lr", float, "peak learning rate, one cycle"),
            ("--seed", int, "seeds the crops' jitter, the split and the training"),
            ("--val-fraction", float, "share held out to report on"),
            ("--split", str, "hold out a share of the crops (an animal's two jittered crops may fall on both sides: "
                             "optimistic figures) or every crop of a share of the frames"),
            ("--background-per-frame", int, "background squares cut from each frame, those holding an animal's "
                                            "centre skipped"),
            ("--min-visible-pixels", int, "animals with fewer visible pixels are not cropped"),
            ("--min-side", float, "the verifier judges boxes whose long side is at least this many px, and is "
                                  "trained on animals of that size or more; smaller boxes keep the detector's score"),
            ("--min-side-fraction", float, "when serving, a box is judged only if its long side is also at least "
                                           "this share of the image's long side (0.0375: 24 px on a 640 px photo, "
                                           "48 px on a 1280x720 frame; 0: off); training is unchanged"),
            ("--parts-per-animal", int, "squares of part of each cropped animal (40-75%% of its long side, centred "
                                        "in its middle): a zebra's part is a zebra, another species' is not"),
            ("--clutter-per-frame", int, "drawn squares of foliage, branches, sky and defocus per frame, never a "
                                         "zebra"),
            ("--detector", str, "hard negatives: this detector's ('shipped' or a checkpoint; empty: none) boxes on "
                                "the frames that lie on no zebra become crops the verifier must reject"),
            ("--mine-imgsz", int, "with --detector: its inference size, px"),
            ("--mine-conf", float, "with --detector: its threshold")):
        tv.add_argument(flag, type=kind, default=d[flag[2:].replace("-", "_")],
                        choices=SPLITS if flag == "--split" else None, help=f"{text} (default: %(default)r)")
    tv.add_argument("--mine-on-animals", action=argparse.BooleanOptionalAction, default=d["mine_on_animals"],
                    help="with --detector: its boxes on animals of other species are hard negatives too "
                    "(default); --no-mine-on-animals keeps only its boxes on background")
    served = VerifierConfig()  # the list defaults, typed (d's values are the fields' raw defaults)
    tv.add_argument("--crop", type=int, default=served.crop,
                    help="side of the square the verifier network sees, 32..256 px: each box's crop is resized to it "
                    "in training and serving (not train's --crop, the windows around zebras; default: %(default)r)")
    tv.add_argument("--widths", type=int, nargs="+", default=list(served.widths),
                    help="channels of the network's stride-2 stages, one stage per value, each 1 or more (default: "
                    f"{' '.join(map(str, served.widths))})")
    tv.add_argument("--contexts", type=float, nargs="+", default=list(served.contexts),
                    help="when serving, p(zebra) is the mean over a crop at each of these contexts (times the box's "
                    "long side; default: the training context, 1.2, alone); training is unchanged")
    tv.add_argument("--mirror", action=argparse.BooleanOptionalAction, default=d["mirror"],
                    help="when serving, each crop's mirror image too (default: off); training is unchanged")
    tv.add_argument("--out", type=Path, required=True, help="verifier checkpoint to write (.pt)")
    add_json_flag(tv)
    tv.set_defaults(func=cmd_train_verifier)

    ve = sub.add_parser("verifier-ensemble", help="join verifiers trained apart into one that averages their p(zebra)",
                        description="One verifier checkpoint holding 2 or more verifiers of one network shape (e.g. "
                        "one recipe's seeds): a box's p(zebra) is the mean of theirs, at each member's cost. Serving "
                        "settings are the first member's unless --contexts or --mirror are given.")
    ve.add_argument("members", nargs="+", help="verifier checkpoints ('shipped': the package's)")
    ve.add_argument("--contexts", type=float, nargs="+", default=None,
                    help="when serving, the crops' contexts (times the box's long side; default: the first member's)")
    ve.add_argument("--mirror", action=argparse.BooleanOptionalAction, default=None,
                    help="when serving, each crop's mirror image too (default: the first member's setting)")
    ve.add_argument("--half", action="store_true",
                    help="store the weights in float16: half the file, served in float32 as ever (default: float32)")
    ve.add_argument("--out", type=Path, required=True, help="ensemble checkpoint to write (.pt)")
    add_json_flag(ve)
    ve.set_defaults(func=cmd_verifier_ensemble)

    vs = sub.add_parser("verifier-serving", help="a verifier with other serving settings (the same weights)",
                        description="Write a verifier checkpoint (single or ensemble) again with other serving "
                        "settings: which boxes it judges, the crops it averages and how much its p(zebra) weighs in "
                        "a box's score. The weights and the training record are kept; settings not given are kept.")
    vs.add_argument("verifier", help="verifier checkpoint ('shipped': the package's)")
    vs.add_argument("--min-side-fraction", type=float, default=None,
                    help="judge a box only if its long side is also at least this share of the image's long side")
    vs.add_argument("--contexts", type=float, nargs="+", default=None,
                    help="the crops' contexts, times the box's long side (p(zebra) is their mean)")
    vs.add_argument("--mirror", action=argparse.BooleanOptionalAction, default=None,
                    help="each crop's mirror image too")
    vs.add_argument("--power", type=float, default=None,
                    help="a judged box whose long side is --power-from of its image's or more scores s·p^POWER, not "
                    "s·p (1..10; 1: s·p for every judged box)")
    vs.add_argument("--power-from", type=float, default=None,
                    help="with --power: the share of the image's long side from which a box's p(zebra) is raised "
                    "to it (0..1; 0: every judged box)")
    vs.add_argument("--out", type=Path, required=True, help="verifier checkpoint to write (.pt)")
    add_json_flag(vs)
    vs.set_defaults(func=cmd_verifier_serving)

    v = sub.add_parser("val", help="precision, recall, mAP50 and mAP50-95 (COCO definition) of a checkpoint")
    v.add_argument("--weights", default=None, help="checkpoint (default: the shipped weights)")
    v.add_argument("--data", required=True, help="dataset.yaml, or a folder of images with a sibling labels/ folder")
    v.add_argument("--split", default="val", help="split of a dataset.yaml: val or train")
    detector_options(v)
    v.add_argument("--batch", type=int, default=8)
    add_option(v, spec_of(DetectorConfig, "conf"), default=0.001, note="val counts every detection above it into AP")
    add_option(v, spec_of(DetectorConfig, "iou"))
    add_option(v, spec_of(DetectorConfig, "max_det"), note="detections per image that count into AP, by score")
    count_option(v)
    v.add_argument("--bootstrap", type=int, default=0, help="also give 95%% intervals of mAP50 and mAP50-95 over "
                   "this many resamples of the set's placements (a placement's views drawn together; 0: none)")
    v.add_argument("--bootstrap-seed", type=int, default=0, help="seed of the resamples (recorded in the output)")
    v.add_argument("--plot", type=Path, default=None, help="also write the PR curve (IoU 0.5) to this PNG")
    v.add_argument("--plots", type=Path, default=Path("runs/val"), help="folder for pr_curve.png and "
                   "predictions.jpg (16 images: ground truth green, detections at conf 0.25 red); '' for none")
    add_json_flag(v)
    v.set_defaults(func=cmd_val)

    e = sub.add_parser("export", help="export a checkpoint for deployment (ONNX, or a serving checkpoint)")
    e.add_argument("--weights", default=None, help="checkpoint (default: the shipped weights)")
    e.add_argument("--format", default="onnx", help="onnx, or pt: a serving checkpoint (fp16 EMA weights) that "
                   "serves frames of --frame px at --imgsz (and others at the same scale)")
    e.add_argument("--imgsz", type=int, default=None, help="input size (default: the checkpoint's)")
    e.add_argument("--frame", type=int, default=None, help="pt: the long side, px, of the frames the source was "
                   "trained on (default: as the checkpoint records it; checkpoints trained before it was recorded "
                   "serve every frame at --imgsz until it is given)")
    e.add_argument("--recipe", default=None, help="pt: a text file kept verbatim in the checkpoint (key 'recipe'): "
                   "how the weights were made (commands, seeds, times)")
    e.add_argument("--blend-base", default=None, help="pt: the checkpoint --weights was fine-tuned from; the output "
                   "is a weight-space ensemble of the two (WiSE-FT): (1 - --blend) x base + --blend x weights; the "
                   "nano an s run was widened from is widened again with the seed the run records")
    e.add_argument("--blend", type=float, default=1.0, help="pt, with --blend-base: the fine-tuned weights' share, "
                   "0..1 (default 1: no blend)")
    e.add_argument("--out", type=Path, required=True, help="output file (.onnx or .pt)")
    add_json_flag(e)
    e.set_defaults(func=cmd_export)


def add_augment_options(parser: argparse.ArgumentParser) -> None:
    """``--aug-<name>`` for every field of :class:`~zebra_sim_ros.detection.config.Augment` (declared there once)."""
    from dataclasses import fields

    from zebra_sim_ros.detection.config import Augment

    g = parser.add_argument_group("augmentation (0 switches one off)")
    for f in fields(Augment):
        g.add_argument(f"--aug-{f.name.replace('_', '-')}", type=float, default=f.default, dest=f"aug_{f.name}",
                       metavar="X", help=f"{f.metadata['help']} (default {f.default})")


def augment_from_args(args: argparse.Namespace) -> Any:
    """The :class:`~zebra_sim_ros.detection.config.Augment` the ``--aug-*`` options give."""
    from dataclasses import fields

    from zebra_sim_ros.detection.config import Augment

    return Augment(**{f.name: getattr(args, f"aug_{f.name}") for f in fields(Augment)})


def cmd_train(args: argparse.Namespace) -> Summary:
    """Train."""
    from zebra_sim_ros.detection.train import TrainConfig, train

    cfg = TrainConfig(data=args.data, out=str(args.out), model=args.model, imgsz=args.imgsz, crop=args.crop,
                      epochs=args.epochs, batch=args.batch, device=args.device, workers=args.workers, lr0=args.lr0,
                      warmup_epochs=args.warmup_epochs, close_mosaic=args.close_mosaic, seed=args.seed,
                      val_every=args.val_every, save_period=args.save_period,
                      max_train_images=args.max_train_images, resume=args.resume,
                      init=args.init, amp=args.amp, dont_care=args.dont_care, aug=augment_from_args(args),
                      other_animals=args.other_animals, p2=args.p2)
    summary = train(cfg)
    if int(os.environ.get("RANK", "0")) != 0:  # under torchrun: only the first process reports
        args.json = False
        return summary
    print(f"trained: {summary}")
    return summary


def cmd_train_verifier(args: argparse.Namespace) -> Summary:
    """Train the crop verifier."""
    from zebra_sim_ros.detection.config import TrainVerifierConfig, VerifierConfig
    from zebra_sim_ros.detection.verify_train import train_verifier

    model = VerifierConfig(crop=args.crop, min_side=args.min_side, widths=tuple(args.widths),
                           min_side_fraction=args.min_side_fraction, contexts=tuple(args.contexts), mirror=args.mirror)
    try:
        model.check()
    except ParameterError as exc:
        raise _by_option(exc) from None
    cfg = TrainVerifierConfig(data=tuple(str(d) for d in args.data), out=str(args.out), model=model,
                              **{f.name: getattr(args, f.name) for f in fields(TrainVerifierConfig)
                                 if f.name not in ("data", "out", "model", "min_visible_fraction")})
    record = train_verifier(cfg)
    print(f"verifier: {args.out} ({record['seconds']} s; held-out crops called zebra: {record['val']})")
    return {"out": str(args.out), **{k: v for k, v in record.items() if k != "history"}}


def _by_option(exc: ParameterError, fields: tuple[str, ...] | None = None) -> ParameterError:
    """A verifier setting's error (``verifier min_side``) named by the option that set it (``--min-side``), not the
    config field; ``fields``: only those fields' (the command's options set no others); any other error as it is."""
    field = exc.name.removeprefix("verifier ")
    if field == exc.name or (fields is not None and field not in fields):
        return exc
    return ParameterError("--" + field.replace("_", "-"), exc.value, exc.allowed)


def cmd_verifier_ensemble(args: argparse.Namespace) -> Summary:
    """Join verifiers into an ensemble."""
    from zebra_sim_ros.detection.verify import ensemble_verifiers

    try:
        record = ensemble_verifiers(args.members, args.out, args.contexts, args.mirror, args.half)
    except ParameterError as exc:
        raise _by_option(exc, ("contexts",)) from None
    shas = ", ".join(m["sha256"][:12] for m in record["members"])
    print(f"verifier ensemble: {args.out} ({len(record['members'])} members: {shas})")
    members = [{k: v for k, v in m.items() if k != "history"} for m in record["members"]]  # as train-verifier's
    return {"out": str(args.out), **record, "members": members}


def cmd_verifier_serving(args: argparse.Namespace) -> Summary:
    """Write a verifier again with other serving settings."""
    from zebra_sim_ros.detection.verify import SERVING, reserve_verifier

    given = {k: getattr(args, k) for k in SERVING if getattr(args, k) is not None}
    try:
        record = reserve_verifier(args.verifier, args.out, **given)
    except ParameterError as exc:
        raise _by_option(exc) from None
    c = record["config"]
    print(f"verifier: {args.out} (from {record['from']}; serving: judged from {c['min_side']:g} px and "
          f"{c['min_side_fraction']:g} of the image, contexts {c['contexts'] or [c['context']]}, mirror "
          f"{'on' if c['mirror'] else 'off'}, score s·p^{c['power']:g} from {c['power_from']:g} of the image, "
          f"s·p under)")
    return {"out": str(args.out), **record}


def cmd_val(args: argparse.Namespace) -> Summary:
    """Validate."""
    from zebra_sim_ros.detection.checkpoint import check_imgsz, check_scale
    from zebra_sim_ros.detection.evaluate import evaluate
    from zebra_sim_ros.detection.metrics import count_line, pr_curve_png

    args.imgsz = args.imgsz or None  # 0: the checkpoint's rule
    check_imgsz("--imgsz", args.imgsz)
    check_scale("--scale", args.scale)
    if args.batch < 1:
        raise ParameterError("--batch", args.batch, ">= 1")
    if args.bootstrap < 0:
        raise ParameterError("--bootstrap", args.bootstrap, ">= 0 (0: none)")
    if args.bootstrap_seed < 0:
        raise ParameterError("--bootstrap-seed", args.bootstrap_seed, ">= 0")
    for name, value in (("--conf", args.conf), ("--iou", args.iou)):
        if not 0.0 <= value <= 1.0:
            raise ParameterError(name, value, "0..1")

    m, facts = evaluate(args.weights, args.data, args.split, args.imgsz, args.batch, args.device, args.conf, args.iou,
                        scale=args.scale, max_det=args.max_det, verifier=args.verifier or None, amp=args.amp,
                        count_conf=args.count_conf)
    per_image = facts.pop("per_image")
    print(f"inference size: {facts['imgsz']} ({facts['imgsz_rule']}); {facts['ms_per_image']} ms per image on "
          f"{facts['device']}, features in {facts['amp']} (reading, letterbox, network, NMS"
          f"{', verifier' if facts['verifier'] else ''})")
    d = m.to_dict()
    print(f"{'images':>8}{'instances':>11}{'P':>8}{'R':>8}{'mAP50':>8}{'mAP50-95':>10}")
    print(f"{d['images']:>8}{d['instances']:>11}{d['precision']:>8.3f}{d['recall']:>8.3f}{d['mAP50']:>8.3f}"
          f"{d['mAP50-95']:>10.3f}")
    print("by box size (sqrt of area, px):" + "".join(
        f"  {k} {v['mAP50']:.3f}/{v['mAP50-95']:.3f} ({v['instances']})" for k, v in facts["ap_by_size"].items()))
    print(count_line(facts["count"]))
    if args.bootstrap:
        from zebra_sim_ros.detection.evaluate import bootstrap_interval

        b = facts["bootstrap"] = bootstrap_interval(per_image, args.bootstrap, args.bootstrap_seed, args.max_det)
        print(f"95% intervals over {b['samples']} resamples of the {b['placements']} placements (seed {b['seed']}): "
              f"mAP50 {b['mAP50 95%'][0]:.3f}-{b['mAP50 95%'][1]:.3f}, "
              f"mAP50-95 {b['mAP50-95 95%'][0]:.3f}-{b['mAP50-95 95%'][1]:.3f}")
    if args.plot:
        pr_curve_png(m, str(args.plot))
        print(f"PR curve: {args.plot}")
    if str(args.plots) not in ("", "."):
        from zebra_sim_ros.detection.evaluate import write_plots

        facts["plots"] = write_plots(per_image, args.plots)
        print(f"plots: {facts['plots']['pr_curve']}, {facts['plots']['predictions']}")
    return {**d, **facts}


def cmd_export(args: argparse.Namespace) -> Summary:
    """Export."""
    if args.format not in ("onnx", "pt"):
        raise ParameterError("--format", args.format, "onnx or pt")
    from zebra_sim_ros.detection.checkpoint import check_imgsz
    from zebra_sim_ros.detection.export import export_checkpoint, export_onnx

    check_imgsz("--imgsz", args.imgsz)
    if args.frame is not None and (args.format != "pt" or not 16 <= args.frame <= 8192):
        raise ParameterError("--frame", args.frame, "16..8192 px, with --format pt")
    if args.recipe is not None and (args.format != "pt" or not Path(args.recipe).is_file()):
        raise ParameterError("--recipe", args.recipe, "a readable text file, with --format pt")
    if args.blend_base is not None and args.format != "pt":
        raise ParameterError("--blend-base", args.blend_base, "a checkpoint, with --format pt")
    if not 0.0 <= args.blend <= 1.0:
        raise ParameterError("--blend", args.blend, "0..1 (the fine-tuned weights' share)")
    if args.blend != 1.0 and args.blend_base is None:
        raise ParameterError("--blend", args.blend, "1 (no blend) unless --blend-base names the checkpoint to blend")
    if args.format == "onnx":
        path = export_onnx(args.weights, args.out, args.imgsz)
    else:
        recipe = Path(args.recipe).read_text() if args.recipe else None
        path = export_checkpoint(args.weights, args.out, args.imgsz, args.frame, recipe, args.blend_base, args.blend)
    print(f"exported {path}")
    return {"out": str(path), "format": args.format}


