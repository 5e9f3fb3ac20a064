"""Thin rclpy adapters, one per executable (``ros2 run zebra_sim_ros <name>``).

Each module converts messages and parameters to and from the pure core and holds nothing else; what they
share (parameter declaration, QoS, stamps, a guarded ``main``) is in :mod:`zebra_sim_ros.nodes.ros_adapter`.
"""
