"""The extremes suite: every pass of the frame under settings and inputs at their limits.

A loaded scene with NaN vertices, zero-area triangles and textures of 1x1, 1xN,
non-power-of-two and 16 bits; the camera inside geometry, on a wall, far away; near and far
planes at their limits (near = far, near > far, near -> 0, huge far); the gaze at the screen
corners or not a number; every CPS mode and block size, TCR in both modes, photon mapping with
every gather variant and tiny and huge radii. Expected everywhere: no exception escapes, no pass
logs an error, no NaN or Inf in any float target read back (HDR colour of both eyes, the photon
irradiance), CPS levels within 0..5.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from PIL import Image

from app.loaders import load_scene
from app.paths import PathKey
from app.session import Session
from app.settings import Settings
from render.offscreen import OffscreenHost

W, H = 96, 48

TOUCHED = (
    "stereo.near_m",
    "stereo.far_m",
    "stereo.fov_deg",
    "stereo.ipd_mm",
    "stereo.convergence_m",
    "render.path",
    "render.lighting",
    "render.brightness",
    "render.exposure",
    "cps.mode",
    "cps.max_level",
    "cps.fovea_deg",
    "cps.temporal",
    "cps.filter",
    "tcr.enabled",
    "tcr.mode",
    "tcr.f_m",
    "photons.enabled",
    "photons.radius_m",
    "photons.gather",
    "photons.k",
    "photons.stereo_reuse",
)


def stress_scene(folder: Path):
    """An OBJ room whose contents are each a known hazard, loaded through the real loader."""
    textures = {
        "one.png": Image.fromarray(np.array([[[200, 30, 30]]], np.uint8)),
        "row.png": Image.fromarray(
            np.random.default_rng(0).integers(0, 255, (1, 7, 3), dtype=np.uint8)
        ),
        "npot.png": Image.fromarray(
            np.random.default_rng(1).integers(0, 255, (5, 13, 3), dtype=np.uint8)
        ),
        "deep.png": Image.fromarray(
            np.random.default_rng(2).integers(0, 65535, (6, 6), dtype=np.uint16)
        ),  # 16-bit grey
    }
    for name, img in textures.items():
        img.save(folder / name)
    mtl = ["newmtl wall\nKd 0.7 0.7 0.7"]
    for i, name in enumerate(textures):
        mtl.append(f"newmtl t{i}\nKd 1 1 1\nmap_Kd {name}")
    (folder / "room.mtl").write_text("\n".join(mtl) + "\n")
    v: list[str] = []
    f: list[str] = []

    def quad(corners, material):
        f.append(f"usemtl {material}")
        base = len(v) // 1 + 1
        for c in corners:
            v.append("v {} {} {}".format(*c))
        f.append(f"f {base}/1 {base + 1}/2 {base + 2}/3")
        f.append(f"f {base}/1 {base + 2}/3 {base + 3}/4")

    # The room (inward and outward faces both: the walls are one-sided quads)
    quad([(-3, 0, -3), (3, 0, -3), (3, 0, 3), (-3, 0, 3)], "wall")  # floor
    quad([(-3, 3, -3), (-3, 3, 3), (3, 3, 3), (3, 3, -3)], "wall")  # ceiling
    quad([(-3, 0, -3), (-3, 3, -3), (3, 3, -3), (3, 0, -3)], "wall")  # far wall
    quad([(-3, 0, 3), (3, 0, 3), (3, 3, 3), (-3, 3, 3)], "wall")  # back wall
    for i, x in enumerate((-2.0, -0.7, 0.6, 1.9)):  # the textured panels
        quad([(x, 0.5, -2.9), (x + 1, 0.5, -2.9), (x + 1, 1.5, -2.9), (x, 1.5, -2.9)], f"t{i}")
    f.append("usemtl wall")
    n = len(v)
    v += [
        "v 0 1 0",
        "v 0 1 0",
        "v 0 1 0",  # zero-area triangle
        "v 1 1 1",
        "v 2 1 1",
        "v 3 1 1",  # collinear
        "v nan 1 0",
        "v 1 inf 0",
        "v 0 1 1",
    ]  # non-finite
    f += [f"f {n + 1} {n + 2} {n + 3}", f"f {n + 4} {n + 5} {n + 6}", f"f {n + 7} {n + 8} {n + 9}"]
    uv = "vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n"
    (folder / "room.obj").write_text(
        "mtllib room.mtl\n" + uv + "\n".join(v) + "\n" + "\n".join(f) + "\n"
    )
    scene = load_scene(folder / "room.obj")
    scene.indirect = True
    return scene


@pytest.fixture(scope="module")
def rig(tmp_path_factory):
    scene = stress_scene(tmp_path_factory.mktemp("stress"))
    s = Settings()
    s.render.overlay = False
    s.photons.photons = 4096
    s.photons.indirect = "gather"  # the gather variants and their grids (the cache: its own test)
    with OffscreenHost(W, H, s) as host:
        host.set_scene(scene)
        session = Session(s)
        session.set_scene(scene)
        yield host, session, scene


NUM = st.sampled_from
POSITIONS = NUM(
    [
        (0.0, 1.6, 0.0),
        (0.0, 1.0, -2.9),
        (-3.0, 1.5, 0.0),
        (0.0, 0.0, 0.0),
        (0.0, 1.6, 1e5),
        (2.999, 2.999, 2.999),
        (-2.0, 1.0, -2.9),
    ]
)
GAZES = NUM(
    [
        (0.5, 0.5),
        (0.0, 0.0),
        (1.0, 1.0),
        (0.0, 1.0),
        (1.0, 0.0),
        (float("nan"), 0.5),
        (-5.0, 1e30),
        (float("inf"), -float("inf")),
    ]
)


@settings(
    max_examples=45,
    deadline=None,
    derandomize=True,
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
)
@given(
    near=NUM([1e-4, 0.05, 5.0, 10.0]),
    far=NUM([1.0, 10.0, 200.0, 1e5]),
    fov=NUM([30.0, 95.0, 130.0]),
    ipd=NUM([0.0, 64.0, 100.0]),
    convergence=NUM([0.1, 2.0, 1e4]),
    position=POSITIONS,
    yaw=NUM([0.0, 90.0, -179.0]),
    pitch=NUM([0.0, 89.0, -89.0]),
    gaze=GAZES,
    fixed=st.booleans(),
    path=NUM(["deferred", "forward"]),
    lighting=NUM(["compute", "fragment"]),
    brightness=NUM([0.0, 1.0, 16.0]),
    exposure=NUM([0.0, 1.0, 64.0]),
    cps=NUM(["none", "cps", "black-mask", "blur-mask"]),
    level=NUM([0, 1, 5]),
    fovea=NUM([0.0, 10.0, 180.0]),
    temporal=st.booleans(),
    filt=NUM(["none", "bilinear", "hierarchical"]),
    tcr=st.booleans(),
    tcr_mode=NUM(["paper", "clamp"]),
    f_m=NUM([1e-6, 1.0, 100.0]),
    photons=NUM(["off", "on"]),
    radius=NUM([1e-3, 0.05, 0.5, 100.0]),
    gather=NUM(["radius", "radius-half", "heap", "kdtree", "kdtree-heap", "shared"]),
    k=NUM([1, 64]),
    reuse=st.booleans(),
)
def test_no_nan_no_exception_levels_in_range(
    rig,
    near,
    far,
    fov,
    ipd,
    convergence,
    position,
    yaw,
    pitch,
    gaze,
    fixed,
    path,
    lighting,
    brightness,
    exposure,
    cps,
    level,
    fovea,
    temporal,
    filt,
    tcr,
    tcr_mode,
    f_m,
    photons,
    radius,
    gather,
    k,
    reuse,
):
    host, session, _scene = rig
    values = dict(
        zip(
            TOUCHED,
            (
                near,
                far,
                fov,
                ipd,
                convergence,
                path,
                lighting,
                brightness,
                exposure,
                cps,
                level,
                fovea,
                temporal,
                filt,
                tcr,
                tcr_mode,
                f_m,
                photons,
                radius,
                gather,
                k,
                reuse,
            ),
        )
    )
    for key, value in values.items():
        host.settings.set(key, value)
    session.apply_key(PathKey(0.0, position, yaw, pitch, gaze, fixed), 1 / 60)
    frame = session.frame_input(*host.eye_size)
    img = host.draw(frame)
    r = host.renderer
    assert img.shape == (H, W, 3)
    assert not r.errors, r.errors
    for eye in (0, 1):
        hdr = host.read_hdr(eye)
        assert np.isfinite(hdr).all(), f"eye {eye}: non-finite HDR pixels"
    with host.ctx:
        if r.photons.active and r.photons.gmap is not None:
            for eye in (0, 1):
                assert np.isfinite(r.photons.read_indirect(eye)).all()
        if r.cps_levels.enabled:
            for m in r.cps.read_levels():
                assert m.max(initial=0) <= 5
        if r.photons.active and radius == 1e-3:
            # 1 mm cells over a 6 m room: far too many; reported, nothing drawn wrong.
            assert r.photons.gmap is None and "cells" in (r.photons.error or "")
