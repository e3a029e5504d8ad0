"""Daylight: the sun placed by date, time and site, the sky seen through an opening, the sky's
light through the window, a broken sky photo, and night."""

from __future__ import annotations

import datetime
import math

import numpy as np
import pytest
from astral import Observer
from astral.sun import azimuth, elevation

from app.camera import StereoCamera
from app.frame import FrameInput
from app.scene import Material, Mesh, PointLight, Scene, Viewpoint
from app.settings import Settings
from app.sky import bake_sky, sun_direction, sun_light, sun_position
from app.sky_light import sky_visibility
from app.sky_model import LUMA
from render.offscreen import OffscreenHost

W, H = 320, 180  # two 160 x 180 eyes


def grid(name, origin, du, dv, n, normal) -> Mesh:
    """A rectangle from ``origin`` spanning ``du`` and ``dv`` in n x n cells, facing ``normal``
    (wound counter-clockwise seen from that side)."""
    o, u, v = (np.asarray(x, np.float32) for x in (origin, du, dv))
    s = np.linspace(0.0, 1.0, n + 1, dtype=np.float32)
    uu, vv = np.meshgrid(s, s, indexing="ij")
    pos = (o + uu[..., None] * u + vv[..., None] * v).reshape(-1, 3)
    idx = []
    for i in range(n):
        for j in range(n):
            a, b = i * (n + 1) + j, (i + 1) * (n + 1) + j
            c, d = b + 1, a + 1
            tri = [(a, b, c), (a, c, d)]
            if float(np.dot(np.cross(u, v), normal)) < 0:
                tri = [(p, r, q) for p, q, r in tri]
            idx += tri
    uv = np.stack([uu.ravel(), vv.ravel()], 1).astype(np.float32)
    normals = np.tile(np.asarray(normal, np.float32), (len(pos), 1))
    return Mesh(name, pos, normals, uv, np.asarray(idx, np.uint32))


def room(window: bool = True) -> Scene:
    """A white 4 x 3 x 4 m room around the origin (floor at y = 0) with a 2 x 1.5 m window in
    its south wall (+Z: north is the model's -Z by default), and a dim lamp in the middle."""
    meshes = [
        grid("floor", (-2, 0, -2), (4, 0, 0), (0, 0, 4), 16, (0, 1, 0)),
        grid("ceiling", (-2, 3, -2), (4, 0, 0), (0, 0, 4), 4, (0, -1, 0)),
        grid("north wall", (-2, 0, -2), (4, 0, 0), (0, 3, 0), 4, (0, 0, 1)),
        grid("west wall", (-2, 0, -2), (0, 0, 4), (0, 3, 0), 4, (1, 0, 0)),
        grid("east wall", (2, 0, -2), (0, 0, 4), (0, 3, 0), 4, (-1, 0, 0)),
    ]
    south = (0, 0, -1)
    if window:
        meshes += [
            grid("under the window", (-2, 0, 2), (4, 0, 0), (0, 1, 0), 4, south),
            grid("over the window", (-2, 2.5, 2), (4, 0, 0), (0, 0.5, 0), 4, south),
            grid("left of the window", (-2, 1, 2), (1, 0, 0), (0, 1.5, 0), 2, south),
            grid("right of the window", (1, 1, 2), (1, 0, 0), (0, 1.5, 0), 2, south),
        ]
    else:
        meshes.append(grid("south wall", (-2, 0, 2), (4, 0, 0), (0, 3, 0), 4, south))
    return Scene(
        "room",
        meshes,
        [Material("white", (0.7, 0.7, 0.7, 1.0), roughness=1.0)],
        [],
        [PointLight((0, 2.5, 0), (1, 1, 1), 2.0, 6.0)],
        Viewpoint((0, 1.6, 0)),
    ).sanitized()


@pytest.fixture(scope="module")
def host():
    s = Settings()
    s.set("stereo.ipd_mm", 0.0)
    s.set("sky.enabled", True)
    h = OffscreenHost(W, H, s)
    yield h
    assert not h.renderer.errors
    h.close()


def look(host: OffscreenHost, scene: Scene, pos, yaw, pitch, **settings) -> np.ndarray:
    """The left eye's linear HDR picture (cd/m2), (H, W, 3), row 0 at the top."""
    s = host.settings
    for key, value in {"sky.time": "10:00", "sky.image": "", **settings}.items():
        s.set(key.replace("__", "."), value)
    if host.renderer.gpu_scene is None or host.renderer.gpu_scene.scene is not scene:
        host.set_scene(scene)
        with host.ctx:
            assert host.renderer.daylight.wait_for_visibility(host.renderer.gpu_scene)
    cam = StereoCamera(s.stereo)
    cam.set_pose(pos, yaw, pitch)
    frame = FrameInput(cam.eyes(*host.eye_size), gaze=(-1, -1))
    host.draw(frame)
    return host.read_hdr(0)[..., :3]


def pixel(host: OffscreenHost, pos, yaw, pitch, point) -> tuple[int, int]:
    """Row and column of a world point in the left eye."""
    cam = StereoCamera(host.settings.stereo)
    cam.set_pose(pos, yaw, pitch)
    eye = cam.eyes(*host.eye_size)[0]
    clip = eye.view_projection @ np.array([*point, 1.0])
    x, y = clip[:2] / clip[3]
    return int((1.0 - (y * 0.5 + 0.5)) * eye.height), int((x * 0.5 + 0.5) * eye.width)


# -- the sun's place -----------------------------------------------------------------------------
def test_the_sun_stands_where_astral_and_the_almanac_put_it():
    """Paris at the June solstice, local solar noon: the sun is due south at 90 - 48.85 + 23.44
    = 64.59 degrees (the almanac's noon altitude for a declination of 23.44 degrees)."""
    s = Settings()
    s.set("sky.date", "2026-06-21")
    s.set("sky.time", "12:00")
    s.set("sky.latitude", 48.85)
    s.set("sky.longitude", 2.35)
    pos = sun_position(s.sky)
    assert pos.elevation_deg == pytest.approx(64.59, abs=0.1)
    assert pos.azimuth_deg == pytest.approx(180.0, abs=1.5)  # the equation of time: 1.7 min
    # astral asked directly, for the UTC moment: 12:00 solar time is 12:00 - 2.35 / 15 h.
    when = datetime.datetime(2026, 6, 21, 11, 50, 36, tzinfo=datetime.timezone.utc)
    where = Observer(latitude=48.85, longitude=2.35)
    assert pos.elevation_deg == pytest.approx(elevation(where, when), abs=0.1)
    assert pos.azimuth_deg == pytest.approx(azimuth(where, when), abs=0.1)
    # A winter afternoon in Sydney: the sun in the north-west, lower.
    s.set("sky.latitude", -33.87)
    s.set("sky.longitude", 151.21)
    s.set("sky.time", "15:00")
    winter = sun_position(s.sky)
    assert 270.0 < winter.azimuth_deg < 340.0 and 10.0 < winter.elevation_deg < 30.0


def test_the_sun_is_a_directional_light_in_lux_that_follows_the_time():
    s = Settings()
    s.set("sky.time", "12:00")
    noon = sun_light(s)
    assert noon is not None and noon.kind == "directional"
    assert np.allclose(noon.direction, -sun_direction(s.sky))
    assert 70_000 < noon.intensity < 110_000  # a clear summer noon: about 100 klx
    assert np.dot(LUMA, noon.color) == pytest.approx(1.0)
    s.set("sky.time", "09:00")
    morning = sun_light(s)
    s.set("sky.time", "15:00")
    afternoon = sun_light(s)
    assert morning is not None and afternoon is not None
    # North is -Z, east +X: the morning sun (in the east) shines towards -X, later towards +X.
    assert morning.direction[0] < -0.3 and afternoon.direction[0] > 0.3
    assert morning.intensity < noon.intensity and morning.color[2] < noon.color[2]  # warmer
    s.set("sky.time", "05:00")
    low = sun_light(s)
    assert low is not None and low.intensity < morning.intensity / 2
    s.set("sky.north_deg", 90.0)  # north turned to -X: the 09:00 sun now shines towards +Z
    s.set("sky.time", "09:00")
    turned = sun_light(s)
    assert turned is not None and turned.direction[2] > 0.3


def test_at_night_there_is_no_sun_and_the_sky_is_dark(host):
    s = Settings()
    s.set("sky.time", "23:30")
    assert sun_light(s) is None
    scene = room()
    hdr = look(host, scene, (0, 1.6, -1.0), 180.0, 15.0, sky__time="23:30")
    assert [light.kind for light in host.renderer.frame_lights()] == ["point"]
    r, c = pixel(host, (0, 1.6, -1.0), 180.0, 15.0, (0.0, 2.2, 2.0))
    assert float(hdr[r, c] @ LUMA) < 0.5  # a night sky: far below a lamp-lit wall's


# -- the sun and the sky in the picture ----------------------------------------------------------
def test_the_sun_patch_moves_across_the_floor_as_the_day_goes_by(host):
    """The sun comes in through the south window only (shadow maps): seen from under the
    ceiling, its patch on the floor lies to the west in the morning and to the east in the
    afternoon, and the floor outside it is in the shade."""
    scene = room()
    pose = ((0.0, 2.9, 0.0), 180.0, -85.0)  # under the ceiling, looking down
    lights = None
    centres = {}
    for time in ("09:00", "15:00"):
        img = look(host, scene, *pose, sky__time=time)
        lights = host.renderer.frame_lights()
        lum = img @ LUMA
        patch = lum > 0.5 * float(lum.max())
        assert 0.005 < patch.mean() < 0.4, time  # a patch, not the whole floor
        assert float(np.median(lum[~patch])) < 0.25 * float(np.median(lum[patch])), time
        centres[time] = float(np.nonzero(patch)[1].mean())
    assert lights is not None and [light.kind for light in lights] == ["point", "directional"]
    west = pixel(host, *pose, (-1.5, 0.0, 0.5))[1]
    east = pixel(host, *pose, (1.5, 0.0, 0.5))[1]
    shift = centres["09:00"] - centres["15:00"]
    assert shift * (west - east) > 0  # the morning patch lies west of the afternoon one
    assert abs(shift) > 0.1 * abs(west - east)


def test_the_sky_is_seen_through_the_window(host):
    scene = room()
    pose = ((0.0, 1.6, 0.0), 180.0, 10.0)
    for path, mitigation in (("deferred", "none"), ("forward", "none"), ("deferred", "cps")):
        hdr = look(host, scene, *pose, render__path=path, cps__mode=mitigation)
        r, c = pixel(host, *pose, (0.0, 2.3, 2.0))  # in the window, above the horizon
        sky = hdr[r, c]
        assert sky[2] > 1.1 * sky[0], path  # blue
        assert float(sky @ LUMA) > 1000.0, path  # a day sky: thousands of cd/m2
        wall = hdr[pixel(host, *pose, (-1.5, 2.7, 2.0))]
        assert not np.allclose(wall, sky, rtol=0.2), path
    host.settings.set("render.path", "deferred")
    host.settings.set("cps.mode", "none")


def test_the_sky_lights_the_floor_near_the_window_more_than_the_far_corner(host):
    open_room, closed = room(), room(window=False)
    vis = sky_visibility(open_room, rays=64, seed=1)
    assert vis is not None
    floor = open_room.meshes[0]
    near = np.argmin(np.linalg.norm(floor.positions - [0.0, 0.0, 1.0], axis=1))
    far = np.argmin(np.linalg.norm(floor.positions - [-1.75, 0.0, -1.75], axis=1))
    assert vis[0][near, 0] > 0.05 and vis[0][near, 0] > 3.0 * vis[0][far, 0]  # the side up
    assert vis[0][near, 1] == 1.0  # under the floating room's floor: the whole sky
    closed_vis = sky_visibility(closed, rays=32, seed=1)
    assert closed_vis is not None  # inside a closed room no sky is seen
    assert max(float(v[:, 0].max()) for v in closed_vis) == 0.0
    pose = ((0.0, 2.8, 0.0), 0.0, -89.0)  # looking down
    at_near = pixel(host, *pose, (0.0, 0.0, 1.0))
    at_far = pixel(host, *pose, (0.0, 0.0, -1.5))
    lit = look(host, open_room, *pose, sky__time="12:00")
    dark = look(host, closed, *pose, sky__time="12:00")
    near_gain = float((lit[at_near] - dark[at_near]) @ LUMA)
    far_gain = float((lit[at_far] - dark[at_far]) @ LUMA)
    assert near_gain > 20.0 and near_gain > 2.0 * far_gain


def test_a_broken_sky_photo_warns_and_the_computed_sky_shows(tmp_path, caplog):
    s = Settings()
    computed = bake_sky(s)
    bad = tmp_path / "sky.hdr"
    bad.write_bytes(b"this is not an image")
    s.set("sky.image", str(bad))
    with caplog.at_level("WARNING"):
        baked = bake_sky(s)
    assert not baked.from_image and baked.warning and "sky.hdr" in baked.warning
    assert "computed sky" in caplog.text
    assert np.array_equal(baked.image, computed.image)
    s.set("sky.image", str(tmp_path / "missing.jpg"))
    assert bake_sky(s).warning is not None


def test_a_sky_photo_is_used_with_the_computed_skys_brightness(tmp_path):
    from PIL import Image

    photo = np.zeros((64, 128, 3), np.uint8)
    photo[:32] = (60, 120, 230)  # blue above the horizon
    photo[32:] = (40, 140, 40)  # green below
    path = tmp_path / "pano.png"
    Image.fromarray(photo).save(path)
    s = Settings()
    computed = bake_sky(s)
    s.set("sky.image", str(path))
    baked = bake_sky(s)
    assert baked.from_image and baked.warning is None
    top, bottom = baked.image[4, 10], baked.image[60, 10]
    assert top[2] > top[0] and bottom[1] > bottom[2]
    upper = (slice(0, 32), slice(None))
    want = float((computed.image[upper] @ LUMA).mean())
    assert float((baked.image[upper] @ LUMA).mean()) == pytest.approx(want, rel=0.1)


def test_the_sun_moves_when_the_time_changes_without_reloading_the_scene(host):
    scene = room()
    pose = ((0.0, 1.6, 0.0), 180.0, 0.0)
    look(host, scene, *pose, sky__time="09:00")
    uploaded = host.renderer.gpu_scene
    first = host.renderer.frame_lights()[-1].direction
    look(host, scene, *pose, sky__time="16:00")
    assert host.renderer.gpu_scene is uploaded
    later = host.renderer.frame_lights()[-1].direction
    assert math.dist(first, later) > 0.5


def _write_rgbe(path, rgb: np.ndarray) -> None:
    """A Radiance .hdr file of ``rgb`` (H, W, 3), run-length encoded per channel."""
    h, w, _ = rgb.shape
    peak = rgb.max(axis=2)
    m, e = np.frexp(np.maximum(peak, 1e-30))
    scale = np.where(peak > 1e-30, m * 256.0 / np.maximum(peak, 1e-30), 0.0)
    rgbe = np.zeros((h, w, 4), np.uint8)
    rgbe[..., :3] = np.clip(rgb * scale[..., None], 0, 255).astype(np.uint8)
    rgbe[..., 3] = np.where(peak > 1e-30, e + 128, 0)
    out = bytearray(b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n" + f"-Y {h} +X {w}\n".encode())
    for y in range(h):
        out += bytes([2, 2, w >> 8, w & 255])
        for c in range(4):
            row = rgbe[y, :, c]
            if (row == row[0]).all():  # runs
                for x in range(0, w, 127):
                    out += bytes([128 + min(127, w - x), int(row[0])])
            else:  # literal dumps
                for x in range(0, w, 128):
                    chunk = row[x : x + 128]
                    out += bytes([len(chunk)]) + chunk.tobytes()
    path.write_bytes(bytes(out))


@pytest.mark.parametrize("suffix", [".hdr", ".exr"])
def test_an_hdr_sky_photo_keeps_its_light(tmp_path, suffix):
    """A high-dynamic-range panorama: bright sky over a dim ground, read as stored (linear)."""
    rgb = np.empty((32, 64, 3), np.float32)
    rgb[:16] = np.linspace(0.5, 2.0, 64, dtype=np.float32)[None, :, None] * [0.3, 0.5, 1.0]
    rgb[16:] = (0.02, 0.03, 0.01)
    path = tmp_path / f"pano{suffix}"
    if suffix == ".hdr":
        _write_rgbe(path, rgb)
    else:
        import OpenEXR

        OpenEXR.File({"type": OpenEXR.scanlineimage}, {"RGB": rgb}).write(str(path))
    s = Settings()
    s.set("sky.image", str(path))
    baked = bake_sky(s, size=(64, 32))
    assert baked.from_image and baked.warning is None
    ratio = baked.image[4, 40] / baked.image[28, 40]
    assert ratio == pytest.approx(rgb[4, 40] / rgb[28, 40], rel=0.05)  # as stored, linear


def test_the_time_slider_moves_the_sun_and_says_where_it_is(qtbot):
    from ui.sky_panel import SkyPanel

    s = Settings()
    changed: list[str] = []
    panel = SkyPanel(s, on_change=changed.append)
    qtbot.addWidget(panel)
    slider = panel.editors["sky.time"]
    assert slider is panel.time_slider and panel.time_text.text() == "10:00"
    assert set(panel.editors) == set(s.shown_keys("sky"))
    assert panel.sun.text() == "Sun 55° above the horizon, south-east"  # Paris, 21 June
    slider.setValue(15 * 6 + 3)  # dragged to 15:30
    assert s.sky.time == "15:30" and changed[-1] == "sky.time"
    assert panel.time_text.text() == "15:30"
    assert panel.sun.text().endswith("above the horizon, west")
    slider.setValue(23 * 6 + 5)
    assert s.sky.time == "23:50"
    assert "below the horizon" in panel.sun.text() and "no sunlight" in panel.sun.text()
    s.set("sky.time", "06:00")  # a preset, say
    panel.refresh()
    assert slider.value() == 36 and panel.time_text.text() == "06:00"


def test_daylight_from_the_window_tab_brightens_the_view(qtbot):
    """The "Daylight" check box in the Sun and sky tab: the sky shows around the model (it
    was the dark background), with no scene reload."""
    from PyQt6.QtWidgets import QCheckBox

    from tests.test_gui import grab
    from tests.test_render import checker_scene
    from ui.main_window import MainWindow

    s = Settings()
    s.render.overlay = False
    w = MainWindow(s, checker_scene())
    qtbot.addWidget(w)
    w.view.setFixedSize(240, 135)
    w.show()
    qtbot.waitExposed(w)
    qtbot.waitUntil(lambda: w.view.renderer is not None, timeout=10000)
    before = grab(w)
    renderer = w.view.renderer
    uploaded = renderer.gpu_scene
    box = w.sky_panel.editors["sky.enabled"]
    assert isinstance(box, QCheckBox) and box.text() == "Daylight"
    box.setChecked(True)
    assert s.sky.enabled
    w.view.repaint()
    after = grab(w)
    corner = (slice(0, 8), slice(0, 8))  # above the picture quad: the background
    assert before[corner].mean() < 30 and after[corner].mean() > 200
    assert renderer.gpu_scene is uploaded
    assert [light.kind for light in renderer.frame_lights()][-1] == "directional"
    w.close()


def test_ticking_daylight_at_the_opening_exposure_turns_the_exposure_automatic(qtbot):
    """A new user ticks "Daylight": a sunlit room is some eight stops brighter than the fixed
    exposure a lamp-lit room opens with, and the view was a white screen. The exposure turns
    automatic and the tab says so; a fixed exposure the user chose stays as it is."""
    from PyQt6.QtWidgets import QCheckBox

    from tests.test_render import checker_scene
    from ui.main_window import MainWindow

    s = Settings()
    s.render.overlay = False
    w = MainWindow(s, checker_scene())
    qtbot.addWidget(w)
    w.show()
    qtbot.waitExposed(w)
    assert s.render.exposure_mode == "manual"
    box = w.sky_panel.editors["sky.enabled"]
    assert isinstance(box, QCheckBox)
    box.setChecked(True)
    assert s.render.exposure_mode == "auto"
    assert "automatic" in w.sky_panel.status.text()
    box.setChecked(False)
    s.set("render.exposure_mode", "manual")
    s.set("render.exposure_ev", 9.0)  # the user's own daylight exposure
    box.setChecked(True)
    assert s.render.exposure_mode == "manual" and s.render.exposure_ev == 9.0
    box.setChecked(False)
    s.set("render.exposure_ev", -1.3)
    w.settings_as_given = True  # a study's condition: its protocol's exposure, exactly
    box.setChecked(True)
    assert s.render.exposure_mode == "manual"


def test_daylight_from_the_command_line_or_a_preset_opens_at_an_automatic_exposure(qtbot, tmp_path):
    """``vrpreview --set sky.enabled=true`` (or a preset with daylight on and nothing said
    of the exposure) opened on a white screen: the window's first frame was at the lamp-lit
    room's fixed exposure. It opens at the automatic one, as ticking the box gives."""
    from tests.test_render import checker_scene
    from ui.main_window import MainWindow

    s = Settings()
    s.render.overlay = False
    s.set("sky.enabled", True)
    w = MainWindow(s, checker_scene())
    qtbot.addWidget(w)
    assert s.render.exposure_mode == "auto"
    assert "automatic" in w.sky_panel.status.text()
    s.set("sky.enabled", False)
    s.set("render.exposure_mode", "manual")
    preset = tmp_path / "daylight.json"
    preset.write_text('{"settings": {"sky": {"enabled": true}}}')
    w.apply_preset(str(preset))
    assert s.sky.enabled and s.render.exposure_mode == "auto"
    w.close()


def test_the_showrooms_window_shows_the_sky_itself_in_daylight(host):
    """The built-in showroom's window pane glows to stand for the sky while daylight is off.
    With daylight on the sky is drawn, and the pane would hide it behind its dim glow (the
    blinds' gaps showed as dark stripes, and the floor mirrored them): it is not drawn, so
    the gaps show the day sky, in every path; with daylight off it is there as before."""
    from assets.showroom import WINDOW_Z, build_showroom

    scene = build_showroom(0)
    pane = [m.name for m in scene.meshes].index("window")
    assert scene.materials[scene.meshes[pane].material].sky_standin
    pose = ((0.0, 1.6, 0.5), 90.0, 5.0)  # facing the west window (x = -4)
    centre = (-3.99, 1.6, 0.5 * sum(WINDOW_Z))
    for path, mitigation in (("deferred", "none"), ("forward", "none"), ("deferred", "cps")):
        hdr = look(host, scene, *pose, render__path=path, cps__mode=mitigation)
        r, c = pixel(host, *pose, centre)
        window = hdr[r - 12 : r + 12, c - 12 : c + 12] @ LUMA
        # The sunlit slats and, through their gaps, the sky: thousands of cd/m2 (the pane
        # glowed at 0.75 and, lit, showed about 120 in the gaps).
        assert np.percentile(window, 5) > 1000.0, path
        ids = host.object_ids(_frame(host, pose))[0]
        assert pane not in np.unique(ids[r - 12 : r + 12, c - 12 : c + 12]), path
    host.settings.set("sky.enabled", False)
    try:
        ids = host.object_ids(_frame(host, pose))[0]
        r, c = pixel(host, *pose, centre)
        assert pane in np.unique(ids[r - 12 : r + 12, c - 12 : c + 12])
    finally:
        host.settings.set("sky.enabled", True)
        host.settings.set("render.path", "deferred")
        host.settings.set("cps.mode", "none")


def _frame(host: OffscreenHost, pose) -> FrameInput:
    cam = StereoCamera(host.settings.stereo)
    cam.set_pose(*pose)
    return FrameInput(cam.eyes(*host.eye_size), gaze=(-1, -1))


def test_the_models_own_sun_gives_way_to_the_sun_of_the_date_and_time(host):
    """A room exported from Blender with its Sun lamp (a glTF directional light) had two suns
    with daylight on, and two patches of sun on the floor. With daylight on the model's own
    suns give way to the sun placed by date and time, in the picture, the even light, the
    photons and the Cycles reference; with daylight off the model's sun is its light."""
    import dataclasses

    from app.daylight_photons import daylight_for
    from app.lab.cycles_reference import lights_for
    from app.photons import trace_photons
    from app.scene import Light

    plain = room()
    towards = np.array([0.3, -0.6, -0.74])  # in through the south window, steeper than ours
    own = Light(
        (0.0, 0.0, 0.0),
        (1.0, 1.0, 1.0),
        60000.0,
        kind="directional",
        direction=tuple(float(v) for v in towards / np.linalg.norm(towards)),
    )
    sunny = dataclasses.replace(plain, lights=[*plain.lights, own])
    pose = ((0.0, 2.9, 0.0), 180.0, -85.0)  # under the ceiling, looking down
    ours = look(host, plain, *pose)
    both = look(host, sunny, *pose)
    assert np.allclose(both, ours, rtol=1e-4, atol=1e-4)
    lights = host.renderer.frame_lights()
    assert [lt.kind for lt in lights] == ["point", "directional"] and own not in lights
    s = host.settings
    assert [d["kind"] for d in lights_for(sunny, s)] == ["point", "directional"]
    assert lights_for(sunny, s)[-1] == lights_for(plain, s)[-1]
    day = daylight_for(s.sky)
    kept = [trace_photons(sc, 4096, daylight=day).power.sum() for sc in (plain, sunny)]
    assert kept[1] == pytest.approx(kept[0], rel=1e-6)
    s.set("sky.enabled", False)
    try:
        assert own in host.renderer.frame_lights()  # the model's sun, with daylight off
        lit = look(host, sunny, *pose)
        assert float((lit @ LUMA).max()) > 10 * float((look(host, plain, *pose) @ LUMA).max())
    finally:
        s.set("sky.enabled", True)


def test_a_photo_backdrop_outside_the_window_shows_as_the_view_out_in_daylight(host):
    """A KHR_materials_unlit backdrop outside the window (a photo of the view out) glowed at
    its 1-lux level whatever the daylight: 0.2 cd/m2, a black pane beside a sky of 10,000.
    With daylight on it now shows at the day's outdoor light, as the sky would there, in our
    frame and in the Cycles reference's job; it neither shuts out nor adds to the daylight the
    room gets; with daylight off it glows at its 1-lux level as before."""
    import dataclasses

    from app.gltf_materials import UNLIT_CD_M2
    from app.lab.cycles_reference import export
    from app.sky import bake_sky, unlit_gain

    plain = room()
    colour = np.array([0.6, 0.7, 0.5])
    photo = Material(
        "view out",
        (0.0, 0.0, 0.0, 1.0),
        roughness=1.0,
        metallic=1.0,
        emissive=tuple(float(c) for c in colour * UNLIT_CD_M2),
        unlit=True,
    )
    backdrop = dataclasses.replace(
        grid("backdrop", (-6, -1, 5), (12, 0, 0), (0, 6, 0), 4, (0, 0, -1)), material=1
    )
    scene = dataclasses.replace(
        plain, meshes=[*plain.meshes, backdrop], materials=[*plain.materials, photo]
    ).sanitized()
    pose = ((0.0, 1.6, 0.0), 180.0, 10.0)
    at = pixel(host, *pose, (0.0, 2.3, 2.0))  # in the window
    sky = float(look(host, plain, *pose)[at] @ LUMA)
    seen = look(host, scene, *pose)[at]
    assert 0.5 * sky < float(seen @ LUMA) < 5.0 * sky, (seen, sky)
    assert seen[1] > seen[0] > seen[2]  # its own colour
    down = ((0.0, 2.8, 0.0), 0.0, -89.0)
    floor = [float((look(host, sc, *down) @ LUMA).mean()) for sc in (plain, scene)]
    assert floor[1] == pytest.approx(floor[0], rel=0.05)
    s = host.settings
    gain = unlit_gain(bake_sky(s.sky))
    job = export(scene, s, scene.spawn, (32, 18), 4)
    assert job.materials[1]["emissive"] == pytest.approx(list(colour * UNLIT_CD_M2 * gain))
    s.set("sky.enabled", False)
    try:
        night = look(host, scene, *pose)[at]
        assert night == pytest.approx(colour * UNLIT_CD_M2, rel=0.05)
    finally:
        s.set("sky.enabled", True)
