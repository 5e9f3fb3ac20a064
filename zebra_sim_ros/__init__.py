"""zebra_sim_ros: synthetic drone imagery of zebras with exact ground truth, as a ROS 2 node graph.

The package is layered as the pipeline runs:

- ``zebra``      the procedural articulated zebra asset (mesh, skeleton, clips, coat, USD, baked cache)
- ``geometry``   small pure-numpy geometry helpers (rotations, boxes)
- ``nodes``      thin rclpy adapters, one module per executable

Nothing outside ``nodes`` imports rclpy.
"""

__version__ = "0.1.0"
