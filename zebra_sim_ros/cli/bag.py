"""``zebra-sim bag ...``: info, recover, filter, eval, census and export of MCAP bags."""

from __future__ import annotations

import argparse
import re
import sys
from pathlib import Path
from typing import Any

from zebra_sim_ros.cli.common import Summary, add_json_flag, census_options, count_option, detector_options
from zebra_sim_ros.errors import ParameterError
from zebra_sim_ros.messages import Datum


def register(sub: Any) -> None:
    """Add the ``bag`` subcommand group."""
    p = sub.add_parser("bag", help="MCAP bags: info, recover, filter, eval, census, export")
    bsub = p.add_subparsers(dest="bag_command", required=True, metavar="ACTION")
    i = bsub.add_parser("info", help="duration, message counts and types per topic (like ros2 bag info)")
    i.add_argument("bag", nargs="+", type=Path, help="bag files, or folders of split files")
    i.add_argument("--full", action="store_true",
                   help="read every message (checks every chunk's CRC, counts bytes per topic) instead of the "
                        "files' summaries; files without a summary (cut short) are always read")
    add_json_flag(i)
    i.set_defaults(func=cmd_info)
    r = bsub.add_parser("recover", help="rewrite every intact message of a damaged bag (after SIGKILL, power loss)")
    r.add_argument("input", type=Path)
    r.add_argument("output", type=Path)
    add_json_flag(r)
    r.set_defaults(func=cmd_recover)
    f = bsub.add_parser("filter", help="some topics and a stretch of time of bags into a new bag (like ros2 bag "
                        "convert with a topic and time filter)")
    # nargs "*": bags that --topics took (it takes every word after it) are named in cmd_filter's error
    f.add_argument("bag", nargs="*", type=Path, help="bag files, or folders of split files (read in order)")
    f.add_argument("--out", required=True, type=Path, help="the bag to write (a new file; not one of those read)")
    f.add_argument("--topics", nargs="+", default=None, metavar="TOPIC",
                   help="only these topics (it takes every word after it: give the bags before it, or end it "
                        "with -- and give every option before that)")
    f.add_argument("--topic-regex", default=None, help="only topics matching this regular expression")
    f.add_argument("--exclude-regex", default=None, help="no topic matching this regular expression")
    f.add_argument("--start", type=float, default=None, metavar="S",
                   help="from this many seconds after the bags' first message (the chunks before are passed over "
                        "unread where a file's summary repeats its channels)")
    f.add_argument("--end", type=float, default=None, metavar="S",
                   help="to this many seconds after the bags' first message (inclusive)")
    f.add_argument("--compression", default="zstd", choices=("zstd", "lz4", "none"), help="chunk compression")
    add_json_flag(f)
    f.set_defaults(func=cmd_filter)
    e = bsub.add_parser("eval", help="mAP50 and mAP50-95 per drone: recorded detections against recorded labels")
    e.add_argument("bag", nargs="+", type=Path)
    e.add_argument("--detections", default="detections",
                   help="name of the detections topic under each drone (default: detections)")
    e.add_argument("--weights", default=None,
                   help="run this detector over the recorded /<drone>/image_raw instead of using recorded detections")
    detector_options(e)  # with --weights
    count_option(e)
    add_json_flag(e)
    e.set_defaults(func=cmd_eval)
    c = bsub.add_parser("census", help="count a recorded run's zebras again across the drones (its placed "
                        "detections, up --locate) with the census's parameters, against the distinct labelled zebras")
    c.add_argument("bag", nargs="+", type=Path, help="bag files, or folders of split files")
    census_options(c)
    c.add_argument("--geojson", type=Path, default=None, help="also write the recounted animals there as GeoJSON "
                   "(WGS84 points with class, score, stamp, cameras and detections; for a GIS)")
    c.add_argument("--datum", default=None, metavar="LAT,LON[,HEIGHT]",
                   help="with --geojson, for a bag whose scenes do not carry their datum (a real flight's): where "
                   "map's origin is on the Earth (deg, deg, m above the WGS84 ellipsoid, 0 if left out); write it "
                   "--datum=-2.3,34.8,1550 for a southern latitude (argparse would take -2.3 for an option)")
    add_json_flag(c)
    c.set_defaults(func=cmd_census)
    x = bsub.add_parser("export", help="a recorded run as a YOLO dataset: each camera image with its labels, for "
                        "train and val")
    x.add_argument("bag", nargs="+", type=Path, help="bag files, or folders of split files")
    x.add_argument("--out", required=True, type=Path, help="a new or empty dataset folder (images/, labels/, ignore/, "
                   "dataset.yaml)")
    x.add_argument("--format", default="jpg", help="how raw images are written: jpg or png (compressed ones as "
                   "recorded where the file keeps their colours; default jpg)")
    x.add_argument("--jpeg-quality", type=int, default=95, help="JPEG quality of raw images written as jpg (1..100)")
    x.add_argument("--val-fraction", type=float, default=0.2, help="share of the steps in val (each step's frames "
                   "together)")
    x.add_argument("--seed", type=int, default=0, help="seed of the split (recorded in the output)")
    add_json_flag(x)
    x.set_defaults(func=cmd_export)


def cmd_info(args: argparse.Namespace) -> Summary:
    """Print a bag summary."""
    from zebra_sim_ros.recording.reader import summarize
    from zebra_sim_ros.recording.stamps import stamp_text

    s = summarize(args.bag, full=args.full)
    print(f"files:     {', '.join(s['files'])}")
    print(f"size:      {s['size_bytes'] / 1e6:.1f} MB")
    print(f"duration:  {s['duration_s']:.3f} s")
    if s["start_ns"] is not None:
        print(f"start:     {stamp_text(s['start_ns'])}")
        print(f"end:       {stamp_text(s['end_ns'])}")
    print(f"messages:  {s['messages']}")
    print("topics:")
    for topic, t in s["topics"].items():
        size = f" {t['bytes'] / 1e6:>10.1f} MB" if t["bytes"] is not None else ""
        print(f"  {topic:<40} {t['type']:<36} {t['count']:>8} msgs{size}")
    if s["read"] and not args.full:
        print(f"read:      {len(s['read'])} file(s) without a readable summary, message by message")
    for note in s["damaged"]:
        print(f"damaged:   {note}")
    return s


def cmd_recover(args: argparse.Namespace) -> Summary:
    """Recover a damaged bag."""
    from zebra_sim_ros.recording.reader import recover

    s = recover(args.input, args.output)
    print(f"recovered {s['messages']} messages into {s['out']}" + (f"; damage: {s['damage']}" if s["damage"] else ""))
    return s


def _regex(name: str, text: str | None) -> re.Pattern[str] | None:
    try:
        return re.compile(text) if text is not None else None
    except re.error as exc:
        raise ParameterError(name, text, f"a regular expression ({exc})") from exc


def _is_bag(path: Path) -> bool:
    """Whether a word names a bag: a file named ``*.mcap`` (a topic name has no dot) or starting with MCAP's magic
    (a cut one does too), or a folder of ``.mcap`` files (``/tmp`` or ``/run`` as a topic name are folders too, but
    without bags in them). A topic name that is also some other file (``chatter`` beside a file of that name)
    stays a topic."""
    from mcap.writer import MCAP0_MAGIC

    if path.is_file():
        if path.suffix == ".mcap":
            return True
        try:
            with open(path, "rb") as f:
                return f.read(len(MCAP0_MAGIC)) == MCAP0_MAGIC
        except OSError:  # unreadable: not a bag this command could take
            return False
    return path.is_dir() and any(path.glob("*.mcap"))


def cmd_filter(args: argparse.Namespace) -> Summary:
    """Write the topics and the stretch of time asked for into a new bag."""
    from zebra_sim_ros.recording.reader import rewrite, topic_filter

    if taken := [t for t in args.topics or () if _is_bag(Path(t))]:
        raise ParameterError("--topics", args.topics, f"topic names only, but {taken} "
                             f"{'is a bag' if len(taken) == 1 else 'are bags'} (--topics takes every word after it: "
                             "give the bags before it, or end the topics with -- and give every option before it)")
    if not args.bag:
        raise ParameterError("bag", [], "at least one bag file, or folder of split files")
    names = set(args.topics or ())
    keep = topic_filter(names, _regex("--topic-regex", args.topic_regex), _regex("--exclude-regex", args.exclude_regex))
    s = rewrite(args.bag, args.out, keep=keep, start_s=args.start, end_s=args.end, compression=args.compression,
                names=("--start", "--end", "--out"))
    span = f" ({(s['end_ns'] - s['start_ns']) / 1e9:.3f} s)" if s["messages"] else ""
    print(f"wrote {s['messages']} messages of {len(s['topics'])} topics{span} into {s['out']}")
    for topic, count in s["topics"].items():
        print(f"  {topic:<40} {count:>8} msgs")
    if missing := sorted(names - set(s["topics"])):
        print(f"not in the bags, or no message in the stretch asked for: {', '.join(missing)}")
    for note in s["damage"]:
        print(f"damaged: {note}")
    if not s["messages"]:  # an empty bag is written, and the run says it found nothing
        print("error: no message matched the topics and the stretch of time asked for", file=sys.stderr)
        s["exit_code"] = 1
    return s


def cmd_eval(args: argparse.Namespace) -> Summary:
    """Score recorded detections against recorded labels."""
    from zebra_sim_ros.detection.metrics import count_line
    from zebra_sim_ros.recording.evaluate import ImageDetector, collect, score

    if args.weights:
        from zebra_sim_ros.detection.checkpoint import check_imgsz, check_scale

        check_imgsz("--imgsz", args.imgsz or None, native=True)  # 0: the checkpoint's rule
        check_scale("--scale", args.scale)
    if args.verifier and not args.weights:
        raise ParameterError("--verifier", args.verifier, "given with --weights (recorded detections are scored as "
                             "they were recorded)")
    detector = (ImageDetector(args.weights, args.device, imgsz=args.imgsz or None, scale=args.scale,
                              verifier=args.verifier, amp=args.amp) if args.weights else None)
    collected = collect(args.bag, args.detections, each=detector)  # one pass, with or without a detector
    if detector is not None:
        collected = detector.apply(collected)
    s = score(collected, args.count_conf)
    for drone, m in s.items():
        if drone not in ("all", "damaged", "skipped") and m:
            print(f"{drone}: {m['frames']} frames, P {m['precision']:.3f} R {m['recall']:.3f} mAP50 {m['mAP50']:.3f} "
                  f"mAP50-95 {m['mAP50-95']:.3f}; counted {m['count']['counted']} for {m['count']['true']} zebras")
    if s["all"]:
        a = s["all"]
        print(f"all: mAP50 {a['mAP50']:.3f} mAP50-95 {a['mAP50-95']:.3f}; {count_line(a['count'])}")
    if s["skipped"]:
        print(f"skipped {len(s['skipped'])} unusable message(s), first: {s['skipped'][0]}")
    for note in s["damaged"]:
        print(f"damaged: {note}")
    return s


def cmd_census(args: argparse.Namespace) -> Summary:
    """Count a recorded run's zebras again across the drones."""
    from zebra_sim_ros.detection.config import CENSUS_READS, CENSUS_RULE
    from zebra_sim_ros.recording.census import bag_census, census_line

    given = {k: getattr(args, k) for k in (*CENSUS_RULE, *CENSUS_READS) if getattr(args, k) is not None}
    s = bag_census(args.bag, given, args.drones, args.geojson, parse_datum(args.datum) if args.datum is not None
                   else None)
    if s["followed"]:
        print("as the bag's locator reported on /diagnostics: "
              + ", ".join(f"{k} {', '.join(v) if isinstance(v, list) else v}" for k, v in s["followed"].items()))

    joined = ", ".join(f"{k} {v:g}" for k, v in s["rule"].items())
    print(f"cameras {', '.join(s['cameras'])} (joined in this order): {s['stamps_counted']} of {s['stamps_placed']} "
          f"placed stamps with every camera's frame and pose")
    print(f"recounted ({joined}): {census_line(s['recounted'])}")
    if s["recorded"] is None:
        print(f"recorded: no {s['census_output']} in the bag")
    else:
        print(f"recorded (the locator's {s['census_output']}, on the same stamps, {s['recorded_stamps']} in the "
              f"bag): {census_line(s['recorded'])}")
    if "geojson" in s:
        d = s["datum"]
        print(f"the recounted animals on the map: {s['geojson']} (GeoJSON; map's origin at {d['latitude_deg']!r}, "
              f"{d['longitude_deg']!r}, {d['altitude_m']!r} m)")
    if s["skipped"]:
        print(f"skipped {len(s['skipped'])} unusable message(s), first: {s['skipped'][0]}")
    for note in s["damaged"]:
        print(f"damaged: {note}")
    return s


def parse_datum(text: str) -> Datum:
    """``--datum``'s "LAT,LON" or "LAT,LON,HEIGHT" (deg, deg, m) as a :class:`Datum`; ParameterError naming it."""
    try:
        return Datum(*(float(v) for v in text.split(",")))
    except (TypeError, ValueError) as exc:
        raise ParameterError("datum", text, f"LAT,LON or LAT,LON,HEIGHT: latitude -90..90 deg, longitude -180..180 "
                             f"deg, a finite height in m ({exc})") from exc


def cmd_export(args: argparse.Namespace) -> Summary:
    """Write a recorded run as a YOLO dataset."""
    from zebra_sim_ros.dataset.bag_export import ExportConfig, export_bag

    s = export_bag(ExportConfig(tuple(str(b) for b in args.bag), str(args.out), args.format, args.jpeg_quality,
                                args.val_fraction, args.seed))
    print(f"wrote {s['frames']['train']} train and {s['frames']['val']} val frames ({s['zebras_labelled']} zebras "
          f"labelled) to {s['out']}; dataset.yaml for zebra-sim train / val (seed {args.seed})")
    if s["val_is_train"]:
        print("no step drawn for val (one step, or --val-fraction 0): dataset.yaml's val is the train split")
    if s["images_without_labels"] or s["labels_without_image"]:
        print(f"not written: {s['images_without_labels']} image(s) without labels, {s['labels_without_image']} "
              "labels without an image")
    if s["skipped"]:
        print(f"skipped {len(s['skipped'])} unusable message(s), first: {s['skipped'][0]}")
    for note in s["damaged"]:
        print(f"damaged: {note}")
    if s.get("exit_code"):
        print("error: no frame written: no image had labels of its stamp (give a split recording as its folder)")
    return s
