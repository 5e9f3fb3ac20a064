"""The ``replay`` node: plays an MCAP recording back with /clock."""

from zebra_sim_ros.nodes import stub_main

USAGE = """Plays an MCAP recording back onto the graph with /clock, with rate, loop, start
offset and topic filters."""


def main(argv: list[str] | None = None) -> int:
    """Entry point of ``ros2 run zebra_sim_ros replay``; returns the exit status."""
    return stub_main("replay", "the MCAP recorder", USAGE, argv)


if __name__ == "__main__":
    raise SystemExit(main())
