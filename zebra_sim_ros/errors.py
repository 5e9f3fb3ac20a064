"""The package's exceptions: one root, specific subclasses whose messages carry the bad values."""

from __future__ import annotations


class ZebraSimError(Exception):
    """Root of every error raised on purpose by zebra_sim_ros."""


class ParameterError(ZebraSimError, ValueError):
    """A parameter or argument is out of its allowed range.

    The message names the parameter, the value received and what is allowed.
    """

    def __init__(self, name: str, value: object, allowed: str) -> None:
        self.name = name
        self.value = value
        self.allowed = allowed
        super().__init__(f"parameter '{name}' = {value!r} is invalid: allowed {allowed}")


class AssetError(ZebraSimError):
    """An asset (zebra cache, USD file) is missing, corrupt or of the wrong version."""


class DependencyError(ZebraSimError):
    """An optional dependency or system library is missing; the message says what to install."""


class WorkerError(ZebraSimError):
    """A worker process of a parallel job died or hung; the message names it, its exit code and how to resume."""
