"""Small pure-numpy geometry modules: rotations and boxes. No ROS, no rendering."""
