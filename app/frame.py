"""What a host hands the renderer for one frame."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from app.camera import EyeView


@dataclass
class FrameInput:
    eyes: list[EyeView]  # left, right
    gaze: tuple[float, float] = (0.5, 0.5)  # normalised in each eye viewport, (0, 0) top-left
    gaze_fixed: bool = False
    levels: list[int] | None = None  # TCR pyramid level per mesh; None: full quality
    # CPS: per eye the side caps (left, right, bottom) from the edge rays, and the rays' hit
    # points in world space (drawn with the detail visualisation). None: no caps (all 0).
    cps_caps: list[tuple[float, float, float]] | None = None
    edge_hits: list[np.ndarray] | None = None
    # Progressive refinement while the viewer rests (app.refine): accumulate this frame as
    # sample ``sample`` of ``refine_target`` (full quality asked for; ``jitter`` is the
    # sub-pixel shift, pixels, already in the eyes' projections). Not refining: as before.
    refining: bool = False
    sample: int = 0
    refine_target: int = 0
    jitter: tuple[float, float] = (0.0, 0.0)


def parse_size(text: str) -> tuple[int, int]:
    """'1280x720' -> (1280, 720): the whole side-by-side view."""
    try:
        w, h = (int(v) for v in text.lower().split("x"))
    except ValueError as exc:
        raise ValueError(f"size must look like 1280x720, got '{text}'") from exc
    if not (2 <= w <= 16384 and 1 <= h <= 16384):
        raise ValueError(f"size {w}x{h} is outside 2x1 .. 16384x16384")
    return w, h
