"""Ambient occlusion: corners darken the ambient light, open floors do not, off changes nothing.

A room corner (a floor and two walls, no lamps: the picture is the ambient term alone) seen
through the offscreen host, for the screen-space method and the per-vertex bake, in every
lighting path.
"""

from __future__ import annotations

import logging

import numpy as np
import pytest

from app.ao_bake import bake_scene, vertex_occlusion
from app.camera import StereoCamera
from app.frame import FrameInput
from app.loaders import load_scene
from app.raycast import RayCaster
from app.scene import Material, Mesh, Scene, Viewpoint
from app.settings import Settings
from render.offscreen import OffscreenHost

W, H = 320, 180  # two 160x180 eyes
ALBEDO = 0.8
AMBIENT = Settings().render.ambient


def grid(name: str, origin, du, dv, n: int, normal) -> Mesh:
    """A plane of n x n quads, wound to face ``normal``."""
    i, j = np.meshgrid(np.arange(n + 1), np.arange(n + 1), indexing="ij")
    pos = (
        np.asarray(origin, np.float64)
        + i[..., None] / n * np.asarray(du, np.float64)
        + j[..., None] / n * np.asarray(dv, np.float64)
    ).reshape(-1, 3)
    idx = []
    for a in range(n):
        for b in range(n):
            v = a * (n + 1) + b
            idx += [[v, v + n + 1, v + n + 2], [v, v + n + 2, v + 1]]
    tri = np.array(idx, np.uint32)
    if np.dot(np.cross(du, dv), normal) < 0:
        tri = tri[:, [0, 2, 1]]
    return Mesh(
        name,
        pos.astype(np.float32),
        np.tile(np.asarray(normal, np.float32), (len(pos), 1)),
        np.zeros((len(pos), 2), np.float32),
        tri,
        0,
    )


def room(walls: bool = True) -> Scene:
    """A 4 x 4 m floor at y = 0 with (``walls``) walls along x = -2 and z = -4; no lamps."""
    meshes = [grid("floor", (-2, 0, -4), (4, 0, 0), (0, 0, 4), 24, (0, 1, 0))]
    if walls:
        meshes += [
            grid("left wall", (-2, 0, -4), (0, 0, 4), (0, 2.5, 0), 24, (1, 0, 0)),
            grid("back wall", (-2, 0, -4), (4, 0, 0), (0, 2.5, 0), 24, (0, 0, 1)),
        ]
    return Scene(
        "corner" if walls else "open floor",
        meshes,
        [Material("plaster", (ALBEDO, ALBEDO, ALBEDO, 1.0), roughness=1.0)],
        lights=[],
        spawn=Viewpoint((0.5, 1.6, 0.5)),
    ).sanitized()


CORNER = (-1.97, 0.0, -3.97)
REACH_M = 0.75  # both methods' reach in these tests: a corner clearly darker at full strength
OPEN_FLOOR = (0.3, 0.0, -1.6)  # over 1.7 m from both walls


@pytest.fixture(scope="module")
def host():
    h = OffscreenHost(W, H, Settings())
    yield h
    assert not h.renderer.errors
    h.close()


def draw(host: OffscreenHost, scene: Scene, **settings) -> list:
    s = host.settings
    defaults = Settings()
    for key in ("render.path", "render.lighting", "render.ao", "render.ao_strength", "cps.mode"):
        s.set(key, defaults.get(key))
    s.set("render.ao", "screen")  # these tests look at the occlusion unless told otherwise
    s.set("render.ao_strength", 1.0)  # at full strength and the bake's reach
    s.set("render.ao_radius_m", REACH_M)
    # ... of the fixed ambient term (the estimate from the lamps is 0 in a room without any).
    s.set("render.ambient_estimate", False)
    for key, value in settings.items():
        s.set(key.replace("__", "."), value)
    if host.scene is not scene:
        host.set_scene(scene)
    host.set_text_image(None)
    cam = StereoCamera(s.stereo)
    cam.set_pose((0.5, 1.6, 0.5), 29.0, -20.0)  # towards the corner
    eyes = cam.eyes(*host.eye_size)
    host.draw(FrameInput(eyes, gaze=(-1, -1)))
    return eyes


def hdr(host: OffscreenHost, eye: int) -> np.ndarray:
    with host.ctx:
        return host.renderer.read_hdr(eye)[..., 0]


def ao_image(host: OffscreenHost, eye: int) -> np.ndarray:
    with host.ctx:
        return host.renderer.ao.read(eye)


def pixel(eye, point) -> tuple[int, int]:
    """Row and column of a world point in an eye's image (row 0 at the top)."""
    c = eye.view_projection @ np.array([*point, 1.0])
    x, y = c[:2] / c[3]
    return int((1.0 - (y * 0.5 + 0.5)) * eye.height), int((x * 0.5 + 0.5) * eye.width)


def around(img: np.ndarray, rc: tuple[int, int], r: int = 1) -> float:
    return float(img[rc[0] - r : rc[0] + r + 1, rc[1] - r : rc[1] + r + 1].mean())


@pytest.fixture(scope="module")
def corner() -> Scene:
    return bake_scene(room(), radius_m=REACH_M)[0]


@pytest.mark.parametrize("method", ["screen", "baked"])
@pytest.mark.parametrize(
    "path",
    [
        {"render__path": "deferred", "render__lighting": "compute"},
        {"render__path": "deferred", "render__lighting": "fragment"},
        {"render__path": "forward"},
        {"render__path": "deferred", "cps__mode": "cps"},
    ],
    ids=["deferred-compute", "deferred-fragment", "forward", "coarse-shading"],
)
def test_a_corner_is_darker_than_the_open_floor_in_both_eyes(host, corner, method, path):
    eyes = draw(host, corner, render__ao=method, **path)
    flat = AMBIENT * ALBEDO  # the ambient term of an unoccluded surface
    for e in (0, 1):
        img = hdr(host, e)
        in_corner = around(img, pixel(eyes[e], CORNER))
        open_floor = around(img, pixel(eyes[e], OPEN_FLOOR))
        assert open_floor == pytest.approx(flat, rel=0.05)
        assert in_corner < 0.8 * open_floor, (method, e, in_corner, open_floor)


def test_the_shipped_reach_and_strength_shade_a_corner_more_gently(host, corner):
    """At the defaults (0.3 m, 50 %: closer to Cycles on five of six views than 0.75 m at
    100 %) the corner is still darker than the open floor, but less dark than at full."""
    defaults = Settings().render
    assert (defaults.ao_radius_m, defaults.ao_strength) == (0.3, 0.5)
    eyes = draw(host, corner)
    full = around(hdr(host, 0), pixel(eyes[0], CORNER))
    draw(host, corner, render__ao_radius_m=0.3, render__ao_strength=0.5)
    img = hdr(host, 0)
    gentle = around(img, pixel(eyes[0], CORNER))
    open_floor = around(img, pixel(eyes[0], OPEN_FLOOR))
    assert full < gentle < 0.97 * open_floor, (full, gentle, open_floor)


def test_the_shipped_bake_shades_a_corner_more_gently_than_a_wide_one(host, corner):
    """The bake's shipped reach (0.3 m: closer to Cycles than 0.75 m on every lamp-lit view)
    still darkens the corner, less than the 0.75 m bake."""
    from app.ao_bake import RADIUS_M

    assert RADIUS_M == Settings().render.ao_radius_m
    eyes = draw(host, corner, render__ao="baked")
    wide = around(hdr(host, 0), pixel(eyes[0], CORNER))
    draw(host, bake_scene(room())[0], render__ao="baked")
    img = hdr(host, 0)
    shipped = around(img, pixel(eyes[0], CORNER))
    open_floor = around(img, pixel(eyes[0], OPEN_FLOOR))
    assert wide < shipped < 0.97 * open_floor, (wide, shipped, open_floor)


def test_ao_darkens_the_ambient_light_only_not_the_lamps(host, corner):
    """With a lamp, the corner loses at most the ambient share: the lamp's light stays."""
    from app.scene import PointLight

    lit = bake_scene(
        Scene(
            "lit corner",
            corner.meshes,
            corner.materials,
            lights=[PointLight((-1.5, 1.0, -3.5), (1, 1, 1), 5.0, 20.0)],
        ).sanitized()
    )[0]
    eyes = draw(host, lit, render__ao="off")
    rc = pixel(eyes[0], CORNER)
    plain = around(hdr(host, 0), rc)
    draw(host, lit, render__ao="screen")
    occluded = around(hdr(host, 0), rc)
    ambient = AMBIENT * ALBEDO
    assert plain - ambient - 1e-3 <= occluded < plain


@pytest.mark.parametrize("method", ["screen", "baked"])
def test_an_open_floor_is_unoccluded_and_even(host, method):
    floor = room(walls=False)
    eyes = draw(host, floor, render__ao=method)
    for e in (0, 1):
        ao = ao_image(host, e)
        depth_hit = hdr(host, e) > 0.02  # the floor (the background is darker)
        values = ao[depth_hit]
        assert values.size > 0.3 * ao.size
        assert values.mean() > 0.98, (method, values.mean())
        assert values.std() < 0.02  # no banding, no pattern
    assert eyes  # both eyes drawn


def test_ao_off_or_at_no_strength_is_exactly_the_plain_picture(host, corner):
    eyes = draw(host, corner, render__ao="off")
    assert not host.renderer.ao.enabled
    plain = [hdr(host, e) for e in (0, 1)]
    # the ambient term alone, the same in the corner as in the open (the albedo and the
    # specular lobe's share of the even light, a few %: shading.glsl env_brdf)
    got = around(plain[0], pixel(eyes[0], CORNER))
    assert AMBIENT * ALBEDO <= got <= AMBIENT * (ALBEDO + 0.05)
    for method in ("screen", "baked"):
        draw(host, corner, render__ao=method, render__ao_strength=0.0)
        for e in (0, 1):
            assert np.array_equal(hdr(host, e), plain[e]), method


def test_the_bake_is_deterministic_and_darkest_in_the_corner():
    a, report = bake_scene(room(), radius_m=REACH_M)
    b, _ = bake_scene(room(), radius_m=REACH_M)
    for ma, mb in zip(a.meshes, b.meshes):
        assert ma.ao is not None and mb.ao is not None
        assert np.array_equal(ma.ao, mb.ao)
    floor = a.meshes[0]
    assert floor.ao is not None
    corner_vertex = np.argmin(np.linalg.norm(floor.positions - np.array([-2, 0, -4]), axis=1))
    middle_vertex = np.argmin(np.linalg.norm(floor.positions - np.array([0.5, 0, -1.5]), axis=1))
    assert floor.ao[corner_vertex, 0] < 0.5
    assert floor.ao[middle_vertex, 0] == 1.0
    assert floor.ao[middle_vertex, 1] == 1.0  # under the floor: nothing either
    assert report.rays_per_vertex == 16
    assert report.cast == report.vertices  # no two vertices share place and normal here


def test_degenerate_input_bakes_to_open_and_renders_without_nan(host):
    nan = np.float32(np.nan)
    positions = np.array([[0, 0, 0], [1, 0, 0], [nan, 0, 0], [0, 0, 1]], np.float32)
    normals = np.array([[0, 1, 0], [0, 0, 0], [0, 1, 0], [nan, 1, 0]], np.float32)
    caster = RayCaster(np.zeros((0, 3, 3), np.float32))
    ao = vertex_occlusion(positions, normals, caster)
    assert np.isfinite(ao).all() and (ao == 1.0).all()
    # A sliver (zero area) and a mesh with nothing left: the scene still bakes and draws.
    sliver = Mesh(
        "sliver",
        np.array([[0, 0, 0], [1, 0, 0], [2, 0, 0]], np.float32),
        np.zeros((3, 3), np.float32),
        np.zeros((3, 2), np.float32),
        np.array([[0, 1, 2]], np.uint32),
    )
    empty = Mesh(
        "empty",
        np.zeros((0, 3), np.float32),
        np.zeros((0, 3), np.float32),
        np.zeros((0, 2), np.float32),
        np.zeros((0, 3), np.uint32),
    )
    base = room()
    raw = Scene("broken", [*base.meshes, sliver, empty], base.materials)
    baked, _ = bake_scene(raw)  # unsanitized input: must not raise
    assert all(m.ao is None or np.isfinite(m.ao).all() for m in baked.meshes)
    scene = bake_scene(raw.sanitized())[0]
    for method in ("screen", "baked"):
        draw(host, scene, render__ao=method)
        for e in (0, 1):
            assert np.isfinite(hdr(host, e)).all()
            assert np.isfinite(ao_image(host, e)).all()
    empty_scene, report = bake_scene(Scene("nothing", [], [Material("m")]))
    assert report.vertices == 0 and not empty_scene.meshes


def test_baked_ao_follows_a_scene_switch(host, corner):
    eyes = draw(host, corner, render__ao="baked")
    assert around(ao_image(host, 0), pixel(eyes[0], CORNER)) < 0.6
    open_floor = bake_scene(room(walls=False))[0]
    eyes = draw(host, open_floor, render__ao="baked")
    assert around(ao_image(host, 0), pixel(eyes[0], CORNER)) > 0.95
    # A scene without a bake is drawn unoccluded while it bakes in the background.
    unbaked = room()
    assert all(m.ao is None for m in unbaked.meshes)
    draw(host, unbaked, render__ao="baked")
    gpu = host.renderer.gpu_scene
    assert gpu is not None and gpu.ao_bake is not None
    assert gpu.ao_bake.wait(60)
    eyes = draw(host, unbaked, render__ao="baked")
    assert around(ao_image(host, 0), pixel(eyes[0], CORNER)) < 0.6


def test_a_shared_interior_bakes_every_vertex_and_reports_the_time(scenes_dir, caplog):
    scene = load_scene(scenes_dir / "interiors" / "bathroom" / "bathroom.gltf")
    with caplog.at_level(logging.INFO, logger="app.ao_bake"):
        baked, report = bake_scene(scene, scene.ray_caster)
    for m in baked.meshes:
        assert m.ao is not None and m.ao.shape == (m.positions.shape[0], 2)
        assert np.isfinite(m.ao).all()
    front = np.concatenate([m.ao[:, 0] for m in baked.meshes if m.ao is not None])
    assert 0.0 <= front.min() < 0.2 and front.max() == 1.0  # buried corners and open surfaces
    # the ray budget holds on a 380,000-triangle room: at least 4 rays a side, fewer than 16
    assert 4 <= report.rays_per_vertex < 16
    assert report.cast <= report.vertices
    lines = [r.getMessage() for r in caplog.records if "ambient occlusion baked" in r.getMessage()]
    assert lines and f"{report.seconds:.2f} s" in lines[0]
    print(lines[0])  # the bake time on a shared interior (pytest -s shows it)


def test_screen_ao_is_the_same_every_frame(host, corner):
    draw(host, corner, render__ao="screen")
    first = [ao_image(host, e) for e in (0, 1)]
    draw(host, corner, render__ao="screen")
    for e in (0, 1):
        assert np.array_equal(ao_image(host, e), first[e])  # fixed pattern, no time
    assert not np.array_equal(first[0], first[1])  # each eye its own view


def test_with_photon_indirect_light_the_ambient_term_is_not_occluded(host, corner):
    from app.photon_map import PhotonMap

    pictures = {}
    for method in ("off", "screen"):
        eyes = draw(host, corner, render__ao=method)
        with host.ctx:
            r = host.renderer
            r.set_photons(PhotonMap.empty())
            host.fbo.use()
            r.render(FrameInput(eyes, gaze=(-1, -1)), host.fbo)
            pictures[method] = r.read_hdr(0)
            assert r.ao.skipped_for_indirect == (method == "screen")
            r.set_photons(None)
    assert np.array_equal(pictures["off"], pictures["screen"])


@pytest.mark.parametrize(
    "values, expected",
    [
        ({}, ["gbuffer", "ao", "lighting", "emissive"]),
        ({"render.path": "forward"}, ["ao", "forward"]),
        ({"cps.mode": "cps", "cps.temporal": False}, ["gbuffer", "cps_levels", "ao"]),
        ({"render.ao": "off"}, ["gbuffer", "lighting", "emissive"]),
    ],
)
def test_the_ao_pass_runs_after_the_g_buffer_before_the_lighting(host, corner, values, expected):
    draw(host, corner, **{k.replace(".", "__"): v for k, v in values.items()})
    ran = [name for name in host.renderer.pass_ms() if name != "shadows"]  # shadow maps first
    assert ran[: len(expected)] == expected
    assert Settings().render.ao == "off"  # the default (render/ao.py says why)
    host.settings.set("cps.temporal", Settings().cps.temporal)
