"""Walking at eye height with collision against the scene, and mouse-drag looking.

The body is a column ``radius_m`` wide from the feet (eye height below the eye) to the eye.
A move is cut into pieces no longer than :data:`SUBSTEP_M`, so running fast neither tunnels
through a thin wall nor takes more than one stair per piece; each piece

* stops at what horizontal rays from knee to eye height hit (a wall, a table's edge at hip
  height, a cupboard), sliding along it, and at what a ray at shin height hits close ahead;
* finds the ground under the body's centre and its front edge: the highest surface below the
  feet plus one riser (:data:`STEP_M`). A higher surface cannot be stepped onto at all, and a
  surface within a riser is a floor only if a person fits above it (eye height plus
  :data:`HEAD_ROOM_M`): that
  is what keeps you off a coffee table by its lower shelf and out from under a desk;
* snaps the feet to ground within a riser up or down (stairs, thresholds).

Ground farther below than a riser (off a landing, off a table) is fallen to at the end of the
step; with no ground below at all (a file with no floor) the walker stays at its height. In fly
mode there is no floor following and no falling; collision, when on, stops the eye at surfaces.
"""

from __future__ import annotations

import math

import numpy as np

from app.camera import orientation
from app.raycast import RayCaster
from app.settings import NavigationSettings

STEP_M = 0.32  # highest step walked up or down without falling: a stair riser (0.3 m at most)
SUBSTEP_M = 0.1  # longest piece of a move checked at once (well under a stair's tread)
HEAD_ROOM_M = 0.15  # free height above the eye a person needs to stand somewhere
_SHIN_M = STEP_M + 0.05  # the shin ray's height above the feet: just over a riser
# Heights of the body rays above the feet, besides the eye: over the second stair of a flight
# (two risers up, a tread ahead), a table edge, a worktop.
_BODY_RAYS_M = (STEP_M + 0.25, 0.9, 1.3)
_EPS = 1e-3


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
        if not np.isfinite(move).all():
            return
        pieces = max(1, math.ceil(float(np.linalg.norm(move)) / SUBSTEP_M))
        part = move / pieces
        for _ in range(pieces):
            if s.fly:
                self._fly(part)
            else:
                self._walk(part)
        if not s.fly:
            self._fall()

    # -- flying ------------------------------------------------------------------------------
    def _fly(self, move: np.ndarray) -> None:
        if self.settings.collision and self.caster is not None:
            move = self._slide(move, self._eye_blocked)
        self.position = self.position + move

    def _eye_blocked(self, move: np.ndarray) -> bool:
        length = float(np.linalg.norm(move))
        if length < 1e-9 or self.caster is None:
            return False
        dist, _ = self.caster.cast(self.position, move / length, length + self.settings.radius_m)
        return math.isfinite(dist)

    # -- walking -----------------------------------------------------------------------------
    def _walk(self, move: np.ndarray) -> None:
        if self.caster is None:
            self.position = self.position + move
            return
        if self.settings.collision:
            move = self._slide(move, self._body_blocked)
        if float(np.linalg.norm(move)) < 1e-12:
            return
        self.position = self.position + move
        feet = self._feet()
        ground = self._ground(self.position[[0, 2]], feet)
        if ground is not None and abs(ground - feet) <= STEP_M:
            self.position[1] = ground + self.settings.eye_height_m  # a step up or down

    def _fall(self) -> None:
        """Land on the ground below (none: stay at this height).

        The fall completes within the step: the window steps the walker only while a key is
        held, so a fall spread over frames would leave the viewer hanging in the air when the
        key is let go over a stairwell.
        """
        if self.caster is None:
            return
        feet = self._feet()
        ground = self._ground(self.position[[0, 2]], feet, reach=math.inf)
        if ground is not None and ground < feet - _EPS:
            self.position[1] = ground + self.settings.eye_height_m

    def _feet(self) -> float:
        return float(self.position[1] - self.settings.eye_height_m)

    def _ground(self, xz: np.ndarray, feet: float, reach: float = 2.0 * STEP_M) -> float | None:
        """Height of the first surface below ``feet + STEP_M`` at ``xz`` (within ``reach``)."""
        top = feet + STEP_M
        dist = self._vertical_cast(xz, top, -1.0, reach)
        return top - dist if math.isfinite(dist) else None

    def _needed_room(self) -> float:
        return self.settings.eye_height_m + HEAD_ROOM_M

    def _head_room(self, xz: np.ndarray, ground: float) -> float:
        return 0.05 + self._vertical_cast(xz, ground + 0.05, 1.0, self._needed_room())

    def _vertical_cast(self, xz: np.ndarray, y: float, sign: float, reach: float) -> float:
        """Distance up (sign 1) or down (-1) to the first surface that is not a wall.

        A ray running exactly along a riser's face or a wall (an edge of a tread, the body on the
        line of a wall) may report a hit anywhere on it; such hits are passed through.
        """
        assert self.caster is not None
        travelled = 0.0
        for _ in range(4):
            o = (xz[0], y + sign * travelled, xz[1])
            dist, tri = self.caster.cast_triangles([o], [(0.0, sign, 0.0)], reach - travelled)
            if not math.isfinite(dist[0]):
                return math.inf
            t = self.caster.tri[tri[0]]
            n = np.cross(t[1] - t[0], t[2] - t[0])
            if abs(n[1]) > 0.1 * float(np.linalg.norm(n)):
                return travelled + float(dist[0])
            travelled += float(dist[0]) + 1e-4
        return math.inf

    def _body_blocked(self, move: np.ndarray) -> bool:
        """Whether the body cannot make the (horizontal) ``move`` from where it is."""
        length = float(np.linalg.norm(move))
        if length < 1e-9 or self.caster is None:
            return False
        s = self.settings
        d = move / length
        feet = self._feet()
        centre = self.position.copy()
        side = np.array([-d[2], 0.0, d[0]])
        starts, lengths = [], []
        for h in (*_BODY_RAYS_M, s.eye_height_m):
            if h > s.eye_height_m:
                continue
            o = np.array([centre[0], feet + h, centre[2]])
            for off in (-0.7, 0.0, 0.7):
                starts.append(o + off * s.radius_m * side)
                lengths.append(length + s.radius_m)
        starts.append(np.array([centre[0], feet + min(_SHIN_M, s.eye_height_m), centre[2]]))
        lengths.append(length + 0.5 * s.radius_m)
        dist, _ = self.caster.cast_many(starts, [d] * len(starts))
        if bool((dist <= np.asarray(lengths)).any()):
            return True
        # The ground where the body's centre and its front edge would be.
        here = self._ground(centre[[0, 2]], feet)
        here_room = self._head_room(centre[[0, 2]], here) if here is not None else math.inf
        for ahead in (length, length + s.radius_m):
            xz = centre[[0, 2]] + d[[0, 2]] * ahead
            g = self._ground(xz, feet)
            if g is None or g < feet - STEP_M:
                continue  # a drop (or nothing): walk off it and fall
            room = self._head_room(xz, g)
            if g + room <= feet + STEP_M:  # on the edge of a step: stand on what is above
                g += room
                room = self._head_room(xz, g)
            # Too low to stand: a table top, the space under a desk. Where it is already low
            # (a low attic, a spawn under a beam) only moves that do not make it worse.
            if room < self._needed_room() and room < here_room - 0.01:
                return True
        return False

    @staticmethod
    def _slide(move: np.ndarray, blocked) -> np.ndarray:
        if not blocked(move):
            return move
        # Keep whichever axis-aligned part of the move is free, the longer first.
        parts = [np.array([move[0], 0.0, 0.0]), np.array([0.0, 0.0, move[2]])]
        if abs(move[1]) > 1e-12:
            parts.append(np.array([0.0, move[1], 0.0]))
        parts.sort(key=lambda p: -float(np.linalg.norm(p)))
        for part in parts:
            if np.linalg.norm(part) > 1e-9 and not blocked(part):
                return part
        return np.zeros(3)
