"""Stereo camera: parallel eyes with asymmetric (off-axis) frusta.

Both eyes look in the same direction; each frustum is shifted towards the other eye so that the
two images coincide on the convergence plane (zero disparity there, crossed in front, uncrossed
behind). Matrices are float64 row-major numpy (column vectors, OpenGL clip conventions);
upload them with ``gl_bytes``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from app.settings import StereoSettings

MIN_NEAR = 1e-4
MAX_COORD = 1e7  # beyond this float32 depth and positions are meaningless; clamp instead


def gl_bytes(m: np.ndarray) -> bytes:
    """A row-major matrix as the column-major float32 bytes GLSL expects."""
    return np.ascontiguousarray(m.T, dtype=np.float32).tobytes()


def _finite(x: float, fallback: float) -> float:
    x = float(x)
    return x if math.isfinite(x) else fallback


def orientation(yaw_deg: float, pitch_deg: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(right, up, forward) unit vectors. Yaw 0 looks down -Z; positive yaw turns left."""
    yaw = math.radians(_finite(yaw_deg, 0.0) % 360.0)
    pitch = math.radians(max(-89.9, min(89.9, _finite(pitch_deg, 0.0))))
    fwd = np.array(
        [-math.sin(yaw) * math.cos(pitch), math.sin(pitch), -math.cos(yaw) * math.cos(pitch)]
    )
    right = np.array([math.cos(yaw), 0.0, -math.sin(yaw)])
    up = np.cross(right, fwd)
    return right, up, fwd


def look_matrix(eye: np.ndarray, right: np.ndarray, up: np.ndarray, fwd: np.ndarray) -> np.ndarray:
    m = np.eye(4)
    m[0, :3], m[1, :3], m[2, :3] = right, up, -fwd
    m[:3, 3] = -m[:3, :3] @ eye
    return m


def frustum(
    left: float, right: float, bottom: float, top: float, near: float, far: float
) -> np.ndarray:
    m = np.zeros((4, 4))
    m[0, 0] = 2 * near / (right - left)
    m[0, 2] = (right + left) / (right - left)
    m[1, 1] = 2 * near / (top - bottom)
    m[1, 2] = (top + bottom) / (top - bottom)
    m[2, 2] = -(far + near) / (far - near)
    m[2, 3] = -2 * far * near / (far - near)
    m[3, 2] = -1.0
    return m


def jittered(
    projection: np.ndarray, jitter: tuple[float, float], width: int, height: int
) -> np.ndarray:
    """``projection`` with the picture moved by ``jitter`` pixels (x right, y up): a shift of
    the clip-space x and y by 2 * jitter / size times w, so depth is untouched."""
    dx, dy = (_finite(v, 0.0) for v in jitter)
    m = projection.copy()
    m[0, :] += (2.0 * dx / max(1, width)) * m[3, :]
    m[1, :] += (2.0 * dy / max(1, height)) * m[3, :]
    return m


@dataclass
class EyeView:
    """Everything a pass needs to draw one eye."""

    index: int  # 0 left, 1 right
    position: np.ndarray  # world-space eye position
    view: np.ndarray
    projection: np.ndarray
    width: int
    height: int
    near: float
    far: float

    @cached_property
    def view_projection(self) -> np.ndarray:
        # Worked out once: the passes ask for it about a hundred times a frame (each draw).
        return self.projection @ self.view

    @cached_property
    def inverse_view_projection(self) -> np.ndarray:
        # Factor by factor: inverting the product directly loses precision far from the origin.
        return np.linalg.inv(self.view) @ np.linalg.inv(self.projection)

    def ray(self, u: float, v: float) -> np.ndarray:
        """World-space unit direction through normalised viewport point (u, v), (0,0) top-left."""
        u = min(1.0, max(0.0, _finite(u, 0.5)))
        v = min(1.0, max(0.0, _finite(v, 0.5)))
        ndc = np.array([2 * u - 1, 1 - 2 * v, -1.0, 1.0])
        p = np.linalg.inv(self.projection) @ ndc
        d_view = p[:3] / p[3]
        d = np.linalg.inv(self.view)[:3, :3] @ d_view
        return d / np.linalg.norm(d)


class StereoCamera:
    """Head pose plus stereo parameters; produces the two EyeViews for a viewport size."""

    def __init__(self, settings: StereoSettings | None = None) -> None:
        self.settings = settings or StereoSettings()
        self.position = np.array([0.0, 1.6, 0.0])
        self.yaw_deg = 0.0
        self.pitch_deg = 0.0

    def set_pose(self, position, yaw_deg: float, pitch_deg: float) -> None:
        p = np.asarray(position, np.float64)
        self.position = np.clip(np.where(np.isfinite(p), p, self.position), -MAX_COORD, MAX_COORD)
        self.yaw_deg = _finite(yaw_deg, self.yaw_deg) % 360.0
        self.pitch_deg = max(-89.9, min(89.9, _finite(pitch_deg, self.pitch_deg)))

    def clip_planes(self) -> tuple[float, float]:
        s = self.settings
        near = max(MIN_NEAR, _finite(s.near_m, 0.05))
        far = _finite(s.far_m, 200.0) if s.far_m > 0 else 200.0
        far = min(max(far, near * 1.001 + 1e-6), 1e7)
        return near, far

    def eyes(
        self, width: int, height: int, jitter: tuple[float, float] = (0.0, 0.0)
    ) -> list[EyeView]:
        """Left and right eye for one eye viewport of width x height pixels; ``jitter``
        shifts both eyes' pictures by a sub-pixel offset (pixels, x right and y up: the
        refinement's samples, ``app.refine``)."""
        s = self.settings
        width, height = max(1, int(width)), max(1, int(height))
        near, far = self.clip_planes()
        half_ipd = max(0.0, _finite(s.ipd_mm, 64.0)) / 2000.0
        conv = max(_finite(s.convergence_m, 2.0), 1e-3)
        fov = math.radians(min(170.0, max(1.0, _finite(s.fov_deg, 95.0))))
        top = near * math.tan(fov / 2)
        half_w = top * width / height
        right, up, fwd = orientation(self.yaw_deg, self.pitch_deg)
        views = []
        for index, side in ((0, -1.0), (1, 1.0)):
            eye = self.position + side * half_ipd * right
            shift = -side * half_ipd * near / conv  # frustum moves towards the other eye
            proj = frustum(-half_w + shift, half_w + shift, -top, top, near, far)
            if jitter != (0.0, 0.0):
                proj = jittered(proj, jitter, width, height)
            views.append(
                EyeView(
                    index, eye, look_matrix(eye, right, up, fwd), proj, width, height, near, far
                )
            )
        return views

    def gaze_ray(
        self, u: float, v: float, width: int, height: int
    ) -> tuple[np.ndarray, np.ndarray]:
        """The cyclopean gaze ray (origin between the eyes, unit direction) for the point (u, v)
        that the gaze marks in both eye viewports.

        Both eyes' rays through (u, v) meet the convergence plane at the same point (the
        off-axis frusta share their window there), so the eyes look at that point; the ray
        from between the eyes through it is the gaze. A ray from one eye would sweep sideways
        by half the IPD per convergence distance and miss small far objects.
        """
        width, height = max(1, int(width)), max(1, int(height))
        near, far = self.clip_planes()
        fov = math.radians(min(170.0, max(1.0, _finite(self.settings.fov_deg, 95.0))))
        top = near * math.tan(fov / 2)
        half_w = top * width / height
        right, up, fwd = orientation(self.yaw_deg, self.pitch_deg)
        centre = EyeView(
            -1,
            self.position.copy(),
            look_matrix(self.position, right, up, fwd),
            frustum(-half_w, half_w, -top, top, near, far),
            width,
            height,
            near,
            far,
        )
        return centre.position, centre.ray(u, v)

    def horizontal_fov_deg(self, width: int, height: int) -> float:
        fov = math.radians(self.settings.fov_deg)
        return math.degrees(2 * math.atan(math.tan(fov / 2) * width / max(1, height)))


def disparity_px(depth_m: float, width: int, height: int, settings: StereoSettings) -> float:
    """Analytic screen disparity (left x minus right x, pixels) of a point on the centre line.

    x_ndc,left - x_ndc,right = 2 e n / (w Z) - 2 e n / (w C) with e = ipd/2 and w = n tan(fov_x/2),
    so the pixels are W/2 times that: W e (1/Z - 1/C) / tan(fov_x/2).
    """
    e = settings.ipd_mm / 2000.0
    tan_half_x = math.tan(math.radians(settings.fov_deg) / 2) * width / height
    return width * e * (1.0 / depth_m - 1.0 / settings.convergence_m) / tan_half_x
