"""What a host hands the renderer for one frame."""

from __future__ import annotations

from dataclasses import dataclass

from app.camera import EyeView


@dataclass
class FrameInput:
    eyes: list[EyeView]  # left, right
    gaze: tuple[float, float] = (0.5, 0.5)  # normalised in each eye viewport, (0, 0) top-left
    gaze_fixed: bool = False
    levels: list[int] | None = None  # TCR pyramid level per mesh; None: full quality
