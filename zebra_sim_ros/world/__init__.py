"""Worlds: terrain heightfields, ground materials, vegetation and sky, built-in presets and USD stages.

Frame: ``map``, ENU (REP 103/105): x east, y north, z up, metres.
"""
