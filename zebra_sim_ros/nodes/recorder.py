"""The ``recorder`` node: records topics to MCAP."""

from zebra_sim_ros.nodes import stub_main

USAGE = """Records the graph's topics to an MCAP file that `ros2 bag play` and rosbags can
read (ros2msg schemas, cdr encoding, message indexes, QoS metadata)."""


def main(argv: list[str] | None = None) -> int:
    """Entry point of ``ros2 run zebra_sim_ros recorder``; returns the exit status."""
    return stub_main("recorder", "the MCAP recorder", USAGE, argv)


if __name__ == "__main__":
    raise SystemExit(main())
