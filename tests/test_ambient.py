"""The ambient term estimated from the lamps' bounced light (app/ambient.py,
``render.ambient_estimate``): what the photon tracer finds in a closed box, nothing where no
light comes back, and the frame's even light follows it."""

from __future__ import annotations

import math

import numpy as np
import pytest

from app.ambient import AmbientProbe, estimate_ambient
from app.camera import StereoCamera
from app.frame import FrameInput
from app.photons import trace_photons
from app.scene import Light, Material, PointLight, Scene, Viewpoint
from app.settings import Settings
from render.offscreen import OffscreenHost
from tests.test_photons import HALF, _box, _box_walls, _quad


def _box_area() -> float:
    x, y, z = 2.0 * HALF
    return 2.0 * (x * y + y * z + x * z)


@pytest.mark.parametrize("albedo", [0.3, 0.6])
def test_closed_box_matches_the_photon_tracer(albedo):
    """Inside a closed grey box every bounce stays in the room: the even indirect light is the
    photon map's stored power (all bounces) over the walls' area, within 6 %."""
    scene = _box(albedo, [PointLight((0.5, 0.4, -0.3), (1.0, 1.0, 1.0), 8.0, 1e4)])
    pm = trace_photons(scene, 2**16, seed=5, max_bounces=40)
    luma = np.array([0.2126, 0.7152, 0.0722])
    photon_irradiance = float(pm.power.sum(axis=0, dtype=np.float64) @ luma) / _box_area()
    est = estimate_ambient(scene)
    assert est.closure == pytest.approx(0.5, abs=0.01)  # inner faces see all, outer none
    assert est.mean_albedo == pytest.approx(albedo, rel=1e-6)
    assert est.ambient * math.pi == pytest.approx(photon_irradiance, rel=0.06)
    assert estimate_ambient(scene) == est, "seeded: the same value every time"


def test_no_light_comes_back_from_black_walls_an_open_floor_or_a_lamp_outside():
    lamp = PointLight((0.0, 0.0, 0.0), (1.0, 1.0, 1.0), 8.0, 1e4)
    assert estimate_ambient(_box(0.0, [lamp])).ambient == 0.0  # black walls
    assert estimate_ambient(_box(0.6, [])).ambient == 0.0  # no lamp
    outside = PointLight((0.0, 5.0, 0.0), (1.0, 1.0, 1.0), 8.0, 1e4)
    assert estimate_ambient(_box(0.6, [outside])).ambient == 0.0  # the box shades itself
    floor = _quad(
        "floor",
        np.array([[-5, 0, -5], [5, 0, -5], [5, 0, 5], [-5, 0, 5]], float),
        np.array([0.0, 1.0, 0.0]),
        0,
    )
    open_floor = Scene("floor", [floor], [Material("white", (1, 1, 1, 1))], lights=[outside])
    assert estimate_ambient(open_floor).ambient == 0.0  # its light goes to the sky
    assert estimate_ambient(Scene("empty", [], [], lights=[outside])).ambient == 0.0


def test_a_paler_room_and_the_sun_give_more_even_light():
    lamp = PointLight((0.5, 0.4, -0.3), (1.0, 1.0, 1.0), 8.0, 1e4)
    dark, pale = estimate_ambient(_box(0.3, [lamp])), estimate_ambient(_box(0.7, [lamp]))
    assert pale.ambient > 3.0 * dark.ambient
    # A directional light into an open-topped box: only the sun that gets in counts.
    walls = [m for m in _box_walls() if m.name != "wall11"]  # no ceiling
    scene = Scene("open box", walls, [Material("grey", (0.5, 0.5, 0.5, 1.0))])
    straight = Light((0, 0, 0), (1, 1, 1), 100.0, kind="directional", direction=(0, -1, 0))
    low = Light((0, 0, 0), (1, 1, 1), 100.0, kind="directional", direction=(0.0, 0.1, -1.0))
    assert estimate_ambient(scene, [straight]).ambient > 1.0
    assert estimate_ambient(scene, [low]).ambient == 0.0  # from below the horizon


def _wall_luminance(s: Settings) -> float:
    scene = _box(0.5, [PointLight((0.5, 0.4, -0.3), (1.0, 1.0, 1.0), 8.0, 1e4)])
    scene.spawn = Viewpoint((0.0, 0.0, 1.5))
    with OffscreenHost(160, 90, s) as host:
        host.set_scene(scene)
        cam = StereoCamera(s.stereo)
        cam.set_pose(scene.spawn.position, 0.0, 0.0)
        host.draw(FrameInput(cam.eyes(*host.eye_size), gaze=(0.5, 0.5)))
        hdr = host.read_hdr(0)[:, :, :3]
    lum = hdr @ np.array([0.2126, 0.7152, 0.0722])
    return float(np.median(lum))


def _env_brdf(roughness: float, ndv: float) -> tuple[float, float]:
    """shading.glsl ``env_brdf`` (Karis's fit of the split-sum environment BRDF)."""
    c0, c1 = np.array([-1.0, -0.0275, -0.572, 0.022]), np.array([1.0, 0.0425, 1.04, -0.04])
    r = roughness * c0 + c1
    a004 = min(r[0] * r[0], 2.0 ** (-9.28 * ndv)) * r[0] + r[1]
    return -1.04 * a004 + r[2], 1.04 * a004 + r[3]


def test_the_frame_takes_the_estimate():
    """The wall facing the camera is lit by the lamp plus the even light: with the estimate,
    brighter by (albedo + its specular share) x (the estimate for the way the wall faces -
    render.ambient)."""
    s = Settings()
    s.set("render.ambient_by_place", False)  # the one level (the field: test_ambient_field)
    s.set("render.ambient_estimate", False)
    fixed = _wall_luminance(s)
    s.set("render.ambient_estimate", True)
    estimated = _wall_luminance(s)
    scene = _box(0.5, [PointLight((0.5, 0.4, -0.3), (1.0, 1.0, 1.0), 8.0, 1e4)])
    x, y = _env_brdf(scene.materials[0].roughness, 1.0)  # the wall seen head-on
    reflects = 0.5 + 0.04 * x + y
    want = reflects * (estimate_ambient(scene).along((0.0, 0.0, 1.0)) - s.render.ambient)
    assert want > 0.05
    assert estimated - fixed == pytest.approx(want, rel=0.05)


def test_the_even_light_is_brighter_where_the_lamps_light_what_a_face_sees():
    """A low lamp under a white ceiling over a dark floor: the floor, which sees the lit
    ceiling, gets more of the bounce than the ceiling, which sees the dark floor; the
    estimate's gradient says so, and the mean is what a person standing there sees."""
    walls = _box_walls()
    mats = [Material("grey", (0.5, 0.5, 0.5, 1.0)), Material("white", (0.9, 0.9, 0.9, 1.0))]
    mats.append(Material("dark", (0.1, 0.1, 0.1, 1.0)))
    for m in walls:
        if m.name == "wall11":  # the ceiling
            m.material = 1
        elif m.name == "wall1-1":  # the floor
            m.material = 2
    lamp = PointLight((0.0, HALF[1] - 0.3, 0.0), (1.0, 1.0, 1.0), 8.0, 1e4)
    est = estimate_ambient(Scene("room", walls, mats, lights=[lamp]))
    up, down = est.along((0.0, 1.0, 0.0)), est.along((0.0, -1.0, 0.0))
    assert up > 1.5 * down > 0.0
    assert down < est.ambient < up


def test_a_glowing_pane_lets_the_sky_and_the_sun_in():
    """The sky's and the sun's bounce come in through a window whose pane glows (it casts no
    shadow in the renderer, so it hides no light here either), as through an open one; the
    pane's own glow adds to the sun's light, and stands for the sky's when that is on."""
    from app.ambient import AmbientProbe
    from app.sky import bake_sky
    from tests.test_photons import HALF

    walls = [m for m in _box_walls() if m.name != "wall11"]  # the ceiling is the window
    pane = _quad(
        "pane",
        np.array(
            [
                [-HALF[0], HALF[1], -HALF[2]],
                [HALF[0], HALF[1], -HALF[2]],
                [HALF[0], HALF[1], HALF[2]],
                [-HALF[0], HALF[1], HALF[2]],
            ]
        ),
        np.array([0.0, -1.0, 0.0]),
        1,
    )
    mats = [Material("grey", (0.5, 0.5, 0.5, 1.0)), Material("sky", emissive=(0.6, 0.8, 1.0))]
    open_box = Scene("open", walls, mats[:1])
    glazed = Scene("glazed", [*walls, pane], mats)
    s = Settings()
    s.sky.enabled = True
    sh = bake_sky(s).sh
    sun = Light((0, 0, 0), (1, 1, 1), 100.0, kind="directional", direction=(0, -1, 0))
    probe = AmbientProbe(glazed)
    glow = probe.estimate([]).ambient  # the pane's own light, without daylight (none with)
    assert glow > 0.0
    for lights, sky in (([], sh), ([sun], None)):
        through = probe.estimate(lights, sky).ambient - (glow if sky is None else 0.0)
        assert through > 0.0
        assert through == pytest.approx(
            AmbientProbe(open_box).estimate(lights, sky).ambient, rel=0.1
        )


def test_a_thin_panel_on_a_wall_takes_its_bounce_light_not_the_wall_it_hides():
    """A white panel 1 mm in front of most of a white wall (a large picture, a wainscot)
    changes nothing a path tracer would show: the room's even light stays within 5 % of the
    bare room's. The wall behind it is covered (something lies on it) and lit by next to
    nothing; a ray that meets the panel must take the panel's light, not the hidden wall's
    (taking it lost 10 % of the bounce per bounce on the corridor)."""
    albedo = 0.7
    lamp = PointLight((0.5, 0.4, -0.3), (1.0, 1.0, 1.0), 8.0, 1e4)
    bare = _box(albedo, [lamp])
    x = HALF[0] - 0.001  # just in front of the +X wall, facing into the room
    corners = np.array(
        [
            [x, -0.9 * HALF[1], -0.9 * HALF[2]],
            [x, -0.9 * HALF[1], 0.9 * HALF[2]],
            [x, 0.9 * HALF[1], 0.9 * HALF[2]],
            [x, 0.9 * HALF[1], -0.9 * HALF[2]],
        ]
    )
    panel = _quad("panel", corners, np.array([-1.0, 0.0, 0.0]), 0)
    panelled = _box(albedo, [lamp], extra=[panel])
    plain, with_panel = estimate_ambient(bare), estimate_ambient(panelled)
    assert with_panel.ambient == pytest.approx(plain.ambient, rel=0.05)


def _glowing_box() -> Scene:
    """The grey box (albedo 0.6) lit by a glowing 1 x 1 m panel on the ceiling, no lamp."""
    y = HALF[1] - 0.01
    corners = np.array([[-0.5, y, -0.5], [0.5, y, -0.5], [0.5, y, 0.5], [-0.5, y, 0.5]])
    panel = _quad("light panel", corners, np.array([0.0, -1.0, 0.0]), 1)
    glow = Material("glow", (0.0, 0.0, 0.0, 1.0), emissive=(30.0, 30.0, 30.0))
    return _box(0.6, [], extra=[panel], materials=[glow])


def test_a_glowing_panel_lights_the_room_as_the_photon_tracer_finds():
    """A room lit only by a glowing ceiling panel (a lamp modelled as a lit surface, as many
    exported rooms have): the renderer draws the panel but lights nothing with it, so the even
    light carries all of its light, its first arrival and its bounces. The light the probe's
    rays find coming from it is what it sends (pi L A, from its lit side only) within 8 %, and
    the even light the photon tracer's (which emits from glowing surfaces, all of it stored,
    none drawn) within 10 %, averaged over four seeds (one moves by about 7 % between seeds
    for a light this small). With daylight on it counts for nothing: a glowing pane stands for
    the sky beyond it, whose light is counted instead."""
    scene = _glowing_box()
    pm = trace_photons(scene, 2**16, seed=5, max_bounces=40)
    luma = np.array([0.2126, 0.7152, 0.0722])
    photon_irradiance = float(pm.power.sum(axis=0, dtype=np.float64) @ luma) / _box_area()
    area = _box_area() + 2.0  # the probe's points are spread over the panel's two sides too
    levels, sent = [], []
    for seed in range(4):
        probe = AmbientProbe(scene, seed=seed)
        levels.append(probe.estimate([]).ambient * math.pi)
        sent.append(area / len(probe.points) * float((probe.emitted_rgb @ luma).sum()))
    glow = scene.materials[1].emissive[1]
    assert np.mean(sent) == pytest.approx(math.pi * glow * 1.0, rel=0.08)
    assert np.mean(levels) == pytest.approx(photon_irradiance, rel=0.10)
    from app.sky import bake_sky

    s = Settings()
    s.sky.enabled = True
    assert AmbientProbe(scene).estimate([], bake_sky(s).sh).ambient == 0.0  # a closed box


def test_a_room_is_probed_at_more_points_than_a_small_object():
    """The probe's points follow the scene's surface (app.ambient.SAMPLES_PER_M2): a 4 x 3 x 5
    m room (94 m2) gets 3760 of them, a 1 m box half the room's most, and a large hall the
    most; the same seed picks the same points."""
    room = _box(0.5, [])
    small = Scene(
        "small",
        [
            _quad(
                "top",
                np.array([[0, 1, 0], [1, 1, 0], [1, 1, 1], [0, 1, 1]], float),
                np.array([0.0, 1.0, 0.0]),
                0,
            ),
        ],
        [Material("white", (0.8, 0.8, 0.8, 1.0))],
    )
    hall = _box(0.5, [])
    for m in hall.meshes:
        m.positions = m.positions * 3.0  # 9x the surface: 846 m2
    counts = {
        name: len(AmbientProbe(s).points)
        for name, s in (("room", room), ("small", small), ("hall", hall))
    }
    assert counts == {"room": 3760, "small": 2048, "hall": 4096}
    again = AmbientProbe(_box(0.5, []))
    np.testing.assert_array_equal(again.points, AmbientProbe(room).points)
