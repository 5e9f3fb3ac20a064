"""Camera images in messages: sensor_msgs/CompressedImage as ``image_transport``'s compressed transport writes and
reads it (:func:`compress_rgb`, :func:`decompress_rgb`), a recorded image as RGB (:func:`message_rgb`), and a bag's
images as detector frames (``zebra-sim predict BAG``: every sensor_msgs/Image of encoding rgb8 or bgr8 and every
jpeg or png sensor_msgs/CompressedImage, on every topic or those given, named after the topic and the stamp)."""

from __future__ import annotations

import re
from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING, NamedTuple

import cv2
import numpy as np

from zebra_sim_ros.recording.cdr import MALFORMED, cdr_compressed_image, rgb_image
from zebra_sim_ros.recording.reader import BagReader

if TYPE_CHECKING:  # the detector's frames import torch, which the camera node (compress_rgb) does without
    from zebra_sim_ros.detection.sources import Frame

IMAGE_TYPE = "sensor_msgs/msg/Image"
COMPRESSED_TYPE = "sensor_msgs/msg/CompressedImage"
COMPRESSED_FORMATS = ("jpeg", "png")  # what compress_rgb writes and decompress_rgb reads
PNG_LEVEL = 1  # zlib level of the PNGs written: benchmarks/bench_compressed.py


def compress_rgb(rgb: np.ndarray, kind: str, quality: int = 90) -> tuple[str, bytes]:
    """An H x W x 3 RGB uint8 image as a CompressedImage's ``(format, data)``, the way ``compressed_image_transport``
    writes an rgb8 image: the codec holds BGR and the format says so (``"rgb8; jpeg compressed bgr8"``). ``kind``:
    jpeg (``quality`` 1-100) or png (lossless)."""
    if kind not in COMPRESSED_FORMATS:
        raise ValueError(f"compressed format {kind!r}: want one of {COMPRESSED_FORMATS}")
    if rgb.ndim != 3 or rgb.shape[2] != 3 or rgb.dtype != np.uint8:
        raise ValueError(f"an H x W x 3 uint8 image, not {rgb.dtype} {rgb.shape}")
    params = [cv2.IMWRITE_JPEG_QUALITY, int(quality)] if kind == "jpeg" else [cv2.IMWRITE_PNG_COMPRESSION, PNG_LEVEL]
    ok, buf = cv2.imencode(".jpg" if kind == "jpeg" else ".png", np.ascontiguousarray(rgb[..., ::-1]), params)
    if not ok:
        raise ValueError(f"OpenCV could not encode a {rgb.shape[1]}x{rgb.shape[0]} image as {kind}")
    return f"rgb8; {kind} compressed bgr8", buf.tobytes()


# the encodings of depth images, masks and 16-bit images: not camera colour
NOT_COLOUR = re.compile(r"^(mono16|(16|32|64)[USF]C\d|8[US]C1|(rgb|bgr|rgba|bgra)16)$")


class CompressedFormat(NamedTuple):
    """A CompressedImage's ``format``, read once: ``"<encoding>; <codec> compressed <codec encoding>"`` as
    ``compressed_image_transport`` writes it, or a bare ``jpeg``/``png`` (``encoding`` "")."""

    encoding: str  # the image's own encoding (rgb8, mono8, 16UC1, ...); "" for a bare format
    codec: str  # jpeg, png, ... (lower case; jpg read as jpeg); "" when none is named
    codec_encoding: str  # what the codec holds (bgr8, rgb8, mono8); "" when the format does not say
    bare: bool  # no "<encoding>;" part: a bare jpeg or png

    @classmethod
    def parse(cls, fmt: str) -> CompressedFormat:
        if ";" not in fmt:  # bare: the whole of it names the codec ("jpeg compressed rgb8" names none we read)
            bare = fmt.strip().lower()
            return cls("", {"jpg": "jpeg"}.get(bare, bare), "", True)
        encoding, after = (p.strip() for p in fmt.split(";", 1))
        words = after.split()
        codec = {"jpg": "jpeg"}.get(words[0].lower(), words[0].lower()) if words else ""
        held = words[2] if len(words) > 2 and words[1] == "compressed" else ""
        return cls(encoding, codec, held, False)

    @property
    def colour(self) -> bool:
        """An 8-bit colour or grey image: its encoding is not a depth, mask or 16-bit one (bare: colour)."""
        return not NOT_COLOUR.match(self.encoding)

    @property
    def holds_bgr(self) -> bool:
        """The codec holds BGR, as OpenCV writes and reads files: the format says so (``compressed bgr...``) or
        says nothing (bare), as ``compressed_image_transport`` takes it."""
        return self.bare or self.codec_encoding.startswith("bgr")


def decompress_rgb(fmt: str, data: bytes) -> np.ndarray:
    """A CompressedImage's ``(format, data)`` as an H x W x 3 RGB uint8 image. Reads what
    ``compressed_image_transport`` and camera drivers write: ``"<encoding>; jpeg compressed <codec encoding>"``,
    or the bare ``jpeg``/``png``; grey images come back as three equal channels. The decoded channels are turned
    from BGR to RGB where the format says the codec held BGR (``compressed bgr...``) or says nothing (bare), as
    ``compressed_image_transport`` does. ValueError for another format (``compressedDepth``, video codecs), a
    depth, mask or 16-bit image (:attr:`CompressedFormat.colour`), or bytes that do not decode."""
    parsed = CompressedFormat.parse(fmt)
    kind = parsed.codec
    if kind not in COMPRESSED_FORMATS:
        raise ValueError(f"unsupported compressed format {fmt!r} (read: {', '.join(COMPRESSED_FORMATS)})")
    if not parsed.colour:
        raise ValueError(f"compressed format {fmt!r}: not an 8-bit colour or grey image")
    if not data:
        raise ValueError(f"an empty {kind} image ({fmt!r})")
    try:
        img = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_COLOR)
    except cv2.error as exc:  # a header that claims more pixels than OpenCV decodes, say
        raise ValueError(f"{len(data)} bytes do not decode as {kind} ({fmt!r}): {str(exc).strip()[-120:]}") from None
    if img is None:
        raise ValueError(f"{len(data)} bytes do not decode as {kind} ({fmt!r})")
    return np.ascontiguousarray(img[..., ::-1] if parsed.holds_bgr else img)


def message_rgb(type_name: str, data: bytes) -> tuple[int, np.ndarray] | None:
    """(stamp ns, H x W x 3 RGB) of a CDR-serialized camera image: a sensor_msgs/Image of encoding rgb8 or bgr8
    (None for other encodings: depth, masks), or a jpeg or png sensor_msgs/CompressedImage (None for a depth, mask
    or 16-bit one; ValueError for other formats); None for other types. A malformed message raises one of
    :data:`~zebra_sim_ros.recording.cdr.MALFORMED`."""
    if type_name == IMAGE_TYPE:
        return rgb_image(data)
    if type_name == COMPRESSED_TYPE:
        t, fmt, blob = cdr_compressed_image(data)
        return (t, decompress_rgb(fmt, blob)) if CompressedFormat.parse(fmt).colour else None
    return None


def bag_frames(path: Path, topics: tuple[str, ...] = (), skipped: list[str] | None = None) -> Iterator[Frame]:
    """The camera images of ``path`` (:func:`message_rgb`; every image topic, or ``topics``); images of other
    encodings (depth, masks) are left out, unreadable ones too and noted in ``skipped`` when given."""
    from zebra_sim_ros.detection.sources import Frame

    reader = BagReader.open(path, name="SOURCE")
    for m in reader.messages():
        if m.type_name not in (IMAGE_TYPE, COMPRESSED_TYPE) or (topics and m.topic not in topics):
            continue
        try:
            got = message_rgb(m.type_name, m.data)
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
