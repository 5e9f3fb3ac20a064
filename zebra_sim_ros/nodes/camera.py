"""The ``camera`` node: renders RGB, depth and instance masks for each placement."""

from zebra_sim_ros.nodes import stub_main

USAGE = """Renders each placement from each camera (headless EGL through moderngl):
RGB (rgb8), metric depth in metres (32FC1) and instance ids, with camera_info."""


def main(argv: list[str] | None = None) -> int:
    """Entry point of ``ros2 run zebra_sim_ros camera``; returns the exit status."""
    return stub_main("camera", "the renderer", USAGE, argv)


if __name__ == "__main__":
    raise SystemExit(main())
