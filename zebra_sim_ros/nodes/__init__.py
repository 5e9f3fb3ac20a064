"""Thin rclpy adapters, one per executable (``ros2 run zebra_sim_ros <name>``).

Each module converts messages and parameters to and from the pure core in
``zebra_sim_ros.zebra`` and holds nothing else. Until a node lands, its ``main`` is a stub
built by :func:`stub_main`: ``--help`` says what the node will do; anything else fails loudly.
"""

import sys
from collections.abc import Sequence


def stub_main(name: str, comes_with: str, usage: str, argv: Sequence[str] | None) -> int:
    """Run a not-yet-implemented node: print usage and return 0 on ``-h``/``--help``, else return 2.

    ``argv`` excludes the program name (``sys.argv[1:]`` when None). Status 2 rather than 1
    so scripts can tell "missing feature" from a runtime failure.
    """
    args = sys.argv[1:] if argv is None else list(argv)
    if "-h" in args or "--help" in args:
        print(f"usage: ros2 run zebra_sim_ros {name} [--ros-args ...]\n\n{usage.strip()}\n")
        print(f"(not implemented yet: it comes with {comes_with})")
        return 0
    print(
        f"zebra_sim_ros: the {name} node is not implemented yet (it comes with {comes_with}); see README",
        file=sys.stderr,
    )
    return 2
