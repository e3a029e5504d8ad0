"""OpenGL contexts: the Qt widget's (wrapped) or a standalone EGL one for headless hosts.

Everything needs OpenGL 4.3 (compute shaders, SSBOs, image load/store); anything less stops
start-up with a message naming what is missing instead of failing later inside a pass.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import logging

import moderngl

log = logging.getLogger(__name__)
REQUIRED = (4, 3)


class GLUnavailableError(RuntimeError):
    """No usable OpenGL 4.3 context; the message says what is missing and what to install."""


def check(ctx: moderngl.Context) -> moderngl.Context:
    """Raise GLUnavailableError unless ``ctx`` offers what the renderer needs."""
    code = ctx.version_code
    info = ctx.info
    renderer = info.get("GL_RENDERER", "unknown renderer")
    version = info.get("GL_VERSION", str(code))
    if code < REQUIRED[0] * 100 + REQUIRED[1] * 10:
        raise GLUnavailableError(
            f"OpenGL {REQUIRED[0]}.{REQUIRED[1]} core is required (compute shaders, shader "
            f"storage buffers, image load/store), but {renderer} offers only {version}. "
            "Update the graphics driver, or install Mesa (Debian: libgl1-mesa-dri libegl1)."
        )
    return ctx


def create_headless() -> moderngl.Context:
    """A standalone EGL context (software or GPU), not current on any thread afterwards."""
    try:
        # The stub types each **settings value as a dict; glcontext takes backend="egl".
        ctx = moderngl.create_context(standalone=True, backend="egl")  # type: ignore[arg-type]
    except Exception as exc:  # noqa: BLE001 - glcontext raises plain Exceptions
        raise GLUnavailableError(
            f"cannot create a headless OpenGL context through EGL ({exc}). Install EGL and "
            "Mesa (Debian: libegl1 libgl1-mesa-dri) or a GPU driver with EGL."
        ) from exc
    try:
        check(ctx)
    except GLUnavailableError:
        ctx.release()
        raise
    release_current_egl()
    return ctx


def release_current_egl() -> None:
    """Leave no EGL context current on this thread.

    glcontext leaves its context current after creation; under libglvnd a Qt window made later
    on the same thread then cannot make its own GLX context current. Hosts therefore enter the
    context (``with ctx:``) around their work, which restores whatever was current before.
    """
    name = ctypes.util.find_library("EGL") or "libEGL.so.1"
    try:
        egl = ctypes.CDLL(name)
    except OSError:
        return
    egl.eglGetCurrentDisplay.restype = ctypes.c_void_p
    egl.eglMakeCurrent.argtypes = [ctypes.c_void_p] * 4
    display = egl.eglGetCurrentDisplay()
    if display:
        egl.eglMakeCurrent(display, None, None, None)
