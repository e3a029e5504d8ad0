"""Simulated gaze: the mouse cursor stands in for an eye tracker.

The gaze point is the cursor's normalised position inside either eye's viewport, applied to
both eyes. A held mouse button means "gaze fixed" (as in the TCR paper's experiment); optionally
a cursor that stays within a small angle for a short time (dwell) also counts as fixed.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from app.settings import GazeSettings


@dataclass
class GazeState:
    u: float = 0.5  # 0 left .. 1 right of the eye viewport
    v: float = 0.5  # 0 top .. 1 bottom
    fixed: bool = False
    speed_deg_s: float = 0.0  # angular speed of the gaze point


class GazeModel:
    def __init__(self, settings: GazeSettings | None = None) -> None:
        self.settings = settings or GazeSettings()
        self.state = GazeState()
        self.button_held = False
        self._still_for = 0.0
        self._anchor = (0.5, 0.5)

    def set_cursor(self, u: float, v: float) -> None:
        """Cursor at normalised eye-viewport coordinates; non-finite input keeps the old point."""
        if math.isfinite(u) and math.isfinite(v):
            self.state.u = min(1.0, max(0.0, u))
            self.state.v = min(1.0, max(0.0, v))

    @staticmethod
    def from_view_pixel(x: float, y: float, view_w: float, view_h: float) -> tuple[float, float]:
        """Map a pixel of the side-by-side view to (u, v) inside the eye viewport it is over."""
        if view_w <= 0 or view_h <= 0:
            return 0.5, 0.5
        half = view_w / 2.0
        ex = x - half if x >= half else x
        return ex / half, y / view_h

    def update(self, dt: float, fov_deg: float) -> GazeState:
        """Advance dwell detection by dt seconds; fov_deg converts viewport units to degrees."""
        s = self.state
        dt = dt if math.isfinite(dt) and dt > 0 else 0.0
        moved_deg = math.hypot(s.u - self._anchor[0], s.v - self._anchor[1]) * fov_deg
        s.speed_deg_s = moved_deg / dt if dt > 0 else 0.0
        if moved_deg > self.settings.dwell_deg:
            self._still_for = 0.0
            self._anchor = (s.u, s.v)
        else:
            self._still_for += dt
        dwelling = self.settings.dwell and self._still_for >= self.settings.dwell_s
        s.fixed = self.button_held or dwelling
        if dt > 0 and moved_deg <= self.settings.dwell_deg:
            s.speed_deg_s = 0.0
        return s
