"""Shadows, spot lights and the sun: what a designer sees on the floor.

Known geometry (a 1 m box on a floor) under a point light and a spot: the floor behind the box
is dark and beside it bright; soft shadows have a graded edge and hard ones none; a flat lit floor
has no acne; maps are drawn once for a static scene and again when a light moves, at most
``render.shadow_updates_per_frame`` lights per frame; a spot's cone falls off as glTF says; the
showroom's blinds stripe the floor with the 10:00 sun.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from app import sky
from app.gltf import gltf_lights
from app.raycast import RayCaster
from app.scene import Light, Material, Scene, Viewpoint
from app.session import Session
from app.settings import Settings
from app.sky_light import occluders
from assets.showroom import WINDOW_Z, MeshBuilder, build_showroom
from render import shadow_mask
from render.offscreen import OffscreenHost

W, H = 640, 360  # both eyes: 320 x 360 each
LIGHT_POS = (2.5, 2.0, 0.0)
SHADOWED = (-1.0, 0.0, 0.0)  # behind the box, seen from the light
LIT = (-1.0, 0.0, 1.6)  # beside the shadow


def box_scene(lights: list[Light], box: bool = True) -> Scene:
    floor = MeshBuilder()
    floor.quad((-5.0, 0.0, 5.0), (10.0, 0.0, 0.0), (0.0, 0.0, -10.0))
    meshes = [floor.mesh("floor", 0)]
    if box:
        cube = MeshBuilder()
        cube.box((0.0, 0.5, 0.0), (1.0, 1.0, 1.0))
        meshes.append(cube.mesh("box", 0))
    return Scene(
        "box",
        meshes,
        [Material("grey", (0.8, 0.8, 0.8, 1.0), None, roughness=1.0)],
        [],
        lights,
        Viewpoint((-0.5, 4.0, 4.0), yaw_deg=0.0, pitch_deg=-50.0),
        floor_y=0.0,
    ).sanitized()


def spot_towards(target, inner=20.0, outer=35.0, pos=LIGHT_POS, intensity=20.0) -> Light:
    d = np.asarray(target, float) - np.asarray(pos, float)
    d /= np.linalg.norm(d)
    return Light(
        pos,
        (1.0, 1.0, 1.0),
        intensity,
        10.0,
        kind="spot",
        direction=tuple(float(v) for v in d),
        inner_cone_deg=inner,
        outer_cone_deg=outer,
    )


@pytest.fixture(scope="module")
def host():
    s = Settings()
    s.render.overlay = False
    s.render.ambient = 0.0  # a pixel's value is then its lights' alone
    s.render.ambient_estimate = False  # (not the lamps' bounce either: app/ambient.py)
    h = OffscreenHost(W, H, s)
    yield h
    assert not h.renderer.errors
    h.close()


MASK_FROM = dict(shadow_mask.MIN_LIGHTS)


@pytest.fixture(autouse=True)
def mask_from_one_light(monkeypatch):
    """The mask for every shadowed light count, so the few-light scenes here test it too (the
    renderer's own threshold: test_the_mask_waits_for_enough_lights)."""
    for mode in MASK_FROM:
        monkeypatch.setitem(shadow_mask.MIN_LIGHTS, mode, 1)


def frame(host: OffscreenHost, scene: Scene):
    session = Session(host.settings.copy())
    session.set_scene(scene)
    return session.frame_input(*host.eye_size)


def hdr(host: OffscreenHost, scene: Scene, shadows: str = "soft", frames: int = 1, **settings):
    host.settings.set("render.shadows", shadows)
    for key, value in settings.items():
        host.settings.set(key.replace("__", "."), value)
    host.set_scene(scene)
    fi = frame(host, scene)
    for _ in range(frames):
        host.draw(fi)
    return host.read_hdr(0)[..., :3].mean(axis=-1), fi


def pixel(fi, world) -> tuple[int, int]:
    """(row, column) of a world point in the left eye (row 0 at the top)."""
    eye = fi.eyes[0]
    clip = eye.view_projection @ np.array([*world, 1.0])
    x, y = clip[:2] / clip[3]
    return int((1.0 - (y * 0.5 + 0.5)) * eye.height), int((x * 0.5 + 0.5) * eye.width)


def floor_point(fi, row: int, col: int) -> np.ndarray:
    """The floor (y = 0) point seen through the centre of a left-eye pixel."""
    eye = fi.eyes[0]
    ndc = np.array([(col + 0.5) / eye.width * 2 - 1, 1 - (row + 0.5) / eye.height * 2])
    inv = eye.inverse_view_projection
    a, b = (inv @ np.array([*ndc, z, 1.0]) for z in (-1.0, 1.0))
    a, b = a[:3] / a[3], b[:3] / b[3]
    return a + (b - a) * (a[1] / (a[1] - b[1]))


def at(img, fi, world) -> float:
    r, c = pixel(fi, world)
    return float(img[r, c])


@pytest.mark.parametrize(
    "light",
    [Light(LIGHT_POS, (1, 1, 1), 20.0, 10.0), spot_towards((-0.5, 0.0, 0.6))],
    ids=["point", "spot"],
)
@pytest.mark.parametrize("shadows", ["hard", "soft"])
@pytest.mark.parametrize("detail", ["full", "half", "quarter"])
def test_the_floor_behind_a_box_is_dark_and_beside_it_bright(host, light, shadows, detail):
    """Per pixel (full) and from the screen-space mask (half, quarter) alike."""
    img, fi = hdr(host, box_scene([light]), shadows, render__shadow_detail=detail)
    assert host.renderer.shadow_mask.enabled == (detail != "full")
    lit, shadowed = at(img, fi, LIT), at(img, fi, SHADOWED)
    assert lit > 0.05
    assert shadowed < 0.02 * lit, (lit, shadowed)
    off, _ = hdr(host, box_scene([light]), "off")
    assert at(off, fi, SHADOWED) > 0.5 * lit  # the darkness is the shadow, not the light's reach
    host.settings.set("render.shadow_detail", Settings().render.shadow_detail)


def edge_profile(host, shadows: str, detail: str = "full") -> np.ndarray:
    """The shadow factor (picture / unshadowed picture) along a line across the shadow's edge."""
    light = Light(LIGHT_POS, (1, 1, 1), 20.0, 10.0)
    img, fi = hdr(host, box_scene([light]), shadows, render__shadow_detail=detail)
    host.settings.set("render.shadow_detail", Settings().render.shadow_detail)
    off, _ = hdr(host, box_scene([light]), "off")
    points = [(-1.2, 0.0, z) for z in np.linspace(0.0, 1.5, 80)]
    return np.array([at(img, fi, p) / max(at(off, fi, p), 1e-6) for p in points])


@pytest.mark.parametrize("detail, crisp", [("full", 1), ("half", 2)])
def test_soft_shadows_have_a_graded_edge_and_hard_ones_do_not(host, detail, crisp):
    """Per pixel a hard edge is one sample of the line wide; through the mask (every 2nd pixel,
    filled in between) at most two."""
    hard, soft = edge_profile(host, "hard", detail), edge_profile(host, "soft", detail)
    for profile in (hard, soft):  # both go from full shadow to full light
        assert profile[0] < 0.02 and profile[-1] > 0.98
    between = lambda p: int(np.sum((p > 0.1) & (p < 0.9)))  # noqa: E731
    assert between(hard) <= crisp
    assert between(soft) >= 2


def _sun(elevation_deg: float) -> Light:
    """A sun at this height above the horizon, from the north-east."""
    e = math.radians(elevation_deg)
    travel = (-math.cos(e) * 0.6, -math.sin(e), math.cos(e) * 0.8)
    return Light((0.0, 0.0, 0.0), (1, 1, 1), 5.0, kind="directional", direction=travel)


@pytest.mark.parametrize("shadows", ["hard", "soft"])
@pytest.mark.parametrize("kind", ["point", "spot", "sun", "low sun"])
@pytest.mark.parametrize("detail", ["full", "half"])
def test_a_flat_lit_floor_has_no_acne(host, shadows, kind, detail):
    """Shadows on a floor nothing stands on change nothing: no speckles, no stripes (per pixel
    and through the mask), under a lamp, a spot, the sun high and the sun low (12 degrees: its
    map's texels stretched over the floor, and no depth offset for the sun's map)."""
    light = {
        "point": lambda: Light((0.0, 2.5, 0.0), (1, 1, 1), 20.0, 10.0),
        "spot": lambda: spot_towards((-0.5, 0.0, 0.5), inner=40.0, outer=60.0),
        "sun": lambda: _sun(45.0),
        "low sun": lambda: _sun(12.0),
    }[kind]()
    scene = box_scene([light], box=False)
    img, fi = hdr(host, scene, shadows, render__shadow_detail=detail)
    host.settings.set("render.shadow_detail", Settings().render.shadow_detail)
    off, _ = hdr(host, scene, "off")
    top, left = pixel(fi, (-2.0, 0.0, -1.0))
    bottom, right = pixel(fi, (1.0, 0.0, 1.5))
    ratio = img[top:bottom, left:right] / np.maximum(off[top:bottom, left:right], 1e-6)
    assert ratio.size > 500
    assert ratio.min() > 0.99 and float(ratio.std()) < 0.002


def mask_lights(count: int) -> list[Light]:
    """The box's light and ``count - 1`` more around the room, near enough to matter."""
    lights = [Light(LIGHT_POS, (1, 1, 1), 20.0, 10.0)]
    for k in range(count - 1):
        a = 2.0 * math.pi * k / max(count - 1, 1)
        lights.append(Light((3.0 * math.cos(a), 1.5, 3.0 * math.sin(a)), (1, 1, 1), 4.0, 4.0))
    return lights


@pytest.mark.parametrize("shadows", ["hard", "soft"])
@pytest.mark.parametrize("count", [3, 8, 10])
def test_the_shadow_mask_gives_the_per_pixel_picture(host, shadows, count):
    """The mask (every 2nd pixel, filled in along the surfaces) against every pixel's own
    lookups, with up to 8 lights in the mask and beyond (10: two light per pixel)."""
    scene = box_scene(mask_lights(count))
    full, fi = hdr(host, scene, shadows, render__shadow_detail="full")
    half, _ = hdr(host, scene, shadows, render__shadow_detail="half")
    mask = host.renderer.shadow_mask
    assert mask.enabled and mask.lights == min(count, 8)
    assert host.renderer.shadows.shadowed == count
    host.settings.set("render.shadow_detail", Settings().render.shadow_detail)
    diff = np.abs(half - full) / max(float(full.max()), 1e-6)
    assert float(diff.mean()) < 0.002, float(diff.mean())
    assert float(np.mean(diff > 0.05)) < 0.01  # a few pixels along the shadows' edges
    off, _ = hdr(host, scene, "off")
    # The box's shadow is there (the other lamps light the spot too).
    assert at(off, fi, SHADOWED) - at(full, fi, SHADOWED) > 0.05
    assert at(half, fi, SHADOWED) == pytest.approx(at(full, fi, SHADOWED), abs=0.01)


@pytest.mark.parametrize("count, step", [(3, 2), (8, 4)])
def test_automatic_detail_spaces_the_mask_by_the_lamps(host, count, step):
    """render.shadow_detail=auto (the default): every 2nd pixel with three shadowed lamps,
    every 4th with eight, whose shadows still match the per-pixel picture."""
    assert Settings().render.shadow_detail == "auto"
    scene = box_scene(mask_lights(count))
    full, fi = hdr(host, scene, "soft", render__shadow_detail="full")
    auto, _ = hdr(host, scene, "soft", render__shadow_detail="auto")
    mask = host.renderer.shadow_mask
    assert mask.enabled and mask.lights == count and mask.step == step
    assert host.renderer.shadow_mask.targets[0].size == shadow_mask.mask_size(host.eye_size, step)
    diff = np.abs(auto - full) / max(float(full.max()), 1e-6)
    assert float(diff.mean()) < 0.003, float(diff.mean())
    assert at(auto, fi, SHADOWED) == pytest.approx(at(full, fi, SHADOWED), abs=0.01)


def test_the_mask_waits_for_enough_lights(host, monkeypatch):
    """Below ``MIN_LIGHTS`` shadowed lights the lighting looks them up per pixel (today the
    mask pays from the first light, hard or soft); shadowed either way."""
    for mode, count in MASK_FROM.items():
        monkeypatch.setitem(shadow_mask.MIN_LIGHTS, mode, count)
    assert MASK_FROM == {"hard": 1, "soft": 1}
    monkeypatch.setitem(shadow_mask.MIN_LIGHTS, "hard", 3)  # as a threshold would
    for shadows, count, used in (("hard", 2, 0), ("hard", 3, 3), ("soft", 1, 1)):
        img, fi = hdr(host, box_scene(mask_lights(count)), shadows)
        assert host.renderer.shadow_mask.lights == used, (shadows, count)
        off, _ = hdr(host, box_scene(mask_lights(count)), "off")
        assert at(off, fi, SHADOWED) - at(img, fi, SHADOWED) > 0.05  # shadowed either way


def test_a_static_scene_draws_each_map_once_and_a_moved_light_again(host):
    lights = [
        Light(LIGHT_POS, (1, 1, 1), 20.0, 10.0),
        spot_towards((-0.5, 0.0, 0.6)),
        Light((-2.0, 2.0, 1.0), (1, 1, 1), 10.0, 8.0),
    ]
    scene = box_scene(lights)
    host.settings.set("render.shadows", "soft")
    host.settings.set("render.shadow_updates_per_frame", 4)
    host.set_scene(scene)
    fi = frame(host, scene)
    maps = host.renderer.shadows
    before = maps.renders
    for _ in range(10):
        host.draw(fi)
    assert maps.renders - before == len(lights)  # once per light in 10 frames
    assert maps.shadowed == len(lights)
    moved = list(scene.lights)
    moved[0] = dataclasses.replace(moved[0], position=(2.0, 2.2, -0.5))
    with host.ctx:
        host.renderer.gpu_scene.set_lights(moved)
    host.draw(fi)
    host.draw(fi)  # a point light's six faces, two a frame: its last map meanwhile
    assert (maps.renders - before, maps.shadowed, maps.pending) == (len(lights), len(lights), 1)
    host.draw(fi)
    assert maps.renders - before == len(lights) + 1  # only the moved light's map again
    host.draw(fi)
    assert maps.renders - before == len(lights) + 1
    host.set_scene(scene)  # new geometry: every map again
    host.draw(fi)
    assert maps.renders - before == 2 * len(lights) + 1


def test_the_budget_limits_map_updates_per_frame(host):
    lights = [
        Light((x, 2.0, z), (1, 1, 1), 5.0, 8.0) for x in (-2.0, 0.0, 2.0) for z in (-1.0, 1.5)
    ]
    scene = box_scene(lights)
    host.settings.set("render.shadows", "hard")
    host.settings.set("render.shadow_updates_per_frame", 2)
    host.set_scene(scene)
    fi = frame(host, scene)
    maps = host.renderer.shadows
    host.draw(fi)  # a new scene's first frame draws every map
    assert (maps.updates, maps.shadowed, maps.pending) == (6, 6, 0)
    moved = [
        dataclasses.replace(light, position=(light.position[0], 2.3, light.position[2]))
        for light in lights
    ]
    with host.ctx:
        host.renderer.gpu_scene.set_lights(moved)
    drawn, faces = [], []
    for _ in range(10):
        before = maps.face_renders
        host.draw(fi)
        drawn.append((maps.updates, maps.shadowed, maps.pending))
        faces.append(maps.face_renders - before)
    # Two redraws at a time, each two cube faces a frame (FACES_PER_FRAME): a light's new
    # map is used once its six faces are drawn; the lights waiting keep their last shadows.
    assert faces == [4] * 9 + [0]
    assert drawn == [
        *((0, 6, 6), (0, 6, 6), (2, 6, 4)),
        *((0, 6, 4), (0, 6, 4), (2, 6, 2)),
        *((0, 6, 2), (0, 6, 2), (2, 6, 0)),
        (0, 6, 0),
    ]
    with host.ctx:  # a light switched on later waits for its turn, without a shadow
        host.renderer.gpu_scene.set_lights([*moved, Light((1.0, 2.0, 3.0), (1, 1, 1), 5.0, 8.0)])
    host.settings.set("render.shadow_updates_per_frame", 1)
    drawn, faces = [], []
    for _ in range(6):
        before = maps.face_renders
        host.draw(fi)
        drawn.append((maps.updates, maps.shadowed, maps.pending))
        faces.append(maps.face_renders - before)
    # One light at a time (the governor's lowered step): one cube face a frame, six frames.
    assert faces == [1] * 6
    assert drawn == [(0, 6, 1)] * 5 + [(1, 7, 0)]
    assert maps.memory_bytes > 0


def test_a_light_out_of_view_gets_no_map(host):
    behind = Light((0.0, 2.0, 30.0), (1, 1, 1), 5.0, 3.0)  # far behind the eye, short reach
    scene = box_scene([Light(LIGHT_POS, (1, 1, 1), 20.0, 10.0), behind])
    hdr(host, scene, "soft", render__shadow_updates_per_frame=4)
    assert host.renderer.shadows.shadowed == 1


def test_a_spot_falls_off_between_its_inner_and_outer_cone(host):
    """Spot over point light of the same intensity, pixel by pixel: glTF's smooth cone."""
    pos, inner, outer = (0.0, 2.5, 0.0), 15.0, 30.0
    spot = Light(pos, (1, 1, 1), 20.0, 10.0, "spot", (0.0, -1.0, 0.0), inner, outer)
    point = Light(pos, (1, 1, 1), 20.0, 10.0)
    a, fi = hdr(host, box_scene([spot], box=False), "off")
    b, _ = hdr(host, box_scene([point], box=False), "off")
    cos_o, cos_i = math.cos(math.radians(outer)), math.cos(math.radians(inner))
    checked = 0
    for r in np.linspace(0.0, 2.0, 21):
        p = floor_point(fi, *pixel(fi, (-r * 0.6, 0.0, r * 0.8)))  # the pixel's own point
        cos_t = pos[1] / float(np.linalg.norm(np.asarray(pos) - p))
        expected = min(max((cos_t - cos_o) / (cos_i - cos_o), 0.0), 1.0) ** 2
        assert at(a, fi, p) / at(b, fi, p) == pytest.approx(expected, abs=0.03), r
        checked += 0.05 < expected < 0.95
    assert checked >= 2  # some pixels lie inside the falloff band


def test_light_culling_keeps_spots_and_the_sun(host):
    """More than 8 lights turn tiled culling on; a spot and the sun must survive it."""
    lights = [Light((x, 0.6, -4.0), (1, 1, 1), 2.0, 1.0) for x in np.linspace(-4, 4, 9)]
    lights += [spot_towards((-0.5, 0.0, 0.6)), Light((0, 0, 0), (1, 1, 1), 0.5, kind="directional")]
    lights[-1].direction = (0.3, -0.9, -0.2)
    scene = box_scene(lights)
    culled, _ = hdr(host, scene, "soft", render__light_culling=True)
    assert host.renderer.light_cull.enabled
    full, _ = hdr(host, scene, "soft", render__light_culling=False)
    host.settings.set("render.light_culling", True)
    assert np.abs(culled - full).max() < 1e-3


def test_every_lighting_path_shows_the_shadow(host):
    light = Light(LIGHT_POS, (1, 1, 1), 20.0, 10.0)
    for settings in (
        {"render__path": "forward"},
        {"render__path": "deferred", "render__lighting": "fragment"},
        {"render__path": "deferred", "render__lighting": "compute", "cps__mode": "cps"},
        {"render__path": "deferred", "render__lighting": "fragment", "cps__mode": "cps"},
    ):
        img, fi = hdr(host, box_scene([light]), "soft", **settings)
        assert at(img, fi, SHADOWED) < 0.05 * at(img, fi, LIT), settings
    for key in ("render.path", "render.lighting", "cps.mode"):
        host.settings.set(key, Settings().get(key))


def test_gltf_spot_and_sun_read_with_their_cone_and_direction():
    down = [-math.sqrt(0.5), 0.0, 0.0, math.sqrt(0.5)]  # -90 degrees about x: -Z turns to -Y
    doc = {
        "extensions": {
            "KHR_lights_punctual": {
                "lights": [
                    {
                        "type": "spot",
                        "intensity": 40.0,
                        "range": 6.0,
                        "spot": {"innerConeAngle": 0.2, "outerConeAngle": 0.5},
                    },
                    {"type": "directional", "intensity": 3.0},
                ]
            }
        },
        "nodes": [
            {
                "translation": [1, 3, 2],
                "rotation": down,
                "extensions": {"KHR_lights_punctual": {"light": 0}},
            },
            {"extensions": {"KHR_lights_punctual": {"light": 1}}},
        ],
        "scenes": [{"nodes": [0, 1]}],
    }
    warnings: list[str] = []
    spot, sun = gltf_lights(doc, warnings)
    assert not warnings
    assert spot.kind == "spot" and spot.position == pytest.approx((1, 3, 2))
    assert spot.direction == pytest.approx((0, -1, 0), abs=1e-9)
    assert spot.inner_cone_deg == pytest.approx(math.degrees(0.2))
    assert spot.outer_cone_deg == pytest.approx(math.degrees(0.5))
    assert spot.intensity == 40.0 and spot.range_m == 6.0
    assert sun.kind == "directional" and sun.direction == pytest.approx((0, 0, -1))


def test_the_10_oclock_sun_stripes_the_showroom_floor_through_the_blinds():
    s = Settings()
    s.render.overlay = False
    # the fixed ambient keeps the dark stripes above 0 (this 8 lux sun's bounce is ~1e-5)
    s.render.ambient_estimate = False
    scene = build_showroom(0)
    # The showroom's own north (Scene.north_deg) with the default date, time and site.
    assert s.sky.time == "10:00"
    towards_sun = sky.sun_direction(dataclasses.replace(s.sky, north_deg=scene.north_deg))
    assert towards_sun[1] > 0.0 and towards_sun[0] < -0.5  # up, and in at the west window
    scene.lights.append(
        Light((0, 0, 0), (1.0, 0.95, 0.9), 8.0, kind="directional", direction=tuple(-towards_sun))
    )
    # Where the sun through the middle of the window meets the floor.
    z = 0.5 * sum(WINDOW_Z)
    t = 1.6 / towards_sun[1]
    centre = np.array([-4.0, 1.6, z]) - towards_sun * t  # on the floor (y = 0)
    scene.spawn = Viewpoint((float(centre[0]), 1.2, float(centre[2])), 90.0, -89.0)
    with OffscreenHost(640, 360, s) as host:
        host.set_scene(scene)
        fi = frame(host, scene)
        host.draw(fi)
        img = host.read_hdr(0)[..., :3].mean(axis=-1)
        assert not host.renderer.errors
    # A line across the slats' stripes (along x, the sun's way into the room).
    rows = [pixel(fi, (float(centre[0]) + dx, 0.0, float(centre[2])))[0] for dx in (-0.3, 0.3)]
    col = pixel(fi, tuple(centre))[1]
    line = img[min(rows) : max(rows), col]
    bright, dark = np.percentile(line, 90), np.percentile(line, 10)
    assert bright > 5 * dark > 0.0
    above = line > 0.5 * (bright + dark)
    changes = int(np.sum(above[1:] != above[:-1]))
    assert changes >= 12, line  # at least six bright and six dark stripes in 60 cm


def test_the_photon_tracer_emits_a_spot_within_its_cone_only():
    """A spot in a grey box sends the power of its cone (glTF falloff) and no more; the sun
    adds nothing inside a closed box (its beam enters only through openings)."""
    from app.photons import trace_photons
    from tests.test_photons import HALF, _box

    inner, outer = 20.0, 30.0
    spot = Light((0.0, 0.0, 0.0), (1.0, 1.0, 1.0), 5.0, 1e4, "spot", (0.0, -1.0, 0.0), inner, outer)
    sun = Light((0.0, 0.0, 0.0), (1.0, 1.0, 1.0), 5.0, kind="directional")
    pm = trace_photons(_box(0.5, [spot, sun]), 2**15, seed=3, max_bounces=1)
    # Expected first-hit flux on the floor (y = -HALF) through the cone, times the albedo.
    rng = np.random.default_rng(7)
    d = rng.normal(size=(400_000, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    cos_o, cos_i = math.cos(math.radians(outer)), math.cos(math.radians(inner))
    cone = np.clip((-d[:, 1] - cos_o) / (cos_i - cos_o), 0.0, 1.0) ** 2
    dist2 = np.min(HALF / np.abs(d), axis=1) ** 2
    # the renderer's falloff times d^2 (app.scene.lamp_falloff): the window, the 10 cm floor
    first_hit = dist2 / np.maximum(dist2, 0.01)
    expected = 4 * np.pi * spot.intensity * np.mean(cone * first_hit) * 0.5
    assert pm.power.sum(axis=0, dtype=np.float64) == pytest.approx([expected] * 3, rel=0.05)


def _sun_alone() -> Settings:
    """Settings under which a pixel's light is the sun's alone (no ambient term, no bounce
    estimate, no reflections, no overlay)."""
    s = Settings()
    s.render.overlay = False
    s.render.ambient = 0.0
    s.render.ambient_estimate = False
    s.render.reflections = "off"
    return s


def _sunlit_showroom() -> tuple[Scene, np.ndarray]:
    """The showroom with the default 10:00 sun (as the blinds test) and the way to the sun."""
    scene = build_showroom(0)
    towards_sun = sky.sun_direction(dataclasses.replace(Settings().sky, north_deg=scene.north_deg))
    scene.lights.append(
        Light((0, 0, 0), (1.0, 0.95, 0.9), 8.0, kind="directional", direction=tuple(-towards_sun))
    )
    return scene, np.asarray(towards_sun, float)


# On the north wall's skirting board (10 cm high, 1.5 cm deep) and the floor before it.
SKIRTING_EDGE = ((0.1, -2.996), (0.1, -2.99), (0.0, -2.981), (0.0, -2.975))


@pytest.mark.parametrize("shadows", ["hard", "soft"])
@pytest.mark.parametrize(
    "view, points",
    [  # the floor along the north wall's skirting board; the south wall under the ceiling
        (
            Viewpoint((-1.0, 0.5, -2.5), 0.0, -45.0),
            [(x, y, z) for x in np.linspace(-1.4, -0.6, 41) for y, z in SKIRTING_EDGE],
        ),
        (
            Viewpoint((-1.0, 2.0, 1.8), 180.0, 40.0),
            [(x, 3.0 - d, 2.999) for x in np.linspace(-1.4, -0.6, 41) for d in (0.01, 0.02)],
        ),
    ],
    ids=["skirting", "ceiling"],
)
def test_the_sun_does_not_leak_in_where_walls_meet(shadows, view, points):
    """Points a ray cast towards the sun finds shut in (the room's walls, ceiling and skirting
    boards are in its way) stay dark a few millimetres from the corner: the sun's map once put
    dotted lines of sunlight along the skirting boards and under the ceiling."""
    s = _sun_alone()
    scene, towards_sun = _sunlit_showroom()
    scene.spawn = view
    tris = occluders(scene)  # what casts a shadow (render.shadows.casts): not the glowing pane
    caster = RayCaster(tris, np.zeros(len(tris), np.int64))
    pts = np.asarray(points, float)
    dist, _ = caster.cast_triangles(pts + towards_sun * 1e-4, np.tile(towards_sun, (len(pts), 1)))
    assert np.isfinite(dist).all(), "every point is in the room's shade"
    with OffscreenHost(W, H, s) as host:
        img, fi = hdr(host, scene, shadows)
        off, _ = hdr(host, scene, "off")
        assert not host.renderer.errors
    sunlit = np.array([at(off, fi, p) for p in pts])  # the sun's light there, unshadowed
    assert sunlit.min() > 0.0
    ratio = np.array([at(img, fi, p) for p in pts]) / sunlit
    assert ratio.max() < 0.05, (ratio.max(), pts[ratio.argmax()])


def test_turning_from_eight_shadowed_lamps_to_one_and_back_compiles_nothing(host):
    """The lighting's variant follows the scene's shadowed lamps, not those in view: looking
    away from seven of the eight lamps (one left, the mask every 2nd pixel instead of every
    4th) and back drew with the programs already made. Before, each turn made new ones (the
    first frame with them 110-170 ms in the corridor walk: a stall while walking)."""
    scene = box_scene(mask_lights(8))
    host.settings.set("render.shadows", "soft")
    host.settings.set("render.shadow_detail", "auto")
    host.set_scene(scene)
    session = Session(host.settings.copy())
    session.set_scene(scene)
    seen = []
    for yaw in (225.0, 45.0, 225.0):  # at the room's corner: towards the room, away, back
        session.walker.place((-4.8, 0.5, -4.8), yaw, -10.0)
        session.tick(0.0)
        fi = session.frame_input(*host.eye_size)
        before = len(host.renderer.shaders)
        for _ in range(3):
            host.draw(fi)
        mask = host.renderer.shadow_mask
        seen.append((mask.lights, mask.step, len(host.renderer.shaders) - before))
    assert [s[:2] for s in seen] == [(8, 4), (1, 2), (8, 4)]
    assert [s[2] for s in seen[1:]] == [0, 0]


def test_the_sun_keeps_its_map_when_near_lamps_fill_the_atlas():
    """Three lamps whose range holds the eye want six 1024 tiles each, the sun one 2048 tile:
    together more than the atlas. The lamps' tiles are halved first (they take the most
    texels), so the sun keeps its half-centimetre texels over the room; halving the largest
    tile first gave it 1 cm ones, and dots of sunlight along the skirting boards."""
    from render.constants import SHADOW_ATLAS
    from render.shadows import MAX_FACE, SUN_TILE, fit_sizes

    wanted = {0: (SUN_TILE, 1), 1: (MAX_FACE, 6), 2: (MAX_FACE, 6), 3: (MAX_FACE, 6)}
    fitted = fit_sizes(wanted, SHADOW_ATLAS * SHADOW_ATLAS)
    assert sum(s * s * n for s, n in fitted.values()) <= SHADOW_ATLAS * SHADOW_ATLAS
    assert fitted[0] == (SUN_TILE, 1)
    assert sorted(fitted[k][0] for k in (1, 2, 3)) == [MAX_FACE // 2, MAX_FACE // 2, MAX_FACE]


def seen_points(fi, rows: np.ndarray, cols: np.ndarray, caster: RayCaster):
    """For left-eye pixels (rows, cols): the distance along each pixel's centre ray to what
    ``caster`` finds there (inf: nothing) and the point it meets, both flattened."""
    eye = fi.eyes[0]
    ndc = np.stack(
        [(cols + 0.5) / eye.width * 2 - 1, 1 - (rows + 0.5) / eye.height * 2], -1
    ).reshape(-1, 2)
    inv = eye.inverse_view_projection
    near = np.c_[ndc, -np.ones(len(ndc)), np.ones(len(ndc))] @ inv.T
    far = np.c_[ndc, np.ones(len(ndc)), np.ones(len(ndc))] @ inv.T
    near, far = near[:, :3] / near[:, 3:], far[:, :3] / far[:, 3:]
    d = (far - near) / np.linalg.norm(far - near, axis=1)[:, None]
    t, _ = caster.cast_triangles(near, d)
    return t, near + d * np.where(np.isfinite(t), t, 0.0)[:, None]


@pytest.mark.parametrize("detail", ["half", "quarter"])
def test_a_skirting_top_seen_across_the_room_stays_in_the_shade(detail):
    """From the spawn, the north wall's skirting board's top is a pixel tall, and the mask has
    no sample on it: it borrows those on the wall and the board's front, which face away from
    the sun. Those kept a factor of 1 (the sun cannot reach them), so half the top's pixels
    showed full sunlight in dots along the board, where a ray to the sun finds the wall."""
    s = _sun_alone()
    scene, towards_sun = _sunlit_showroom()
    scene.spawn = Viewpoint((3.0, 1.6, 2.3), 20.0, -4.0)
    with OffscreenHost(1280, 720, s) as host:
        img, fi = hdr(host, scene, "soft", render__shadow_detail=detail)
        off, _ = hdr(host, scene, "off")
        assert not host.renderer.errors
    rows, cols = np.mgrid[300:500, 0 : fi.eyes[0].width]
    caster = RayCaster(scene.triangles())
    t, hit = seen_points(fi, rows, cols, caster)
    top = np.isfinite(t) & (np.abs(hit[:, 1] - 0.1) < 0.002) & (hit[:, 2] > -3.0)
    top &= hit[:, 2] < -2.985  # the board's top: 10 cm up, 1.5 cm deep
    to_sun = np.tile(towards_sun, (len(hit), 1))
    shut, _ = caster.cast_triangles(hit + towards_sun * 1e-4, to_sun)
    r, c = rows.ravel(), cols.ravel()
    keep = top & np.isfinite(shut) & (off[r, c] > 0.0)
    assert keep.sum() > 40  # the board's top, seen at dozens of pixels
    ratio = img[r[keep], c[keep]] / off[r[keep], c[keep]]
    assert ratio.max() < 0.05, (float(ratio.max()), float((ratio > 0.05).mean()))


def test_the_sun_through_the_blinds_is_an_even_patch_seen_across_the_room():
    """Seen from across the showroom, the blinds' stripes on the floor are finer than a pixel
    (a path tracer shows an even patch) and far finer than the shadow mask's samples: one
    lookup per sample aliased them into blobs. Looked up over each sample's footprint the
    patch is even (less than half as uneven from pixel to pixel), with the light the
    per-pixel picture has."""
    s = _sun_alone()
    scene, _ = _sunlit_showroom()
    scene.spawn = Viewpoint(
        (2.5, 1.6, 0.5), 80.0, -10.0
    )  # the window view (docs/reference_flip.md)
    with OffscreenHost(1280, 720, s) as host:
        full, _ = hdr(host, scene, "soft", render__shadow_detail="full")
        pictures = {}
        for footprint in (True, False):
            host.renderer.shadow_mask.sun_footprint = footprint
            pictures[footprint], _ = hdr(host, scene, "soft", render__shadow_detail="quarter")
            assert host.renderer.shadow_mask.step == 4
        assert not host.renderer.errors
    # The patch on the floor below the window: where the per-pixel picture, blurred, is lit.
    floor = np.zeros(full.shape, bool)
    floor[375:430, 130:330] = True
    k = np.ones(9) / 9.0
    blurred = np.apply_along_axis(lambda r: np.convolve(r, k, "same"), 1, full)
    patch = floor & (blurred > 0.25 * blurred[floor].max())
    assert patch.sum() > 500

    def unevenness(img: np.ndarray) -> float:  # pixel to pixel, along the rows, in the patch
        step = np.abs(np.diff(img, axis=1))[patch[:, 1:] & patch[:, :-1]]
        return float(step.mean() / img[patch].mean())

    assert unevenness(pictures[True]) < 0.5 * unevenness(pictures[False])
    # The same light, spread over the footprint: the floor round the patch as a whole.
    assert pictures[True][floor].mean() == pytest.approx(full[floor].mean(), rel=0.1)


def test_a_cornice_under_the_ceiling_stays_in_the_shade():
    """A cornice's face (6 cm tall, leaning 20 degrees from the wall, along the east wall under
    the ceiling), seen from a metre away: the soft edge's taps lie on the face carried on past
    the ceiling, outside in the sun, and lit its top few millimetres in a line of sunlight
    along the ceiling (the living room's cornice in daylight; a path tracer shows none). The
    ceiling is within centimetres there towards the sun, where the sun's soft edge is far
    under a millimetre: the picture is the point's own comparison."""
    s = _sun_alone()
    scene, towards_sun = _sunlit_showroom()
    up = np.array([-0.022, 0.06, 0.0])  # from the wall 6 cm under the ceiling to the ceiling
    cornice = MeshBuilder()
    cornice.quad((3.9999, 2.94, 1.0), tuple(up), (0.0, 0.0, -2.0))
    scene.meshes.append(cornice.mesh("cornice", scene.meshes[0].material))
    normal = np.array([-up[1], up[0], 0.0]) / np.linalg.norm(up)
    assert normal @ towards_sun > 0.1  # the face turns to the sun
    scene.spawn = Viewpoint((3.0, 2.5, 0.0), -90.0, 25.0)
    with OffscreenHost(1280, 720, s) as host:
        off, fi = hdr(host, scene, "off")
        pictures = {
            d: hdr(host, scene, "soft", render__shadow_detail=d)[0] for d in ("full", "half")
        }
        assert not host.renderer.errors
    rows, cols = np.mgrid[0 : fi.eyes[0].height, 0 : fi.eyes[0].width]
    tris = occluders(scene)
    caster = RayCaster(tris, np.zeros(len(tris), np.int64))
    t, hit = seen_points(fi, rows, cols, caster)
    on_face = np.isfinite(t) & (np.abs((hit - (3.9999, 2.94, 0.0)) @ normal) < 1e-3)
    top = on_face & (hit[:, 1] > 2.995) & (np.abs(hit[:, 2]) < 0.8)  # its top 5 mm
    shut, _ = caster.cast_triangles(hit + normal * 1e-4, np.tile(towards_sun, (len(hit), 1)))
    r, c = rows.ravel(), cols.ravel()
    keep = top & (shut < 0.05) & (off[r, c] > 0.0)  # the ceiling within centimetres
    assert keep.sum() > 100  # the face's top, seen at hundreds of pixels
    for detail, img in pictures.items():
        ratio = img[r[keep], c[keep]] / off[r[keep], c[keep]]
        assert ratio.max() < 0.05, (detail, float(ratio.max()), float((ratio > 0.05).mean()))
