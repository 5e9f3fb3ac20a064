"""The ``placer`` node: zebra placements and camera poses, one seeded frame at a time."""

from zebra_sim_ros.nodes import stub_main

USAGE = """Publishes one zebra placement per frame: a random terrain rectangle, 2..250 zebras
with animation clip, frame, scale and yaw, packed without collisions, plus the three
aerial camera poses. Seeded: the seed goes into every frame's metadata."""


def main(argv: list[str] | None = None) -> int:
    """Entry point of ``ros2 run zebra_sim_ros placer``; returns the exit status."""
    return stub_main("placer", "the placement core", USAGE, argv)


if __name__ == "__main__":
    raise SystemExit(main())
