"""The headless OpenGL context: EGL through glcontext, with a clear error when a library is missing."""

from __future__ import annotations

import ctypes.util
from typing import Any

from zebra_sim_ros.errors import DependencyError

_DEBIAN = "libegl1 libgl1 libegl-mesa0 libgl1-mesa-dri"


def create_context(require_gpu: bool = False) -> tuple[Any, dict[str, str]]:
    """A standalone OpenGL 4.3+ context on EGL, and its info (vendor, renderer, version, device).

    ``device`` is ``cpu`` for Mesa's llvmpipe / softpipe and ``gpu`` otherwise. Raises
    :class:`DependencyError` naming the Debian packages when EGL or GL cannot be loaded.
    """
    try:
        import moderngl
    except ImportError as exc:  # pragma: no cover - a declared dependency
        raise DependencyError("moderngl is not installed: pip install moderngl glcontext") from exc
    for lib in ("EGL", "GL"):
        if ctypes.util.find_library(lib) is None:
            raise DependencyError(f"lib{lib}.so.1 not found: install the Debian packages {_DEBIAN} "
                                  f"(apt-get install -y {_DEBIAN})")
    try:
        egl: dict[str, Any] = {"backend": "egl", "libegl": "libEGL.so.1", "libgl": "libGL.so.1"}
        ctx = moderngl.create_context(standalone=True, require=430, **egl)
    except Exception as exc:  # moderngl raises plain Exceptions with the EGL error text
        raise DependencyError(f"cannot create a headless EGL OpenGL 4.3 context ({exc}); install {_DEBIAN}, "
                              "or the NVIDIA driver's EGL for a GPU") from exc
    info = {k: str(ctx.info.get(k, "")) for k in ("GL_VENDOR", "GL_RENDERER", "GL_VERSION")}
    renderer = info["GL_RENDERER"].lower()
    info["device"] = "cpu" if ("llvmpipe" in renderer or "softpipe" in renderer) else "gpu"
    if require_gpu and info["device"] == "cpu":
        raise DependencyError(f"a GPU was required but the OpenGL renderer is {info['GL_RENDERER']}")
    return ctx, info
