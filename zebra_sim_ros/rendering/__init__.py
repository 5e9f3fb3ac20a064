"""Rendering: RGB, metric depth and exact instance masks of the scene from each drone camera.

moderngl on a headless EGL context: Mesa's llvmpipe on a CPU, the NVIDIA driver where a GPU exists.
The core never imports rclpy; the camera node and ``zebra-sim render`` both call :class:`Renderer`.
"""
