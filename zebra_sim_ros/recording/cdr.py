"""Reading the fields we need from CDR-serialized ROS 2 messages (std_msgs/String, sensor_msgs/Image,
Detection2DArray and any message that starts with a std_msgs/Header) without rclpy: a bag is read on machines
without ROS, and an image's stamp is read without decoding its pixels.
"""

from __future__ import annotations

import struct
from typing import NamedTuple

import numpy as np

from zebra_sim_ros.messages import Detection, Detections, Stamp, stamp_ns

# What reading a malformed message raises: broken CDR (struct.error, IndexError), bad UTF-8 or JSON (ValueError),
# missing or mistyped fields (KeyError, TypeError). Such a message is noted and skipped; the rest still counts.
MALFORMED = (ValueError, KeyError, TypeError, IndexError, struct.error)


def cdr_string(data: bytes) -> str:
    """The ``data`` field of a CDR-serialized std_msgs/String (little- or big-endian encapsulation)."""
    little = data[1] == 1
    (n,) = struct.unpack("<I" if little else ">I", data[4:8])
    return data[8:8 + n - 1].decode("utf-8")  # the length counts the terminating NUL


class _Cdr:
    """A minimal little/big-endian CDR reader (offsets aligned from the start of the payload)."""

    def __init__(self, data: bytes) -> None:
        self.data, self.pos = data, 4
        self.end = "<" if data[1] == 1 else ">"

    def _align(self, n: int) -> None:
        self.pos += (-(self.pos - 4)) % n

    def u32(self) -> int:
        self._align(4)
        (v,) = struct.unpack_from(self.end + "I", self.data, self.pos)
        self.pos += 4
        return int(v)

    def u8(self) -> int:
        v = self.data[self.pos]
        self.pos += 1
        return v

    def f64(self) -> float:
        self._align(8)
        (v,) = struct.unpack_from(self.end + "d", self.data, self.pos)
        self.pos += 8
        return float(v)

    def _span(self, n: int) -> bytes:
        if self.pos + n > len(self.data):
            raise ValueError(f"a field of {n} bytes at byte {self.pos} runs past the message's {len(self.data)}: "
                             "cut short")
        v = self.data[self.pos:self.pos + n]
        self.pos += n
        return v

    def string(self) -> str:
        return self._span(self.u32())[:-1].decode("utf-8")

    def blob(self) -> bytes:
        return self._span(self.u32())


def _stamp_of(r: _Cdr) -> int:
    sec, nanosec = r.u32(), r.u32()
    if sec >= 2**31:
        sec -= 2**32
    return stamp_ns(sec, nanosec)


def header_stamp_ns(data: bytes) -> int:
    """The stamp of a CDR-serialized message that starts with a std_msgs/Header (Image, CameraInfo, ...), in ns,
    without touching the rest of it."""
    return _stamp_of(_Cdr(data))


def cdr_image(data: bytes) -> tuple[int, int, int, str, int, bytes]:
    """(stamp ns, height, width, encoding, step, pixel bytes) of a CDR-serialized sensor_msgs/Image."""
    r = _Cdr(data)
    t = _stamp_of(r)
    r.string()  # frame_id
    height, width = r.u32(), r.u32()
    encoding = r.string()
    r.u8()  # is_bigendian
    step = r.u32()
    return t, height, width, encoding, step, r.blob()


def cdr_compressed_image(data: bytes) -> tuple[int, str, bytes]:
    """(stamp ns, format, compressed bytes) of a CDR-serialized sensor_msgs/CompressedImage."""
    r = _Cdr(data)
    t = _stamp_of(r)
    r.string()  # frame_id
    fmt = r.string()
    return t, fmt, r.blob()


def rgb_image(data: bytes) -> tuple[int, np.ndarray] | None:
    """(stamp ns, H x W x 3 RGB array) of a CDR-serialized rgb8 or bgr8 sensor_msgs/Image; None for other
    encodings."""
    t, height, width, encoding, step, pixels = cdr_image(data)
    if encoding not in ("rgb8", "bgr8"):
        return None
    a = np.frombuffer(pixels, np.uint8).reshape(height, step)[:, : width * 3].reshape(height, width, 3)
    return t, np.ascontiguousarray(a[..., ::-1] if encoding == "bgr8" else a)


def _detection_head(r: _Cdr) -> tuple[str, float]:
    """A vision_msgs Detection2D's or Detection3D's header and hypotheses, read up to its box: its best
    hypothesis' class and score (the hypotheses' poses and covariances are not used)."""
    _stamp_of(r)
    r.string()  # the detection's own header: its array's
    best = ("", -1.0)
    for _ in range(r.u32()):
        class_id, score = r.string(), r.f64()
        for _ in range(7 + 36):  # the pose (position, orientation) and its covariance
            r.f64()
        best = max(best, (class_id, score), key=lambda h: h[1])
    return best


class Placed3D(NamedTuple):
    """One detection of a Detection3DArray as :func:`cdr_detections3d` reads it: its best hypothesis' class and
    score, its box's centre (in the array's frame) and its ``id``."""

    class_id: str
    score: float
    center: tuple[float, float, float]
    id: str


def cdr_detections3d(data: bytes) -> tuple[int, list[Placed3D]]:
    """A CDR-serialized ``vision_msgs/Detection3DArray`` (or ``zebra_sim_msgs/``'s, the same layout): its stamp (ns)
    and its detections (:class:`Placed3D`)."""
    r = _Cdr(data)
    t = _stamp_of(r)
    r.string()  # frame_id
    out = []
    for _ in range(r.u32()):
        class_id, score = _detection_head(r)
        x, y, z = r.f64(), r.f64(), r.f64()
        for _ in range(4 + 3):  # the box's orientation and size
            r.f64()
        out.append(Placed3D(class_id, score, (x, y, z), r.string()))
    return t, out


def cdr_pose_position(data: bytes) -> tuple[int, tuple[float, float, float]]:
    """The stamp (ns) and position of a CDR-serialized ``geometry_msgs/PoseStamped`` (a camera's pose in ``map``)."""
    r = _Cdr(data)
    t = _stamp_of(r)
    r.string()  # frame_id
    return t, (r.f64(), r.f64(), r.f64())


def cdr_diagnostics(data: bytes) -> list[tuple[str, dict[str, str]]]:
    """The statuses of a CDR-serialized ``diagnostic_msgs/DiagnosticArray``: each one's name and its values."""
    r = _Cdr(data)
    _stamp_of(r)
    r.string()  # frame_id
    out = []
    for _ in range(r.u32()):
        r.u8()  # level
        name = r.string()
        r.string()  # message
        r.string()  # hardware_id
        values = {}
        for _ in range(r.u32()):
            key = r.string()
            values[key] = r.string()
        out.append((name, values))
    return out


def cdr_detections(data: bytes) -> Detections:
    """A CDR-serialized ``vision_msgs/Detection2DArray`` (or ``zebra_sim_msgs/``'s, the same layout) as our typed
    :class:`~zebra_sim_ros.messages.Detections` (boxes back to [x0, y0, x1, y1]; each detection's best hypothesis;
    width and height 0: the message does not carry them)."""
    r = _Cdr(data)
    t = _stamp_of(r)
    frame_id = r.string()
    out = []
    for _ in range(r.u32()):
        class_id, score = _detection_head(r)
        cx, cy, _theta, w, h = (r.f64() for _ in range(5))
        r.string()  # id
        out.append(Detection((cx - w / 2, cy - h / 2, cx + w / 2, cy + h / 2), score, 0, class_id or "zebra"))
    return Detections(Stamp.from_ns(t), frame_id, 0, 0, tuple(out))
