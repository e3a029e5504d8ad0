"""Render scale per eye and the upscaler that enlarges the eyes in the present pass.

The eyes are drawn at ``render.scale`` of the view and the present pass enlarges them with
an edge-adaptive filter after FSR 1's EASU (AMD FidelityFX Super Resolution 1: a 12-tap
Lanczos-like kernel stretched along the local edge, clamped to its 2x2 neighbourhood against
ringing), on the tone-mapped, display-encoded colour as FSR expects
(``render/shaders/easu.glsl``, ``upscale.frag.glsl``). ``bilinear`` stays as the plain comparison.

FSR 1's second half, RCAS (robust contrast-adaptive sharpening, ``render/shaders/rcas.glsl``),
sharpens the picture EASU enlarges (``render.sharpen``). FSR runs it after EASU at the output
size; by default here it runs at the drawn size just before EASU, as its own small pass into a
second target per eye (``rcas.frag.glsl``). Measured on llvmpipe, showroom at 2x640x720
(``tests/measure_rcas.py``), the present pass's time over EASU alone at render.scale 0.67 / 0.5:
this placement +3.4 / +1.7 ms, FSR's after EASU (``PresentPass.rcas_placement = "after"``)
+6.3 / +7.3 ms, folded into EASU's 12 taps ("folded", 60 fetches a pixel) +20 / +22 ms; FLIP
against the full frame 0.0638 / 0.0806 here, 0.0638 / 0.0792 after (EASU alone 0.0585 /
0.0773: sharpening never lowers the error against an unsharpened full frame). Before EASU only
soft detail gains: a drawn edge one pixel wide has nothing to sharpen, where "after" crisps
EASU's own soft edges too.
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


#: FSR's default sharpness, in stops (0 strongest); ``render.sharpen`` 0.9 maps to it.
DEFAULT_STOPS = 0.2


def sharpen_stops(amount: float) -> float | None:
    """RCAS's sharpness in stops for ``render.sharpen`` (0 to 1: off to strongest): None
    when off, else 2 stops at the weakest step down to 0 (FSR's strongest) at 1."""
    a = min(1.0, max(0.0, float(amount)))
    return None if a <= 0.0 else 2.0 * (1.0 - a)


def rcas_con(stops: float) -> float:
    """RCAS's lobe scale for a sharpness in stops (FsrRcasCon: 2^-stops)."""
    return float(2.0 ** -max(0.0, stops))


def upscale_defines(
    src: tuple[int, int], dst: tuple[int, int], upscaler: str, sharpen: float = 0.0
) -> dict[str, object]:
    """The present shader's variant: none at 1:1, else the chosen filter; EASU with
    ``sharpen`` > 0 (render.sharpen) reads its taps through RCAS."""
    if src == dst:
        return {}
    if upscaler == "bilinear":
        return {"UPSCALE_BILINEAR": True}
    return {"EASU": True, "RCAS": sharpen_stops(sharpen) is not None}
