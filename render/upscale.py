"""Render scale per eye and the upscaler that enlarges the eyes in the present pass.

The eyes are drawn at ``render.scale`` of the view and the present pass enlarges them with
an edge-adaptive filter after FSR 1's EASU (AMD FidelityFX Super Resolution 1: a 12-tap
Lanczos-like kernel stretched along the local edge, clamped to its 2x2 neighbourhood against
ringing), on the tone-mapped, display-encoded colour as FSR expects
(``render/shaders/easu.glsl``, ``upscale.frag.glsl``). ``bilinear`` stays as the plain comparison.
"""

from __future__ import annotations

UPSCALERS = ("easu", "bilinear")  # render.upscaler "edge" is easu
#: No eye is drawn smaller than this many pixels on a side (the tile and level maps need some).
MIN_SIDE = 16


def render_size(view: tuple[int, int], scale: float) -> tuple[int, int]:
    """The eye targets' size for a view of ``view`` pixels at ``scale`` (1: the view's)."""
    s = min(1.0, max(0.0, float(scale)))
    if s >= 0.999:
        return view
    w, h = view
    return max(min(w, MIN_SIDE), round(w * s)), max(min(h, MIN_SIDE), round(h * s))


def upscale_defines(src: tuple[int, int], dst: tuple[int, int], upscaler: str) -> dict[str, object]:
    """The present shader's variant: none at 1:1, else the chosen filter."""
    if src == dst:
        return {}
    return (
        {"UPSCALE_BILINEAR": upscaler == "bilinear"} if upscaler == "bilinear" else {"EASU": True}
    )
