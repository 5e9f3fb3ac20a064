"""Recording: MCAP bags the way rosbag2 writes them, recovery, reading (tolerant of truncation), summaries.

Pure core (no rclpy): the ``recorder`` and ``replay`` nodes and ``zebra-sim bag`` use these modules.
"""
