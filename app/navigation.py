"""Walking at eye height with collision against the scene, and mouse-drag looking."""

from __future__ import annotations

import math

import numpy as np

from app.camera import orientation
from app.raycast import RayCaster
from app.settings import NavigationSettings

STEP_M = 0.35  # highest step walked up (or down) without a jump


class Walker:
    """The viewer's body: eye position, heading, and a ray caster to bump into walls with."""

    def __init__(self, settings: NavigationSettings, caster: RayCaster | None = None) -> None:
        self.settings = settings
        self.caster = caster
        self.position = np.array([0.0, settings.eye_height_m, 0.0])
        self.yaw_deg = 0.0
        self.pitch_deg = 0.0

    def place(self, position, yaw_deg: float, pitch_deg: float = 0.0) -> None:
        p = np.asarray(position, np.float64)
        if np.isfinite(p).all():
            self.position = p.copy()
        if math.isfinite(yaw_deg):
            self.yaw_deg = yaw_deg % 360.0
        if math.isfinite(pitch_deg):
            self.pitch_deg = max(-89.0, min(89.0, pitch_deg))

    def look(self, dx_px: float, dy_px: float) -> None:
        k = self.settings.turn_deg_per_px
        if math.isfinite(dx_px) and math.isfinite(dy_px):
            self.yaw_deg = (self.yaw_deg - dx_px * k) % 360.0
            self.pitch_deg = max(-89.0, min(89.0, self.pitch_deg - dy_px * k))

    def step(self, forward: float, strafe: float, rise: float, dt: float) -> None:
        """Move by the input axes (-1..1) for dt seconds, sliding along walls."""
        if not all(math.isfinite(v) for v in (forward, strafe, rise, dt)) or dt <= 0:
            return
        s = self.settings
        right, _up, fwd = orientation(self.yaw_deg, self.pitch_deg if s.fly else 0.0)
        move = (fwd * forward + right * strafe) * s.walk_speed_mps * dt
        if s.fly:
            move = move + np.array([0.0, rise * s.walk_speed_mps * dt, 0.0])
        else:
            move[1] = 0.0
        if s.collision and self.caster is not None:
            move = self._clip(move)
        self.position = self.position + move
        if not s.fly and s.collision and self.caster is not None:
            self._follow_floor()

    def _blocked(self, move: np.ndarray) -> bool:
        length = float(np.linalg.norm(move))
        if length < 1e-9 or self.caster is None:  # step() clips only with a caster
            return False
        d = move / length
        s = self.settings
        # Rays from shin, hip and eye height: a table top or a sofa arm stops you as a wall does.
        heights = (s.eye_height_m - 0.3, s.eye_height_m - 0.8, 0.0)
        origins = [self.position - np.array([0.0, h, 0.0]) for h in heights]
        side = np.cross(d, [0.0, 1.0, 0.0])
        n = float(np.linalg.norm(side))
        side = side / n if n > 1e-9 else np.zeros(3)
        starts = [o + off * side * s.radius_m for o in origins for off in (-0.7, 0.0, 0.7)]
        dist, _ = self.caster.cast_many(starts, [d] * len(starts), length + s.radius_m)
        return bool(np.isfinite(dist).any())

    def _clip(self, move: np.ndarray) -> np.ndarray:
        if not self._blocked(move):
            return move
        # Slide: keep whichever axis-aligned part of the move is free, the longer first.
        parts = [np.array([move[0], 0.0, 0.0]), np.array([0.0, 0.0, move[2]])]
        parts.sort(key=lambda p: -float(np.linalg.norm(p)))
        for part in parts:
            if np.linalg.norm(part) > 1e-9 and not self._blocked(part):
                return part + np.array([0.0, move[1], 0.0])
        return np.array([0.0, move[1], 0.0])

    def _follow_floor(self) -> None:
        """Follow steps of up to STEP_M up or down; anything else below is not a floor."""
        if self.caster is None:  # step() follows the floor only with a caster
            return
        s = self.settings
        probe = self.position - np.array([0.0, s.eye_height_m - STEP_M, 0.0])
        dist, _ = self.caster.cast(probe, [0.0, -1.0, 0.0], 2 * STEP_M)
        if math.isfinite(dist):
            self.position[1] = probe[1] - dist + s.eye_height_m
