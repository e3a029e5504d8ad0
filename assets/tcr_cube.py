"""The TCR paper's experiment: a textured cube of side f seen along the view axis.

Three built-in paths reproduce the paper's runs: ``tcr_cube_distance`` (the viewer steps back
from f to 64 f, standing still at each distance, so the state stays "viewpoint still"),
``tcr_cube_orbit`` (the viewpoint circles the cube: state 1) and ``tcr_cube_gaze`` (the gaze is
held on the cube while standing, then while orbiting: states 2 and 3).
"""

from __future__ import annotations

import math

from app.paths import CameraPath, PathKey
from app.scene import Material, PointLight, Scene, Viewpoint
from assets.showroom import MeshBuilder
from assets.textures import painting_abstract

SIDE_M = 1.0  # = the default eye-to-screen distance f (tcr.f_m)
CENTRE = (0.0, 1.6, 0.0)
DISTANCES_F = (1.5, 2, 3, 4, 6, 8, 12, 16, 24, 32, 48, 64)
HOLD_S = 1.0  # standing still at each distance, longer than the state machine's window


def build_tcr_cube() -> Scene:
    b = MeshBuilder()
    b.box(CENTRE, (SIDE_M, SIDE_M, SIDE_M))
    mesh = b.mesh("cube", 0)
    texture = painting_abstract(512)
    light = PointLight((0.0, 4.0, 6.0), (1.0, 1.0, 1.0), 60.0, 200.0)
    scene = Scene(
        "tcr-cube",
        [mesh],
        [Material("cube", (1, 1, 1, 1), 0, roughness=0.8)],
        [texture],
        [light],
        Viewpoint((0.0, 1.6, DISTANCES_F[0] * SIDE_M)),
        source="built-in",
    )
    return scene.sanitized()


def distance_path() -> CameraPath:
    keys: list[PathKey] = []
    t = 0.0
    for d in DISTANCES_F:
        pos = (CENTRE[0], CENTRE[1], CENTRE[2] + SIDE_M / 2 + d * SIDE_M)
        keys.append(PathKey(t, pos))
        t += HOLD_S
        keys.append(PathKey(t - 1 / 60, pos))
    return CameraPath(keys, "tcr-cube")


def orbit_path(radius_f: float = 4.0, seconds: float = 6.0, fixed_gaze: bool = False) -> CameraPath:
    keys = []
    steps = 48
    for i in range(steps + 1):
        a = 2 * math.pi * i / steps
        x = CENTRE[0] + math.sin(a) * radius_f * SIDE_M
        z = CENTRE[2] + math.cos(a) * radius_f * SIDE_M
        keys.append(
            PathKey(
                seconds * i / steps, (x, CENTRE[1], z), math.degrees(a), 0.0, (0.5, 0.5), fixed_gaze
            )
        )
    return CameraPath(keys, "tcr-cube")


def gaze_path() -> CameraPath:
    """Stand and hold the gaze on the cube (state 2), then orbit holding it (state 3)."""
    pos = (CENTRE[0], CENTRE[1], CENTRE[2] + 4.0 * SIDE_M)
    keys = [
        PathKey(0.0, pos, 0, 0, (0.5, 0.5), False),
        PathKey(1.0, pos, 0, 0, (0.5, 0.5), True),
        PathKey(3.0, pos, 0, 0, (0.5, 0.5), True),
    ]
    for k in orbit_path(fixed_gaze=True).keys:
        keys.append(PathKey(3.0 + 1 / 60 + k.t, k.position, k.yaw_deg, k.pitch_deg, k.gaze, True))
    return CameraPath(keys, "tcr-cube")
