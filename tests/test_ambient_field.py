"""The even light by place (app/ambient_field.py, ``render.ambient_by_place``): the probe's
faces kept on a grid, read back where they were found, the one level where none were, covered
faces left out, and the frame shades with it as the CPU twin says."""

from __future__ import annotations

import numpy as np
import pytest

from app.ambient import AmbientProbe, estimate_ambient
from app.ambient_field import AXES, FieldLayout, build_field
from app.camera import StereoCamera
from app.frame import FrameInput
from app.scene import Material, PointLight, Scene, Viewpoint
from app.settings import Settings
from render.offscreen import OffscreenHost
from tests.test_ambient import _env_brdf
from tests.test_photons import HALF, _box, _box_walls, _quad

LEVELS = np.full(6, 0.2)


def _floor_faces(n: int = 40) -> tuple[np.ndarray, np.ndarray]:
    """A 4 m x 4 m floor of faces looking up, on a grid."""
    g = np.linspace(-2.0, 2.0, n)
    x, z = np.meshgrid(g, g)
    pts = np.stack([x.ravel(), np.zeros(x.size), z.ravel()], axis=1)
    return pts, np.tile([0.0, 1.0, 0.0], (len(pts), 1))


def test_the_field_gives_back_what_was_found_where_it_was_found():
    """A floor whose bounce light rises from 0.1 to 0.5 across it: read back in its middle,
    the field rises with it (a linear ramp survives the tent), and the two halves differ."""
    pts, up = _floor_faces()
    values = 0.3 + 0.1 * pts[:, 0]  # 0.1 at x = -2, 0.5 at x = +2
    field = build_field(pts, up, values, LEVELS, cell=0.25)
    assert field is not None
    probe = np.array([[-1.0, 0.02, 0.0], [0.0, 0.02, 0.0], [1.0, 0.02, 0.0]])
    got = field.lookup(probe, np.tile([0.0, 1.0, 0.0], (3, 1)))
    assert got == pytest.approx([0.2, 0.3, 0.4], abs=0.01)


def test_where_no_face_looks_that_way_the_one_level_stands_in():
    """Looking down over an up-facing floor, or far from every face: the level of that
    direction, not black."""
    pts, up = _floor_faces()
    levels = np.array([0.11, 0.12, 0.13, 0.14, 0.15, 0.16])
    field = build_field(pts, up, np.full(len(pts), 0.5), levels, cell=0.25)
    assert field is not None
    down = field.lookup(np.array([[0.0, 0.02, 0.0]]), np.array([[0.0, -1.0, 0.0]]))
    assert down[0] == pytest.approx(0.14)
    far = field.lookup(np.array([[0.0, 0.02, 0.0]]), np.array([[1.0, 0.0, 0.0]]))
    assert far[0] == pytest.approx(0.11)
    tilted = np.array([[0.0, 0.6, 0.8]])  # 36 % up (0.5), 64 % +Z (0.15)
    got = field.lookup(np.array([[0.0, 0.02, 0.0]]), tilted)
    assert got[0] == pytest.approx(0.36 * 0.5 + 0.64 * 0.15, abs=1e-6)


def test_bad_faces_are_left_out_and_none_gives_no_field():
    pts, up = _floor_faces(4)
    values = np.full(len(pts), 0.4)
    values[0] = np.nan
    values[1] = -1.0
    pts[2] = np.inf
    field = build_field(pts, up, values, LEVELS)
    assert field is not None and field.faces == len(pts) - 3
    assert np.isfinite(field.values).all()
    assert build_field(pts[:0], up[:0], values[:0], LEVELS) is None
    with pytest.raises(ValueError):
        build_field(pts, up, values, LEVELS, cell=0.0)


def test_a_kept_layout_gives_the_field_a_fresh_build_gives_and_bad_light_lays_out_afresh():
    """The probe keeps where its faces fall on the grid (they do not move with the lights): the
    field from that layout equals one built from scratch; a face whose light turned NaN on
    this estimate is left out as a fresh build leaves it out, not spread from the layout."""
    pts, up = _floor_faces(12)
    values = 0.3 + 0.1 * pts[:, 0]
    layout = FieldLayout.of(pts, up, 0.25)
    fresh = build_field(pts, up, values, LEVELS, cell=0.25)
    kept = build_field(pts, up, values, LEVELS, cell=0.25, layout=layout)
    assert fresh is not None and kept is not None
    np.testing.assert_allclose(kept.values, fresh.values, rtol=1e-6, atol=1e-7)
    np.testing.assert_allclose(kept.chroma, fresh.chroma, rtol=1e-6, atol=1e-7)
    bad = values.copy()
    bad[5] = np.nan
    from_layout = build_field(pts, up, bad, LEVELS, cell=0.25, layout=layout)
    assert from_layout is not None and from_layout.faces == len(pts) - 1
    assert np.isfinite(from_layout.values).all()
    left_out = build_field(
        np.delete(pts, 5, 0), np.delete(up, 5, 0), np.delete(values, 5), LEVELS, cell=0.25
    )
    assert left_out is not None
    np.testing.assert_allclose(from_layout.values, left_out.values, rtol=1e-6, atol=1e-7)


def test_a_rug_covers_the_floor_under_it():
    """The floor's faces under a slab lying on it see the slab 1 cm away in every direction:
    covered, so they do not pull the floor's field down; the open floor is not."""
    rug = _quad(
        "rug",
        np.array(
            [
                [-1, -HALF[1] + 0.01, -1],
                [1, -HALF[1] + 0.01, -1],
                [1, -HALF[1] + 0.01, 1],
                [-1, -HALF[1] + 0.01, 1],
            ],
            float,
        ),
        np.array([0.0, 1.0, 0.0]),
        0,
    )
    scene = _box(0.5, [PointLight((0.5, 0.4, -0.3), (1.0, 1.0, 1.0), 8.0, 1e4)], [rug])
    probe = AmbientProbe(scene)
    p = probe.points
    on_floor = np.abs(p[:, 1] + HALF[1]) < 1e-4
    under = on_floor & (np.abs(p[:, 0]) < 0.8) & (np.abs(p[:, 2]) < 0.8)
    open_floor = on_floor & ((np.abs(p[:, 0]) > 1.3) | (np.abs(p[:, 2]) > 1.3))
    assert under.sum() > 10 and open_floor.sum() > 10
    inner = 2 * np.flatnonzero(under) + (probe.normal[under, 1] < 0)  # the face looking up
    assert probe.covered[inner].mean() > 0.9
    inner_open = 2 * np.flatnonzero(open_floor) + (probe.normal[open_floor, 1] < 0)
    assert probe.covered[inner_open].mean() < 0.05


def test_a_lamp_by_one_wall_lights_that_end_of_the_room_more():
    """A lamp near one end of a long box: the estimate's field is brighter on the floor at
    that end than at the other, where the one level is the same at both."""
    lamp = PointLight((0.0, 0.0, -HALF[2] + 0.4), (1.0, 1.0, 1.0), 8.0, 1e4)
    est = estimate_ambient(_box(0.5, [lamp]))
    assert est.by_place is not None
    y = -HALF[1] + 0.01
    near, far = est.by_place.lookup(
        np.array([[0.0, y, -HALF[2] + 0.8], [0.0, y, HALF[2] - 0.8]]),
        np.array([[0.0, 1.0, 0.0], [0.0, 1.0, 0.0]]),
    )
    assert near > 1.3 * far > 0.0
    assert far < est.along((0.0, 1.0, 0.0)) < near


def _centre(s: Settings, scene) -> tuple[float, np.ndarray]:
    """The left eye's luminance over its four centre pixels and the wall points they show."""
    with OffscreenHost(160, 90, s) as host:
        host.set_scene(scene)
        cam = StereoCamera(s.stereo)
        cam.set_pose(scene.spawn.position, 0.0, 0.0)
        eyes = cam.eyes(*host.eye_size)
        host.draw(FrameInput(eyes, gaze=(0.5, 0.5)))
        hdr = host.read_hdr(0)[:, :, :3]
    h, w = hdr.shape[:2]
    lum = hdr[h // 2 - 1 : h // 2 + 1, w // 2 - 1 : w // 2 + 1] @ [0.2126, 0.7152, 0.0722]
    eye = eyes[0]
    points = []
    for row in (h // 2 - 1, h // 2):  # row 0 at the top
        for col in (w // 2 - 1, w // 2):
            ndc = np.array([(col + 0.5) / w * 2 - 1, 1 - (row + 0.5) / h * 2])
            a, b = (eye.inverse_view_projection @ np.array([*ndc, z, 1.0]) for z in (-1.0, 1.0))
            a, b = a[:3] / a[3], b[:3] / b[3]
            points.append(a + (b - a) * ((-HALF[2] - a[2]) / (b[2] - a[2])))  # on the wall
    return float(lum.mean()), np.array(points)


def test_the_frame_shades_with_the_field_as_its_cpu_twin_says():
    """The wall straight ahead: with the field, brighter than with the one level by what
    reflects x (field there - level) says (at the four pixels averaged)."""
    scene = _box(0.5, [PointLight((0.5, 0.4, -0.3), (1.0, 1.0, 1.0), 8.0, 1e4)])
    scene.spawn = Viewpoint((0.0, 0.0, 1.5))
    s = Settings()
    s.set("render.ambient_by_place", False)
    level_lum, _ = _centre(s, scene)
    s.set("render.ambient_by_place", True)
    field_lum, at = _centre(s, scene)
    est = estimate_ambient(scene)
    toward = np.tile([0.0, 0.0, 1.0], (len(at), 1))
    here = float(est.by_place.lookup(at, toward).mean())
    x, y = _env_brdf(scene.materials[0].roughness, 1.0)
    reflects = 0.5 + 0.04 * x + y
    want = reflects * (here - est.along((0.0, 0.0, 1.0)))
    assert abs(want) > 0.005  # the wall ahead is not at the mean
    # half floats: the HDR target's step is 5e-4 at these levels, the field's a tenth of it
    assert field_lum - level_lum == pytest.approx(want, abs=1.2e-3)


def test_the_axes_are_the_six_grids():
    assert AXES.shape == (6, 3)
    assert (np.abs(AXES).sum(axis=1) == 1).all()
    assert Material  # the test module's imports used


def test_a_red_floor_warms_the_ceiling_above_it():
    """A white box with a red floor under a lamp: the bounce light the field gives the ceiling
    is red (more red than blue), its luminance kept; with a grey floor it is grey."""

    def ceiling_colour(floor_rgb) -> np.ndarray:
        est = estimate_ambient(_floored(floor_rgb))
        assert est.by_place is not None
        return est.by_place.colour_at(np.array([[0.0, HALF[1] - 0.01, 0.0]]))[0]

    red = ceiling_colour((0.8, 0.1, 0.1))
    grey = ceiling_colour((0.5, 0.5, 0.5))
    assert red[0] > 1.5 * red[2]
    assert float(red @ [0.2126, 0.7152, 0.0722]) == pytest.approx(1.0, abs=0.02)
    assert grey == pytest.approx([1.0, 1.0, 1.0], abs=0.03)


def test_a_warm_lamp_warms_the_bounce_in_a_white_room():
    """The bounce takes the lamp's colour as well as the surfaces': a warm lamp (2700 K-ish)
    in a grey box gives the ceiling a warm bounce, a white lamp a grey one, a blue lamp a
    blue one; the luminance stays 1 (the level is the luminance estimate's)."""

    def ceiling_colour(lamp_rgb) -> np.ndarray:
        scene = _floored((0.5, 0.5, 0.5), lamp_rgb)
        est = estimate_ambient(scene)
        assert est.by_place is not None
        return est.by_place.colour_at(np.array([[0.0, HALF[1] - 0.01, 0.0]]))[0]

    warm = ceiling_colour((1.0, 0.87, 0.72))
    white = ceiling_colour((1.0, 1.0, 1.0))
    blue = ceiling_colour((0.6, 0.8, 1.0))
    assert warm[0] > 1.25 * warm[2], warm
    assert blue[2] > 1.4 * blue[0], blue
    assert white == pytest.approx([1.0, 1.0, 1.0], abs=0.03)
    assert float(warm @ [0.2126, 0.7152, 0.0722]) == pytest.approx(1.0, abs=0.02)


def _floored(floor_rgb, lamp_rgb=(1.0, 1.0, 1.0)) -> Scene:
    """A white box under a lamp near its ceiling, its floor of colour ``floor_rgb``."""
    walls = _box_walls()
    mats = [Material("white", (0.8, 0.8, 0.8, 1.0)), Material("floor", (*floor_rgb, 1.0))]
    for m in walls:
        m.material = 1 if m.name == "wall1-1" else 0  # the floor
    lamp = PointLight((0.0, HALF[1] - 0.4, 0.0), tuple(lamp_rgb), 8.0, 1e4)
    scene = Scene("room", walls, mats, lights=[lamp])
    scene.spawn = Viewpoint((0.0, 0.0, 0.0))
    return scene


def test_the_frame_shows_the_ceiling_warmed_by_the_red_floor():
    """Looking up at that ceiling: red over blue higher with the field (the bounce light's
    colour) than with the one level (grey)."""
    scene = _floored((0.8, 0.1, 0.1))

    def red_over_blue(by_place: bool) -> float:
        s = Settings()
        s.set("render.ambient_by_place", by_place)
        with OffscreenHost(160, 90, s) as host:
            host.set_scene(scene)
            cam = StereoCamera(s.stereo)
            cam.set_pose(scene.spawn.position, 0.0, 80.0)
            host.draw(FrameInput(cam.eyes(*host.eye_size), gaze=(0.5, 0.5)))
            hdr = host.read_hdr(0)[:, :, :3].astype(np.float64)
        h, w = hdr.shape[:2]
        centre = hdr[h // 2 - 4 : h // 2 + 4, w // 2 - 4 : w // 2 + 4].reshape(-1, 3).mean(axis=0)
        return float(centre[0] / centre[2])

    assert red_over_blue(True) > red_over_blue(False) * 1.05


def _far_wall(range_m: float) -> tuple[float, float]:
    """A lamp near one end of the box of range ``range_m``: the frame's luminance at the far
    wall's centre, and the field's value there."""
    lamp = PointLight((0.0, 0.0, -HALF[2] + 0.4), (1.0, 1.0, 1.0), 8.0, range_m)
    scene = _box(0.5, [lamp])
    scene.spawn = Viewpoint((0.0, 0.0, 0.0))
    s = Settings()
    with OffscreenHost(160, 90, s) as host:
        host.set_scene(scene)
        cam = StereoCamera(s.stereo)
        cam.set_pose(scene.spawn.position, 180.0, 0.0)  # looking down +Z
        host.draw(FrameInput(cam.eyes(*host.eye_size), gaze=(0.5, 0.5)))
        hdr = host.read_hdr(0)[:, :, :3]
    h, w = hdr.shape[:2]
    lum = hdr[h // 2 - 2 : h // 2 + 2, w // 2 - 2 : w // 2 + 2] @ [0.2126, 0.7152, 0.0722]
    est = estimate_ambient(scene)
    assert est.by_place is not None
    wall = est.by_place.lookup(np.array([[0.0, 0.0, HALF[2] - 0.01]]), np.array([[0, 0, -1.0]]))
    return float(lum.mean()), float(wall[0])


def test_a_lamps_light_past_its_range_comes_with_the_even_light():
    """The renderer stops drawing a lamp at its range (the range window keeps light culling
    exact); a path tracer does not. The even light carries what lies beyond: with a 2 m range
    the far wall, 4.6 m from the lamp, gets the lamp's direct light / pi in the field and
    looks nearly as it does with an unlimited range (without: two thirds as bright)."""
    lum_whole, field_whole = _far_wall(1e4)
    lum_short, field_short = _far_wall(2.0)
    direct = 8.0 / (2.0 * HALF[2] - 0.4) ** 2  # lux, facing the lamp, nothing in between
    assert field_short - field_whole == pytest.approx(direct / np.pi, rel=0.15)
    assert 0.85 * lum_whole < lum_short <= lum_whole * 1.02


def test_the_window_glass_does_not_light_the_wall_beside_it():
    """The showroom's window pane glows (it shows the sky) and lets light through, so rays
    pass it (as its lamp shades and downlights); its points hold the light arriving at the
    window from the sunlit blinds a few centimetres away, not a surface's. Spread into the
    field they lit the wall round the window as a white halo (2.3 times the light there in
    daylight). They are left out; the wall away from the window keeps its light."""
    from app import scenes
    from app.sky import scene_sky

    s = Settings()
    s.sky.enabled = True
    room = scenes.resolve("showroom")
    with OffscreenHost(64, 32, s) as host:
        host.set_scene(room)
        with host.ctx:
            sh = host.renderer.daylight.update_sky(scene_sky(s.sky, room)).sh
        lights = host.renderer.frame_lights()
    wall = np.array([[-3.99, 1.6, -0.8], [-3.99, 1.6, 2.0], [-3.99, 2.5, 0.6]])  # round the pane
    far = np.array([[-3.99, 1.6, -2.2]])
    facing = np.array([[1.0, 0.0, 0.0]])  # into the room
    light = {}
    for kept in (False, True):
        probe = AmbientProbe(room)
        pane = probe.clear
        p = probe.points
        in_window = (np.abs(p[:, 0] + 3.995) < 1e-3) & (np.abs(p[:, 1] - 1.6) < 0.65)
        in_window &= np.abs(p[:, 2] - 0.6) < 1.05  # the pane: 2.2 x 1.4 m, 5 mm in the wall
        assert in_window.sum() > 10 and pane[in_window].all()
        assert not pane[np.abs(p[:, 0] + 4.0) < 1e-3].all()  # the wall round it is not clear
        if kept:
            probe.clear = np.zeros_like(pane)
        est = probe.estimate(lights, sh)
        assert est.by_place is not None
        light[kept] = (
            est.by_place.lookup(wall, np.repeat(facing, len(wall), axis=0)),
            est.by_place.lookup(far, facing),
        )
    assert (light[False][0] < 0.6 * light[True][0]).all(), light
    assert np.allclose(light[False][1], light[True][1], rtol=0.02), light
