"""Placement: the paper's per-frame randomisation of zebras, time of day and drone cameras.

Pure core (no rclpy). :class:`zebra_sim_ros.placement.placer.Placer` turns a seed, a world and the
zebra library into a deterministic sequence of :class:`zebra_sim_ros.placement.scene.Scene` objects.
"""
