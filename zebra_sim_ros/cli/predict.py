"""``zebra-sim predict SOURCE --out DIR``: the detector on an image, a folder of images, a video or a bag.

Writes, per image (a video's frames and a bag's camera images included)::

    DIR/images/<name>.jpg    the image with the boxes drawn (a video: DIR/<video>_detections.mp4 instead)
    DIR/labels/<name>.txt    YOLO: "class cx cy w h" normalised, one line per detection
    DIR/json/<name>.json     the typed detections (schema zebra_sim_ros/detections: boxes in pixels, scores)

A progress line counts the images as it goes; the last line gives the throughput. Inference size, thresholds
and device are the detector node's parameters (the checkpoint's rule by default).
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from zebra_sim_ros.cli.common import Summary, add_json_flag, detector_options
from zebra_sim_ros.errors import ParameterError
from zebra_sim_ros.params import add_option, spec_of


def register(sub: Any) -> None:
    """Add ``predict``."""
    from zebra_sim_ros.detection.config import DetectorConfig

    p = sub.add_parser("predict", help="detect zebras in an image, a folder, a video or a bag; save drawn images, "
                       "YOLO labels and JSON", description=__doc__,
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("source", type=Path, metavar="SOURCE", help="an image, a folder of images, a video or a .mcap bag")
    p.add_argument("--out", type=Path, required=True, help="output folder")
    p.add_argument("--weights", default=None, help="checkpoint (default: the shipped weights)")
    detector_options(p)
    add_option(p, spec_of(DetectorConfig, "conf"))
    add_option(p, spec_of(DetectorConfig, "iou"))
    add_option(p, spec_of(DetectorConfig, "max_det"))
    p.add_argument("--batch", type=int, default=4, help="images per forward pass")
    p.add_argument("--topics", nargs="*", default=[], help="bag: image topics to read (default: every rgb8/bgr8 "
                   "sensor_msgs/Image)")
    p.add_argument("--no-draw", action="store_true", help="write labels and JSON only")
    p.add_argument("--quiet", action="store_true", help="no progress line")
    add_json_flag(p)
    p.set_defaults(func=cmd_predict)


class _Progress:
    """One line on stderr, rewritten: images done (of how many, when known) and the rate so far."""

    def __init__(self, total: int, quiet: bool) -> None:
        self.total, self.quiet, self.done, self.t0, self.shown = total, quiet, 0, time.perf_counter(), 0.0

    def add(self, n: int) -> None:
        self.done += n
        now = time.perf_counter()
        if self.quiet or (now - self.shown < 0.2 and self.done != self.total):
            return
        self.shown = now
        rate = self.done / max(now - self.t0, 1e-9)
        of = f"/{self.total}" if self.total else ""
        bar = ""
        if self.total:
            k = int(30 * self.done / self.total)
            bar = "[" + "#" * k + "." * (30 - k) + "] "
        print(f"\r[predict] {bar}{self.done}{of} images, {rate:.1f} images/s", end="", file=sys.stderr, flush=True)

    def close(self) -> None:
        if not self.quiet:
            print(file=sys.stderr, flush=True)


def _frames(source: Path, topics: tuple[str, ...], skipped: list[str]) -> tuple[Iterator[Any], int, float]:
    """The source's frames, how many there are (0 if unknown) and a video's frame rate (0 otherwise)."""
    from zebra_sim_ros.detection.sources import image_frames, source_kind, video_frames

    kind = source_kind(source)
    if kind == "video":
        return video_frames(source)
    if kind == "bag":
        from zebra_sim_ros.recording.images import bag_frames

        return bag_frames(source, topics, skipped), 0, 0.0
    from zebra_sim_ros.detection.data import IMAGE_EXTS

    files = 1 if kind == "image" else sum(1 for p in source.rglob("*") if p.suffix.lower() in IMAGE_EXTS)
    return image_frames(source), files, 0.0


def cmd_predict(args: argparse.Namespace) -> Summary:
    """Run the detector over the source and write what the module docstring lists."""
    from zebra_sim_ros.detection.checkpoint import check_imgsz, check_scale, load_model, select_device
    from zebra_sim_ros.detection.predict import detect

    check_imgsz("--imgsz", args.imgsz or None)
    check_scale("--scale", args.scale)
    if args.batch < 1:
        raise ParameterError("--batch", args.batch, ">= 1")
    skipped: list[str] = []
    frames, total, fps = _frames(args.source, tuple(args.topics), skipped)
    device = select_device(args.device)
    model, _ = load_model(args.weights, device, amp=args.amp)
    verifier = None
    if args.verifier:
        from zebra_sim_ros.detection.verify import load_verifier

        verifier, _ = load_verifier(args.verifier, device, "--verifier")
    for sub in ("labels", "json") + (() if args.no_draw else ("images",)):
        (args.out / sub).mkdir(parents=True, exist_ok=True)
    video = _VideoOut(args.out, args.source, fps) if fps and not args.no_draw else None
    progress = _Progress(total, args.quiet)
    t0 = time.perf_counter()
    n = boxes = 0
    batch: list[Any] = []

    def flush() -> None:
        nonlocal n, boxes
        dets = detect(model, [f.rgb for f in batch], args.imgsz or None, args.conf, args.iou, args.max_det,
                      scale=args.scale, verifier=verifier)
        for f, d in zip(batch, dets, strict=True):
            _write(args.out, f, d, model.cfg.names, None if args.no_draw or video else "images")
            if video is not None:
                video.add(f.rgb, d)
            boxes += len(d)
        n += len(batch)
        progress.add(len(batch))
        batch.clear()

    try:
        for frame in frames:
            batch.append(frame)
            if len(batch) >= args.batch:
                flush()
        if batch:
            flush()
    finally:
        progress.close()
        if video is not None:
            video.close()
    seconds = time.perf_counter() - t0
    if n == 0:
        raise ParameterError("SOURCE", str(args.source), "a source with at least one rgb8/bgr8 image")
    rate = n / max(seconds, 1e-9)
    print(f"[predict] {n} images, {boxes} detections in {seconds:.1f} s: {rate:.2f} images/s, "
          f"{1000 * seconds / n:.1f} ms per image (model load excluded); wrote {args.out}", flush=True)
    return {"images": n, "detections": boxes, "seconds": round(seconds, 2), "images_per_s": round(rate, 2),
            "out": str(args.out), "video": str(video.path) if video is not None else None, "skipped": skipped}


def _write(out: Path, frame: Any, dets: Any, names: Any, images: str | None) -> None:
    """The labels, the JSON and (``images``) the drawn image of one frame."""
    import cv2

    from zebra_sim_ros.detection.draw import draw_boxes
    from zebra_sim_ros.detection.predict import detections_message
    from zebra_sim_ros.detection.sources import yolo_lines
    from zebra_sim_ros.messages import Stamp

    h, w = frame.rgb.shape[:2]
    (out / "labels" / f"{frame.name}.txt").write_text("".join(line + "\n" for line in yolo_lines(dets, w, h)))
    msg = detections_message(Stamp.from_ns(frame.stamp_ns or 0), frame.frame_id, w, h, dets, names)
    (out / "json" / f"{frame.name}.json").write_text(msg.to_json())
    if images:
        cv2.imwrite(str(out / images / f"{frame.name}.jpg"), draw_boxes(frame.rgb, dets)[..., ::-1],
                    [cv2.IMWRITE_JPEG_QUALITY, 92])


class _VideoOut:
    """The drawn frames of a video source as ``<out>/<video>_detections.mp4`` at the source's frame rate."""

    def __init__(self, out: Path, source: Path, fps: float) -> None:
        self.path = out / f"{source.stem}_detections.mp4"
        self.fps = fps
        self.writer: Any = None

    def add(self, rgb: Any, dets: Any) -> None:
        import cv2

        from zebra_sim_ros.detection.draw import draw_boxes

        if self.writer is None:
            h, w = rgb.shape[:2]
            self.writer = cv2.VideoWriter(str(self.path), cv2.VideoWriter.fourcc(*"mp4v"), self.fps, (w, h))
        self.writer.write(draw_boxes(rgb, dets)[..., ::-1])

    def close(self) -> None:
        if self.writer is not None:
            self.writer.release()
