"""The ``labeller`` node: ground-truth boxes and overlays from instance masks."""

from zebra_sim_ros.nodes import stub_main

USAGE = """Turns instance masks and posed meshes into per-zebra labels: tight (visible) and
amodal 2D boxes, visible and in-frame fractions, YOLO label files, and one
LINE_LIST ImageMarker per frame for Foxglove."""


def main(argv: list[str] | None = None) -> int:
    """Entry point of ``ros2 run zebra_sim_ros labeller``; returns the exit status."""
    return stub_main("labeller", "the label generator", USAGE, argv)


if __name__ == "__main__":
    raise SystemExit(main())
