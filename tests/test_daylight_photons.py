"""Daylight in the photon map: the sun and the sky shine in through a room's window."""

from __future__ import annotations

import numpy as np
import pytest

from app import daylight_photons as dp
from app.indirect import PhotonService
from app.photon_map import PhotonMap
from app.photons import trace_photons
from app.raycast import RayCaster
from app.scene import Material, Mesh, PointLight, Scene, Viewpoint
from app.settings import PhotonSettings, Settings, SkySettings

# The room: x in [-2, 2], y in [0, 3], z in [-2.5, 2.5]; a 2 m x 1 m window in the +X wall.
LO, HI = np.array([-2.0, 0.0, -2.5]), np.array([2.0, 3.0, 2.5])
WINDOW_Y, WINDOW_Z = (1.0, 2.0), (-1.0, 1.0)
WINDOW_AREA = (WINDOW_Y[1] - WINDOW_Y[0]) * (WINDOW_Z[1] - WINDOW_Z[0])
#: Towards the sun: in through the window (from +X) and down onto the floor, never the ceiling.
SUN = np.array([1.0, 0.8, 0.2]) / np.linalg.norm([1.0, 0.8, 0.2])
SUN_LUX = 50_000.0


def _quad(name: str, corners, normal, material: int) -> Mesh:
    idx = np.array([[0, 1, 2], [0, 2, 3]], np.uint32)
    c = np.asarray(corners, np.float32)
    if np.cross(c[1] - c[0], c[2] - c[0]) @ np.asarray(normal) < 0:
        idx = idx[:, ::-1].copy()
    n = np.tile(np.asarray(normal, np.float32), (4, 1))
    return Mesh(name, c, n, np.zeros((4, 2), np.float32), idx, material)


def _rect_x(x: float, y0: float, y1: float, z0: float, z1: float, material: int) -> Mesh:
    c = [(x, y0, z0), (x, y0, z1), (x, y1, z1), (x, y1, z0)]
    return _quad("east wall", c, (-1.0, 0.0, 0.0), material)


def _room(window: bool = True, floor=(0.8, 0.45, 0.15), lights=()) -> Scene:
    """Walls and ceiling white, the floor ``floor``; an opening in the +X wall if ``window``."""
    (x0, y0, z0), (x1, y1, z1) = LO, HI
    meshes = [
        _quad("floor", [(x0, y0, z0), (x1, y0, z0), (x1, y0, z1), (x0, y0, z1)], (0, 1, 0), 1),
        _quad("ceiling", [(x0, y1, z0), (x1, y1, z0), (x1, y1, z1), (x0, y1, z1)], (0, -1, 0), 0),
        _quad("west", [(x0, y0, z0), (x0, y1, z0), (x0, y1, z1), (x0, y0, z1)], (1, 0, 0), 0),
        _quad("north", [(x0, y0, z0), (x1, y0, z0), (x1, y1, z0), (x0, y1, z0)], (0, 0, 1), 0),
        _quad("south", [(x0, y0, z1), (x1, y0, z1), (x1, y1, z1), (x0, y1, z1)], (0, 0, -1), 0),
    ]
    if window:
        (wy0, wy1), (wz0, wz1) = WINDOW_Y, WINDOW_Z
        meshes += [
            _rect_x(x1, y0, wy0, z0, z1, 0),  # below the window
            _rect_x(x1, wy1, y1, z0, z1, 0),  # above it
            _rect_x(x1, wy0, wy1, z0, wz0, 0),  # beside it
            _rect_x(x1, wy0, wy1, wz1, z1, 0),
        ]
    else:
        meshes.append(_rect_x(x1, y0, y1, z0, z1, 0))
    mats = [Material("white", (0.8, 0.8, 0.8, 1.0)), Material("floor", (*floor, 1.0))]
    scene = Scene("window room", meshes, mats, lights=list(lights))
    scene.spawn = Viewpoint((0.0, 1.6, 0.0))
    return scene


def _sun_only(lux: float = SUN_LUX) -> dp.Daylight:
    return dp.Daylight((dp.Beam(tuple(SUN), (lux, lux, lux)),))


def _near(photons: PhotonMap, y: float, tol: float = 0.05) -> np.ndarray:
    """Summed RGB power of the photons stored within ``tol`` of the plane at height ``y``."""
    on = np.abs(photons.positions[:, 1] - y) < tol
    return photons.power[on].astype(np.float64).sum(axis=0)


def test_sun_through_a_window_lights_the_ceiling_warm_by_the_floor():
    """Only the sun, only through the window: the ceiling, which the sun does not reach, gets
    bounce light, and it is warm because the floor the sun lands on is."""
    photons = trace_photons(_room(), 60_000, seed=3, daylight=_sun_only())
    ceiling = _near(photons, HI[1])
    west = photons.power[np.abs(photons.positions[:, 0] - LO[0]) < 0.05].sum(axis=0)
    for bounce in (ceiling, west):  # neither is in the sun's way (it lands on the floor)
        r, g, b = bounce
        assert b > 0.0 and r > 1.2 * g > 1.2 * b  # warm, like the floor (0.8, 0.45, 0.15)
    # The ceiling gets a plausible share of the beam through the window (50 klx x 2 m2 x cos):
    # the floor reflects about half of it, the white walls pass most of that on.
    entering = SUN_LUX * WINDOW_AREA * SUN[0]
    assert 0.2 < ceiling @ dp.LUMA / entering < 0.7
    # A grey floor gives a neutral bounce.
    grey = _near(trace_photons(_room(floor=(0.5, 0.5, 0.5)), 60_000, 3, daylight=_sun_only()), 3.0)
    assert grey.max() / grey.min() < 1.1
    # The sun's first hits (the patch on the floor) are not stored: the renderer draws them.
    patch = photons.positions[:, 1] < 0.05
    assert photons.positions[patch].shape[0] < 0.5 * len(photons)


def test_closed_room_and_sun_below_the_horizon_get_no_sun_photons():
    closed = trace_photons(_room(window=False), 20_000, seed=1, daylight=_sun_only())
    assert len(closed) == 0
    assert any("no window or opening" in note for note in closed.notes)
    # The sun behind the room (from -X): it cannot reach the window, so it gets no photons.
    behind = dp.Daylight((dp.Beam((-SUN[0], SUN[1], SUN[2]), (SUN_LUX,) * 3),), (10.0,) * 3)
    photons = trace_photons(_room(), 20_000, seed=1, daylight=behind)
    assert any("daylight: 0 sun photons, 20000 sky photons" in n for n in photons.notes)
    # Midnight in Paris: the sun is down; the sky has faded too, so no daylight at all.
    night = dp.daylight_for(SkySettings(enabled=True, time="00:30"))
    assert night is not None and night.beams == () and night.dark
    # Dusk: the sun just set, a little sky light left (sky photons only).
    dusk = dp.Daylight((), (30.0, 30.0, 30.0), (0.0, 0.0, 0.0))
    photons = trace_photons(_room(), 20_000, seed=1, daylight=dusk)
    assert len(photons) > 0
    assert any("daylight: 0 sun photons, 20000 sky photons" in n for n in photons.notes)


def test_same_seed_same_photons():
    sky = dp.daylight_for(SkySettings(enabled=True, time="15:00", north_deg=90.0))
    assert sky is not None and sky.beams
    a = trace_photons(_room(), 20_000, seed=5, daylight=sky)
    b = trace_photons(_room(), 20_000, seed=5, daylight=sky)
    assert len(a) > 0 and a.notes == b.notes
    assert a.positions.tobytes() == b.positions.tobytes()
    assert a.power.tobytes() == b.power.tobytes()
    c = trace_photons(_room(), 20_000, seed=6, daylight=sky)
    assert a.positions.tobytes() != c.positions.tobytes()


def _emitted(daylight: dp.Daylight, count: int, seed: int = 0):
    """The daylight paths a trace would start in the window room: origins, directions, flux."""
    scene = _room()
    caster = RayCaster(scene.triangles())
    box = dp.scene_box(caster.tri)
    assert box is not None
    portal = dp.find_portal(caster, box, np.array(scene.spawn.position), seed)
    sources = dp.DaylightSources.build(daylight, portal, caster)
    n = np.array([count] * (sources.n_beams + 1))
    src = np.repeat(np.arange(len(n)), n)
    return sources, *sources.emit(src, n, np.random.default_rng(seed)), src


def _through_window(o: np.ndarray, d: np.ndarray) -> np.ndarray:
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (HI[0] - o[:, 0]) / d[:, 0]
    p = o + d * t[:, None]
    return (
        (t > 0)
        & (p[:, 1] > WINDOW_Y[0])
        & (p[:, 1] < WINDOW_Y[1])
        & (p[:, 2] > WINDOW_Z[0])
        & (p[:, 2] < WINDOW_Z[1])
    )


def test_sun_power_through_the_window_is_illuminance_times_beam_area():
    """The sun photons that pass the window carry E * A_window * cos, the beam that enters."""
    sources, o, d, flux, src = _emitted(_sun_only(), 200_000)
    sun = src == 0
    inside = _through_window(o[sun], d[sun])
    entering = flux[sun][inside].sum(axis=0)
    expected = SUN_LUX * WINDOW_AREA * SUN[0]
    assert entering == pytest.approx([expected] * 3, rel=0.03)
    # The portal is the window, not the whole box: most photons go in (over the whole box,
    # about 2 m2 x cos of the 27 m2 of box that the sun sees: one in twenty).
    assert inside.mean() > 0.6


def test_sky_power_through_the_window_is_pi_luminance_area():
    """A uniform sky (and ground of the same luminance) of L sends pi L A through a window."""
    lum = 1_000.0
    day = dp.Daylight((), (lum, lum, lum), (lum, lum, lum))
    _, o, d, flux, src = _emitted(day, 400_000)
    inside = _through_window(o, d) & (d[:, 0] < 0)
    assert flux[inside].sum(axis=0) == pytest.approx([np.pi * lum * WINDOW_AREA] * 3, rel=0.03)
    # Over the whole box one photon in twenty would go in; the portal sends in over a fifth.
    assert inside.mean() > 0.2
    # The photons that go in carry alike: none of them a few hundred times another's light, as
    # when the portal's cells were weighed by their probe crossings alone (the window's grown
    # border, which no probe ray crossed, then sent a few photons of 318x the mean flux).
    entering = flux[inside, 1]
    assert entering.max() < 4.0 * entering.mean()


def test_lamps_and_daylight_share_the_photons_by_power():
    lamp = PointLight((0.0, 2.5, 0.0), (1.0, 1.0, 1.0), 200.0, 100.0)
    day = _sun_only()
    photons = trace_photons(_room(lights=[lamp]), 30_000, seed=2, daylight=day)
    note = next(n for n in photons.notes if n.startswith("daylight:"))
    sun = int(note.split()[1])
    sources, *_ = _emitted(day, 1, seed=2)  # the portal the trace of seed 2 finds
    lamp_power = 4 * np.pi * 200.0
    expected = 30_000 * sources.power_luma[0] / (sources.power_luma[0] + lamp_power)
    assert abs(sun - expected) <= 1
    # A directional light of the scene is a beam through the window like the sun.
    sunlamp = PointLight((0, 0, 0), (1, 1, 1), SUN_LUX, kind="directional", direction=tuple(-SUN))
    a = trace_photons(_room(lights=[sunlamp]), 20_000, seed=4)
    b = trace_photons(_room(), 20_000, seed=4, daylight=_sun_only())
    assert a.power.tobytes() == b.power.tobytes() and len(a) > 0


def test_service_traces_again_when_the_sun_moves():
    """With indirect light on and daylight on, a new time of day is a new photon map; daylight
    off gives the lamps-only map back."""
    sky = SkySettings(enabled=True, time="09:00", north_deg=-90.0)
    service = PhotonService(sky=lambda: sky)
    settings = PhotonSettings(enabled="on", photons=8192)
    scene = _room(lights=[PointLight((0.0, 2.5, 0.0), (1.0, 1.0, 1.0), 50.0, 100.0)])
    morning = service.ensure(settings, scene)
    assert morning is not None and any(n.startswith("daylight:") for n in morning.notes)
    assert service.ensure(settings, scene) is morning
    sky.time = "11:00"
    later = service.ensure(settings, scene)
    assert later is not None and later is not morning
    assert later.power.tobytes() != morning.power.tobytes()
    sky.enabled = False
    lamps = service.ensure(settings, scene)
    assert lamps is not None and not any(n.startswith("daylight:") for n in lamps.notes)
    assert service.current(settings, scene) is lamps


def test_window_traces_daylight_and_again_when_daylight_is_turned_off(qtbot):
    """The window, indirect light on: ticking Daylight in the Sun and sky tab brings daylight
    photons (traced in the background), a new time of day new ones, unticking the lamps' only."""
    from ui.main_window import MainWindow

    settings = Settings()
    settings.render.overlay = False
    settings.photons.enabled = "on"
    settings.photons.photons = 16384
    lamp = PointLight((0.0, 2.5, 0.0), (1.0, 1.0, 1.0), 50.0, 100.0)
    w = MainWindow(settings, _room(lights=[lamp]))
    qtbot.addWidget(w)
    w.show()
    qtbot.waitExposed(w)

    def shown(daylight: bool):
        m = w._photons_shown
        return m is not None and any(n.startswith("daylight:") for n in m.notes) == daylight

    qtbot.waitUntil(lambda: shown(False), timeout=20000)
    lamps_only = w._photons_shown
    w.sky_panel.editors["sky.enabled"].setChecked(True)
    qtbot.waitUntil(lambda: shown(True), timeout=20000)
    morning = w._photons_shown
    # Daylight adds the sun's and the sky's bounces to the lamps' light.
    assert morning is not None and morning.power.sum() > 2 * lamps_only.power.sum()
    assert w.sky_panel.form.set("sky.time", "11:30")
    qtbot.waitUntil(lambda: shown(True) and w._photons_shown is not morning, timeout=20000)
    w.sky_panel.editors["sky.enabled"].setChecked(False)
    qtbot.waitUntil(lambda: shown(False), timeout=20000)
    assert w._photons_shown.power.tobytes() == lamps_only.power.tobytes()
    w.close()


@pytest.mark.parametrize(
    "pane",
    [
        Material("sky seen through the window", (1, 1, 1, 1), emissive=(0.01, 0.01, 0.01)),
        Material("glass", (0.9, 0.95, 1.0, 0.2), alpha_mode="BLEND"),
    ],
    ids=["glowing pane", "blended glass"],
)
def test_a_pane_in_the_window_lets_the_daylight_in(pane: Material):
    """A window glazed with a glowing pane (the sky beyond it) or with glass: both cast no
    shadow in the renderer, and the photons' daylight comes in as through the open window."""
    open_room = trace_photons(_room(), 60_000, seed=3, daylight=_sun_only())
    glazed = _room()
    (wy0, wy1), (wz0, wz1) = WINDOW_Y, WINDOW_Z
    glazed.materials.append(pane)
    glazed.meshes.append(_rect_x(HI[0], wy0, wy1, wz0, wz1, len(glazed.materials) - 1))
    photons = trace_photons(glazed, 60_000, seed=3, daylight=_sun_only())
    assert not any("no window or opening" in note for note in photons.notes)
    ceiling, reference = _near(photons, HI[1]) @ dp.LUMA, _near(open_room, HI[1]) @ dp.LUMA
    assert ceiling == pytest.approx(reference, rel=0.1)


def test_the_photons_carry_the_sun_and_sky_the_renderer_draws():
    """The photons' sun is the renderer's (and Cycles'): its illuminance and colour, not a
    second clear-sky formula (which gave 18 % more at 10:00 on the default date). Their sky is
    the baked sky, direction by direction: a window turned to the sunny south lets in more
    sky light than the same window turned north (with a uniform sky the two were equal)."""
    import dataclasses

    from app.sky import sun_light
    from tests.test_sky_light import room

    where = SkySettings(enabled=True, time="10:00")
    day = dp.daylight_for(where)
    sun = sun_light(where)
    assert day is not None and sun is not None and len(day.beams) == 1
    lux = np.asarray(day.beams[0].lux)
    assert lux == pytest.approx(np.asarray(sun.color) * sun.intensity, rel=1e-9)
    assert np.asarray(day.beams[0].towards) == pytest.approx(-np.asarray(sun.direction))
    power = {}
    for north in (0.0, 180.0):  # the window (+Z) faces south, then north
        sky_only = dataclasses.replace(
            dp.daylight_for(SkySettings(enabled=True, time="10:00", north_deg=north)), beams=()
        )
        photons = trace_photons(room(n=4), 40_000, seed=1, daylight=sky_only)
        power[north] = float((photons.power @ dp.LUMA).sum())
    assert power[0.0] > 1.15 * power[180.0], power


def test_sky_photons_carry_alike_and_the_skys_light_through_the_window(tmp_path):
    """Sky photons are drawn from the baked sky in proportion to the light each direction sends
    through the face they enter by: the power through the window is the sky's (the sum over its
    texels of L cos Omega, times the window's area), and every photon that goes in carries about
    the same light, though the user's sky photo holds a bright band over 50x the rest."""
    import dataclasses

    from PIL import Image

    photo = np.full((64, 128, 3), 20, np.uint8)
    photo[22:26] = 255  # a bright band 20-30 degrees over the horizon, all around
    photo[32:] = (40, 60, 30)  # the ground
    Image.fromarray(photo).save(tmp_path / "sky.png")
    where = SkySettings(enabled=True, time="10:00", image=str(tmp_path / "sky.png"))
    day = dataclasses.replace(dp.daylight_for(where), beams=())
    assert day.sky_key is not None
    image, dirs, solid = dp._baked_sky(day.sky_key)
    cos = np.clip(dirs @ np.array([1.0, 0.0, 0.0]), 0.0, None)  # looking out of the window
    seen = image[cos > 0.0] @ dp.LUMA
    assert seen.max() > 50.0 * seen.min()
    expected = (image * (cos * solid)[..., None]).sum(axis=(0, 1)) * WINDOW_AREA
    _, o, d, flux, src = _emitted(day, 400_000)
    inside = _through_window(o, d) & (d[:, 0] < 0)
    assert flux[inside].sum(axis=0) == pytest.approx(expected, rel=0.03)
    entering = flux[inside] @ dp.LUMA
    # A photon's light varies with its portal cell's weight (up to 3.7x here, see
    # crossing_weight) and the cosine within its texel (up to 2x), not with the sky's 50x.
    assert np.percentile(entering, 99.9) < 3.0 * entering.mean()
    assert entering.max() < 8.0 * entering.mean()
