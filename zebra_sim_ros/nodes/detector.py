"""The ``detector`` node: YOLO detection on incoming images."""

from zebra_sim_ros.nodes import stub_main

USAGE = """Runs the plain-torch YOLO detector on incoming images and publishes the boxes and
an ImageMarker overlay. The subscription QoS is a parameter and is logged at start."""


def main(argv: list[str] | None = None) -> int:
    """Entry point of ``ros2 run zebra_sim_ros detector``; returns the exit status."""
    return stub_main("detector", "the YOLO detector", USAGE, argv)


if __name__ == "__main__":
    raise SystemExit(main())
