"""Camera images of a bag as detector frames (``zebra-sim predict BAG``): every sensor_msgs/Image of encoding
rgb8 or bgr8, on every topic or those given, named after the topic and the stamp."""

from __future__ import annotations

import re
from collections.abc import Iterator
from pathlib import Path

from zebra_sim_ros.detection.sources import Frame
from zebra_sim_ros.recording.cdr import MALFORMED, rgb_image
from zebra_sim_ros.recording.reader import BagReader

IMAGE_TYPE = "sensor_msgs/msg/Image"


def bag_frames(path: Path, topics: tuple[str, ...] = (), skipped: list[str] | None = None) -> Iterator[Frame]:
    """The rgb8/bgr8 images of ``path`` (every Image topic, or ``topics``); images of other encodings (depth,
    masks) and unreadable ones are left out, and noted in ``skipped`` when given."""
    reader = BagReader.open(path, name="SOURCE")
    for m in reader.messages():
        if m.type_name != IMAGE_TYPE or (topics and m.topic not in topics):
            continue
        try:
            got = rgb_image(m.data)
        except MALFORMED as exc:
            if skipped is not None:
                skipped.append(f"{m.topic} at {m.log_time}: {exc}")
            continue
        if got is None:
            continue  # depth, instance masks: not camera colour
        t, rgb = got
        name = re.sub(r"[^A-Za-z0-9]+", "_", m.topic).strip("_")
        yield Frame(f"{name}_{t}", rgb, t)
    if skipped is not None:
        skipped += [f"bag damaged: {s}" for s in reader.stopped]
