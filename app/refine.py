"""Progressive refinement while the viewer rests (issue 15): the still detector, the sample
schedule and the sub-pixel jitter.

When the viewpoint and the gaze rest, each frame asks for full quality (finest textures, CPS
off) and a sub-pixel shifted projection; the renderer's accumulation pass
(``render.refine.RefinePass``) keeps a running mean per pixel, so edges get anti-aliased and
noise averages out. The first still frame is drawn as usual (so a single frame at rest is the
same picture as without refinement); accumulation starts with the second.

The fovea refines first: for the first ``target`` samples the fovea takes every frame and the
periphery every other one; then the periphery takes every frame until it has ``target`` too,
after ``needed(target) = target + target // 2`` frames. The jitter sequence is a Halton (2, 3)
sequence shifted by half a pixel (sample 0 is unshifted), ordered so that both the fovea's
samples (Halton points 0..n-1) and the periphery's (two runs of consecutive points) stay
evenly spread over the pixel.

``render.refine``: "on", "off" or "auto" (:func:`refine_on`: on when the host knows a
display refresh rate, i.e. in the window; off headless, so renders, benches and tests draw
the frames of before). Motion resets the mean; so does a drift of the view by more than
POSE_REST_PX of a pixel since the mean began (the mean is not reprojected), and the renderer
dropping it (finer textures or a new photon map: :meth:`Refinement.restart`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

# Gaze at rest: the gaze point moves less than this (degrees of view per second); below it is
# fixational jitter, above it the eye is looking somewhere else.
GAZE_REST_DEG_S = 2.0
# The view at rest: the pose the mean was started at may drift by at most this share of a
# pixel (turning, or stepping as seen at POSE_REST_DISTANCE_M) before the mean starts again.
# TCR's "still" speed lets a slow turn through (0.05 m/s is 1.5 degrees a second), and the
# mean is not reprojected: without this, a slow turn would smear the accumulated picture.
POSE_REST_PX = 0.1
# ... and a view that moves by POSE_REST_PX in less than this many seconds is moving.
POSE_REST_S = 0.25
POSE_REST_DISTANCE_M = 1.0


def refine_on(mode: str, display_hz: float | None) -> bool:
    """``render.refine``: "on", "off", or "auto": on when a display refresh rate is known (the
    window), off without one (headless renders, benches and tests stay frame for frame)."""
    text = str(mode).strip().lower()
    if text == "auto":
        return bool(display_hz) and math.isfinite(float(display_hz or 0.0))
    return text == "on"


def pose_shift_deg(
    a: tuple[float, float, float, float, float], b: tuple[float, float, float, float, float]
) -> float:
    """How far the picture moves between poses (x, y, z, yaw, pitch) in degrees of view: the
    turn plus the step as seen from POSE_REST_DISTANCE_M."""
    turned = abs((b[3] - a[3] + 180.0) % 360.0 - 180.0) + abs(b[4] - a[4])
    moved = math.dist(a[:3], b[:3])
    return turned + math.degrees(moved / POSE_REST_DISTANCE_M)


def radical_inverse(index: int, base: int) -> float:
    """The van der Corput radical inverse of ``index`` in ``base`` (in [0, 1))."""
    result, f = 0.0, 1.0 / base
    i = max(0, int(index))
    while i > 0:
        result += f * (i % base)
        i //= base
        f /= base
    return result


def halton_jitter(index: int) -> tuple[float, float]:
    """Sub-pixel offset in pixels (each in [-0.5, 0.5)) of Halton point ``index`` (bases 2, 3),
    shifted by half a pixel so that point 0 is the pixel centre (no offset)."""
    x = (radical_inverse(index, 2) + 0.5) % 1.0 - 0.5
    y = (radical_inverse(index, 3) + 0.5) % 1.0 - 0.5
    return x, y


def needed(target: int) -> int:
    """Frames until every pixel has ``target`` samples (the fovea gets them first)."""
    t = max(1, int(target))
    return t + t // 2


def periphery_turn(sample: int, target: int) -> bool:
    """Whether the periphery takes sample ``sample`` (the fovea takes every one)."""
    return sample >= max(1, int(target)) or sample % 2 == 0


def jitter_index(sample: int, target: int) -> int:
    """Which Halton point sample ``sample`` uses: during the first ``target`` samples the
    periphery's (even) samples take points 0, 1, 2, ... and the odd ones the points after
    them, so the periphery's samples and the fovea's are each evenly spread."""
    t = max(1, int(target))
    s = max(0, int(sample))
    if s >= t:
        return s
    evens = (t + 1) // 2
    return s // 2 if s % 2 == 0 else evens + (s - 1) // 2


@dataclass(frozen=True)
class RefineStep:
    """What one frame asks for: accumulate (``refining``) sample ``sample`` of ``target`` with
    the projection shifted by ``jitter`` pixels; ``hold``: refined, show the mean as it is."""

    refining: bool = False
    sample: int = 0
    target: int = 0
    jitter: tuple[float, float] = (0.0, 0.0)

    @property
    def hold(self) -> bool:
        return self.refining and self.sample >= needed(self.target)


class Refinement:
    """The viewer's rest and the refinement's progress (plain state, no GL).

    ``observe`` once per tick says whether viewpoint and gaze rest (motion resets);
    ``next_frame`` once per rendered frame hands out the next sample."""

    def __init__(self) -> None:
        self.still = False
        self.frames = 0  # frames rendered since the viewer came to rest
        self.target = 64
        self.enabled = True
        self._last_gaze: tuple[float, float] | None = None
        self._anchor: tuple[float, float, float, float, float] | None = None  # the mean's pose
        self._last_pose: tuple[float, float, float, float, float] | None = None

    def reset(self) -> None:
        self.still = False
        self.frames = 0
        self._last_gaze = None
        self._anchor = None
        self._last_pose = None

    def restart(self) -> None:
        """The renderer dropped the mean (the picture changed under it, e.g. finer textures
        arrived): the next frame is sample 0 again, still at rest."""
        if self.frames > 1:
            self.frames = 1

    def observe(
        self,
        dt: float,
        viewpoint_speed: float,
        move_off: float,
        gaze: tuple[float, float],
        view_deg: tuple[float, float],
        pose: tuple[float, float, float, float, float] | None = None,
        deg_per_px: float = 0.0,
    ) -> bool:
        """One tick: the viewpoint rests when its speed (``Session.viewpoint_speed``, TCR's
        motion term) is at most TCR's "still" threshold ``move_off``; the gaze rests when its
        point moves less than GAZE_REST_DEG_S (``view_deg``: the eye's field of view, degrees
        across and up). A tick of zero length (a click) changes nothing but the gaze.
        ``pose`` (x, y, z, yaw, pitch): the refinement also starts again when the view has
        drifted from the pose its mean began at by more than POSE_REST_PX pixels of
        ``deg_per_px`` degrees (the mean is not reprojected)."""
        u, v = (float(gaze[0]), float(gaze[1]))
        gaze_still = True
        if self._last_gaze is not None and dt > 0:
            du = (u - self._last_gaze[0]) * view_deg[0]
            dv = (v - self._last_gaze[1]) * view_deg[1]
            gaze_still = math.hypot(du, dv) / dt <= GAZE_REST_DEG_S
        elif self._last_gaze is not None and (u, v) != self._last_gaze:
            gaze_still = False
        self._last_gaze = (u, v)
        speed = float(viewpoint_speed)
        still = gaze_still and math.isfinite(speed) and abs(speed) <= max(0.0, move_off)
        if pose is not None:
            x, y, z, yaw, pitch = (float(c) for c in pose)
            p = (x, y, z, yaw, pitch)
            if not all(math.isfinite(c) for c in p):
                still = False
            else:
                rest = POSE_REST_PX * max(0.0, float(deg_per_px))
                last = self._last_pose
                # A view that moves by more than that in POSE_REST_S is turning or walking,
                # however slowly: it is not at rest (else a slow turn would start the mean
                # again every few frames, the governor switching between full quality and its
                # walking settings each time).
                if (
                    last is not None
                    and dt > 0
                    and pose_shift_deg(last, p) / dt > rest / POSE_REST_S
                ):
                    still = False
                elif still and self._anchor is not None and self.frames > 0:
                    if pose_shift_deg(self._anchor, p) > rest:
                        self.frames = 0  # the mean was of another view: start again here
            self._last_pose = p
            if self.frames == 0:
                self._anchor = p
        if not still:
            self.frames = 0
        self.still = still
        return still

    @property
    def sample(self) -> int:
        """Samples accumulated so far (0 until the second frame at rest)."""
        return min(max(0, self.frames - 1), needed(self.target))

    @property
    def active(self) -> bool:
        """Refining: at rest, refinement on and not yet done."""
        return self.enabled and self.still and self.frames >= 1 and not self.done

    @property
    def done(self) -> bool:
        return self.enabled and self.still and self.sample >= needed(self.target)

    @property
    def progress(self) -> float:
        """0..1: the share of the frames refinement needs that are accumulated."""
        if not (self.enabled and self.still):
            return 0.0
        return min(1.0, self.sample / needed(self.target))

    def next_frame(self) -> RefineStep:
        """The next rendered frame's request (and count it)."""
        if not (self.enabled and self.still):
            self.frames = 0
            return RefineStep()
        self.frames += 1
        if self.frames == 1:  # the first frame at rest: as without refinement
            return RefineStep()
        s = min(self.frames - 2, needed(self.target))
        jitter = (
            (0.0, 0.0) if s >= needed(self.target) else halton_jitter(jitter_index(s, self.target))
        )
        return RefineStep(True, s, self.target, jitter)

    def status_line(self) -> str | None:
        """The overlay's line: "refining 63%", "refined", or None while moving."""
        if not (self.enabled and self.still) or self.frames < 2:
            return None
        if self.done:
            return "refined"
        return f"refining {math.floor(100 * self.progress):d}%"
