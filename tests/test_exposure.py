"""Exposure in EV, automatic exposure and the tone curves (issue 14, light in physical units).

What a user would check: one EV is twice the light; the tone curves start at black, never
darken a brighter input, saturate, and match their published sources; automatic exposure shows
a dim room and one 100 times brighter alike, gradually, at the set adaptation time; black,
blinding and 1x1 frames stay finite; TCR's light term follows what the picture shows.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from app.camera import StereoCamera
from app.exposure import (
    EV_DEFAULT,
    EV_MAX,
    EV_MIN,
    NO_SURFACE,
    EyeAdaptation,
    displayed_brightness,
    exposure_scale,
    metered_ev,
    tone_map,
    white_luminance,
)
from app.frame import FrameInput
from app.paths import FIXED_DT
from app.scene import Material, PointLight, Scene, Texture, Viewpoint
from app.session import Session
from app.settings import Settings
from render.offscreen import OffscreenHost
from tests.test_ambient import _env_brdf
from tests.test_render import quad

W, H = 64, 36  # the whole side-by-side view: two 32x36 eyes (flat walls: size is irrelevant)
GREY = np.geomspace(1e-6, 1e6, 2001)


def srgb_decode(px: np.ndarray) -> np.ndarray:
    c = np.asarray(px, np.float64) / 255.0
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


def srgb_encode(c: np.ndarray) -> np.ndarray:
    c = np.asarray(c, np.float64)
    return np.where(c < 0.0031308, 12.92 * c, 1.055 * np.maximum(c, 1e-7) ** (1 / 2.4) - 0.055)


def wall(albedo=0.5, emissive=0.0, lights=(), textured=False) -> Scene:
    """A wall filling both eyes' views at 1 m, lit only by the ambient term (and ``lights``)."""
    textures = []
    if textured:
        tex = np.full((4, 4, 4), 255, np.uint8)
        tex[::2, ::2, :3] = 200
        textures = [Texture("plaster", tex)]
    return Scene(
        "wall",
        [quad("wall", (0, 1.6, -1), 20.0)],
        [
            Material(
                "m",
                (albedo, albedo, albedo, 1),
                0 if textured else None,
                roughness=1.0,
                emissive=(emissive,) * 3,
            )
        ],
        textures,
        list(lights),
        Viewpoint((0, 1.6, 0)),
    ).sanitized()


@pytest.fixture(scope="module")
def host():
    h = OffscreenHost(W, H, Settings())
    yield h
    assert not h.renderer.errors
    h.close()


def frame(host: OffscreenHost) -> FrameInput:
    cam = StereoCamera(host.settings.stereo)
    cam.set_pose((0, 1.6, 0), 0.0, 0.0)
    return FrameInput(cam.eyes(*host.eye_size), gaze=(-1, -1))


def show(host: OffscreenHost, scene: Scene | None, **settings) -> np.ndarray:
    """Defaults plus ``settings`` (``render__exposure_ev=...``); a new scene when given."""
    s = host.settings
    for key in s.keys():
        if key.startswith("render.") or key.startswith("tcr."):
            s.set(key, Settings().get(key))
    s.render.overlay = False
    # These rooms are lit by the fixed ambient term (render.ambient) the tests set: the
    # estimate from the lamps would replace it (0 in a room without lamps).
    s.render.ambient_estimate = False
    for key, value in settings.items():
        s.set(key.replace("__", "."), value)
    if scene is not None:
        host.set_scene(scene)
    return host.draw(frame(host))


def centre(img: np.ndarray) -> np.ndarray:
    return img[H // 2 - 4 : H // 2 + 4, W // 4 - 4 : W // 4 + 4].reshape(-1, 3).mean(axis=0)


# -- exposure in EV ----------------------------------------------------------------------------


def test_white_is_1_2_times_2_to_the_ev_and_one_ev_is_twice_the_light():
    assert white_luminance(0.0) == pytest.approx(1.2)
    assert white_luminance(10.0) == pytest.approx(1228.8)
    for ev in (-10.0, EV_DEFAULT, 0.0, 7.5, 20.0):
        assert exposure_scale(ev + 1.0) == pytest.approx(exposure_scale(ev) / 2.0)


def test_one_ev_halves_the_picture_before_the_tone_curve(host):
    luminance = 3.0  # cd/m2: a glowing wall, no lights
    scene = wall(albedo=0.0, emissive=luminance)
    ev = math.log2(luminance / (1.2 * 0.5))  # the wall at half of white
    base = dict(render__tone_mapping="clamp", render__ambient=0.0)
    half = srgb_decode(centre(show(host, scene, render__exposure_ev=ev, **base)))
    quarter = srgb_decode(centre(show(host, None, render__exposure_ev=ev + 1, **base)))
    eighth = srgb_decode(centre(show(host, None, render__exposure_ev=ev + 2, **base)))
    np.testing.assert_allclose(half, 0.5, rtol=0.02)
    np.testing.assert_allclose(quarter, 0.25, rtol=0.02)
    np.testing.assert_allclose(eighth, 0.125, rtol=0.03)
    # Brightness is exposure compensation: 50% is one EV less; the old factor still works.
    dimmer = srgb_decode(
        centre(show(host, None, render__exposure_ev=ev, render__brightness=0.5, **base))
    )
    np.testing.assert_allclose(dimmer, 0.25, rtol=0.02)
    factor = srgb_decode(
        centre(show(host, None, render__exposure_ev=ev + 1, render__exposure=2.0, **base))
    )
    np.testing.assert_allclose(factor, 0.5, rtol=0.02)
    assert host.renderer.exposure_readout() == f"Exposure EV {ev:.1f} (fixed)"


# -- tone curves -------------------------------------------------------------------------------


@pytest.mark.parametrize("curve", ["aces", "agx", "clamp"])
def test_tone_curves_start_at_black_never_darken_and_saturate(curve):
    grey = tone_map(np.stack([GREY] * 3, axis=-1), curve)
    assert np.all(np.isfinite(grey))
    assert np.all(np.diff(grey, axis=0) >= -1e-12), "a brighter input never shows darker"
    assert tone_map(np.zeros(3), curve).tolist() == [0.0, 0.0, 0.0]
    assert np.all(grey[-1] >= 0.99) and np.all(grey <= 1.0)
    colours = tone_map(np.random.default_rng(0).uniform(0, 50, (500, 3)), curve)
    assert np.all((colours >= 0) & (colours <= 1))


def test_aces_and_agx_match_their_published_values():
    g = np.full(3, 0.18)
    # ACES (RRT + sRGB ODT): scene 18% grey shows at about 10% of white (10 of 100 nits).
    assert tone_map(g, "aces")[0] == pytest.approx(0.10, abs=0.01)
    # Hill's fit reaches white near scene value 25.7 (the fit's a/b = 1).
    assert tone_map(np.full(3, 20.0), "aces")[0] < 1.0
    assert tone_map(np.full(3, 30.0), "aces")[0] == 1.0
    # AgX: 18% grey at the middle of its log range shows at half the display's code values;
    # white at 2^(log2(0.18) + 6.5) = 16.3.
    assert srgb_encode(tone_map(g, "agx"))[0] == pytest.approx(0.5, abs=0.01)
    assert tone_map(np.full(3, 16.3), "agx")[0] == pytest.approx(1.0, abs=0.005)
    # The default EV keeps the old look: Hill's ACES at EV -1.3 against Narkowicz's fit (the
    # old curve) at the old exposure 1, within 3 of 255 levels from 0.02 to 4 cd/m2.
    x = np.geomspace(0.02, 4.0, 200)
    old = np.clip((x * (2.51 * x + 0.03)) / (x * (2.43 * x + 0.59) + 0.14), 0, 1)
    new = tone_map(np.stack([x * exposure_scale(EV_DEFAULT)] * 3, axis=-1), "aces")[:, 0]
    assert np.abs(srgb_encode(new) - srgb_encode(old)).max() * 255 < 3


@pytest.mark.parametrize("curve", ["aces", "agx", "clamp"])
def test_the_shaders_curves_are_their_sources(host, curve):
    ev = math.log2(1.0 / 1.2)  # exposure factor 1: the wall's luminance goes straight in
    for luminance in (0.0, 0.02, 0.18, 1.0, 4.0, 30.0, 1e6):
        scene = wall(albedo=0.0, emissive=luminance)
        shown = centre(
            show(host, scene, render__tone_mapping=curve, render__exposure_ev=ev, render__ambient=0)
        )
        # 1e6 overflows the half-float picture: shown as its largest value (65504), white.
        expected = srgb_encode(tone_map(np.full(3, min(luminance, 65504.0)), curve)) * 255
        np.testing.assert_allclose(shown, expected, atol=1.5, err_msg=f"{curve} at {luminance}")


# -- automatic exposure ------------------------------------------------------------------------


def test_the_meter_leaves_out_hot_spots_and_black_corners():
    lum = np.full(1000, math.log2(0.5))
    assert metered_ev(lum) == pytest.approx(math.log2(0.5 / (1.2 * 0.18)))
    spots = lum.copy()
    spots[:40] = math.log2(1e5)  # a lamp's hot spot, 4% of the frame
    spots[40:80] = -24.0  # a black corner
    assert metered_ev(spots) == pytest.approx(metered_ev(lum))
    assert metered_ev(np.array([np.nan, np.inf])) is None
    assert metered_ev(np.full(10, NO_SURFACE)) is None  # nothing drawn: nothing to meter
    assert metered_ev(np.r_[lum, np.full(5000, NO_SURFACE)]) == metered_ev(lum)
    assert metered_ev(np.full(10, -24.0)) == EV_MIN
    assert metered_ev(np.full(10, 60.0)) == EV_MAX


def test_the_eye_adapts_with_its_time_constant():
    eye = EyeAdaptation()
    assert eye.update(2.0, FIXED_DT, 1.0) == 2.0  # the first metering is taken at once
    for _ in range(60):  # one second
        eye.update(12.0, FIXED_DT, 1.0)
    assert eye.ev == pytest.approx(2.0 + 10.0 * (1 - math.exp(-1.0)))
    assert eye.update(None, FIXED_DT, 1.0) == eye.ev  # no metering: unchanged
    assert eye.update(3.0, FIXED_DT, 0.0) == 3.0  # adaptation time 0: at once


def test_auto_exposure_shows_a_dim_and_a_100x_brighter_room_alike_gradually(host):
    auto = dict(render__exposure_mode="auto", render__adaptation_s=0.25)
    show(host, wall(), render__ambient=0.04, **auto)  # the dim room: metered at once
    for _ in range(3):
        dim = show(host, None, render__ambient=0.04, **auto)
    dim_ev = host.renderer.exposure.base_ev
    x, y = _env_brdf(1.0, 1.0)  # the even light's specular share too (roughness 1)
    assert dim_ev == pytest.approx(math.log2(0.04 * (0.5 + 0.04 * x + y) / (1.2 * 0.18)), abs=0.05)
    means, evs = [], []
    for _ in range(90):  # the lights 100x brighter, 1.5 s at the fixed step: 6 time constants
        means.append(show(host, None, render__ambient=4.0, **auto).mean())
        evs.append(host.renderer.exposure.base_ev)
    bright_ev = dim_ev + math.log2(100.0)
    assert means[-1] == pytest.approx(dim.mean(), rel=0.10)
    assert evs[-1] == pytest.approx(bright_ev, abs=0.05)
    # Gradual: glaring at first, then darker every frame; a quarter second after the change
    # (one time constant; the metering is a frame late) about two-thirds of the way.
    assert means[0] > 2 * means[-1]
    assert all(b <= a + 1e-9 for a, b in zip(means, means[1:]))
    progress = (evs[15] - dim_ev) / (bright_ev - dim_ev)
    assert 1 - math.exp(-14 / 15) - 0.02 < progress < 1 - math.exp(-1.0) + 0.02, progress
    assert host.renderer.exposure_readout() == f"Exposure EV {evs[-1]:.1f} (auto)"


def test_a_model_in_the_void_is_metered_on_its_surfaces_alone(host):
    glow = Scene(
        "lamp",
        [quad("lamp", (0, 1.6, -2), 0.8)],
        [Material("m", (0, 0, 0, 1), emissive=(10.0, 10.0, 10.0))],
        [],
        [],
    ).sanitized()
    for _ in range(3):
        img = show(host, glow, render__exposure_mode="auto", render__ambient=0.0)
        glow = None  # the first call sets the scene
    assert host.renderer.exposure.base_ev == pytest.approx(math.log2(10.0 / (1.2 * 0.18)))
    assert 60 < centre(img).mean() < 140  # the lamp at grey, not blown out by the void


def test_a_model_under_the_sky_is_metered_with_its_sky(host):
    """A small dark model seen from outside in daylight: the sky fills the view and is metered
    as a camera would (it was left out as void: the meter read the model alone, or nothing,
    and the sky of thousands of cd/m2 showed as a white screen)."""
    speck = Scene(
        "speck",
        [quad("speck", (0, 1.6, -5), 0.2)],
        [Material("m", (0.0, 0.0, 0.0, 1), roughness=1.0)],
        [],
        [],
    ).sanitized()
    fixed = show(host, speck, sky__enabled=True)
    assert fixed.mean() > 250  # the lamp-lit room's fixed exposure: the sky blows out
    for _ in range(3):
        img = show(host, None, sky__enabled=True, render__exposure_mode="auto")
    ev = host.renderer.exposure.base_ev
    sky = host.read_hdr(0)[..., :3] @ np.array([0.2126, 0.7152, 0.0722])
    assert 0.5 * np.median(sky) < white_luminance(ev) * 0.18 < 2 * np.median(sky)
    assert 40 < img.mean() < 200 and (img < 250).mean() > 0.9  # a sky, not a white screen
    host.settings.sky.enabled = False


def test_black_blinding_and_1x1_frames_stay_finite(host):
    auto = dict(render__exposure_mode="auto")
    host.set_scene(wall(albedo=0.0))
    for _ in range(3):
        img = show(host, None, render__ambient=0.0, **auto)
    assert host.renderer.exposure.base_ev == EV_MIN and img.max() < 5
    blinding = [PointLight((0, 1.6, 0), (1, 1, 1), 1e12, 50.0)]
    for scene in (wall(emissive=1e6), wall(lights=blinding)):
        host.set_scene(scene)
        for _ in range(3):
            img = show(host, None, **auto)
        ev = host.renderer.exposure.base_ev
        assert math.isfinite(ev) and EV_MIN <= ev <= EV_MAX
        assert np.isfinite(host.read_hdr(0)).all()
        assert 60 < centre(img).mean() < 200  # metered down to a grey, not black or NaN
    with OffscreenHost(2, 1, Settings()) as tiny:
        tiny.settings.render.exposure_mode = "auto"
        tiny.set_scene(wall())
        for _ in range(3):
            px = tiny.draw(frame(tiny))
        assert px.shape == (1, 2, 3) and not tiny.renderer.errors
        assert math.isfinite(tiny.renderer.exposure.base_ev)
        assert "nan" not in tiny.renderer.exposure_readout().lower()


# -- TCR's light term --------------------------------------------------------------------------


def test_displayed_brightness_is_the_brightness_once_adapted():
    assert displayed_brightness(1.0, EV_DEFAULT) == 1.0  # no metering: as the built-in scenes
    assert displayed_brightness(0.5, 3.0, 3.0) == 0.5  # adapted: the Brightness alone
    assert displayed_brightness(0.5, 3.0, 3.05) == 0.5  # the meter's noise: still exactly l=1
    assert displayed_brightness(1.0, 3.0, 1.0) == pytest.approx(0.25)  # shown 2 EV too dark
    assert math.isnan(displayed_brightness(1.0, math.nan, 0.0))
    assert displayed_brightness(0.0, 0.0, 0.0) == 0.0


def test_tcr_light_term_follows_the_exposure(host):
    """A dim room at the default fixed exposure coarsens the textures (l = 2); automatic
    exposure brightens it and l is 0; walking from a bright room into it, l eases off as
    the eye adapts; Brightness 50% adds one; a bright room never coarsens them."""
    settings = host.settings
    session = Session(settings)
    room = wall(textured=True)
    session.set_scene(room)

    def light_term(**kw) -> int:
        show(host, None, tcr__enabled=True, render__adaptation_s=0.25, **kw)
        session.exposure_state = host.renderer.exposure_state()
        assert session.displayed_brightness() == host.renderer.displayed_brightness()
        session.tick(FIXED_DT)
        reason = session.reason(0)
        assert reason is not None
        return reason.l

    show(host, room, tcr__enabled=True, render__ambient=0.04)
    # Seen 2.3 EV darker than 18% grey: floor(2.3) = 2 (the meter runs for the l term).
    assert [light_term(render__ambient=0.04) for _ in range(3)][-1] == 2
    assert light_term(render__ambient=0.04, render__exposure_mode="auto") == 0
    auto = dict(render__exposure_mode="auto")
    assert light_term(render__ambient=0.04, render__brightness=0.5, **auto) == 1
    for _ in range(40):
        bright = light_term(render__ambient=4.0, **auto)
    assert bright == 0  # a bright room, adapted: full detail
    terms = [light_term(render__ambient=0.04, **auto) for _ in range(60)]
    assert terms[1] >= 5 and terms[-1] == 0  # into the dim room: dark until the eye adapts
    assert all(b <= a for a, b in zip(terms[1:], terms[2:])), terms  # eases off gradually
    assert len(set(terms)) > 3
    # Fixed exposure: the bright room shows bright (the metering is a frame late).
    assert [light_term(render__ambient=4.0) for _ in range(2)][-1] == 0


# -- the window --------------------------------------------------------------------------------


def test_the_evaluation_bar_reads_the_exposure(qtbot):
    from tests.test_render import checker_scene
    from ui.main_window import MainWindow

    settings = Settings()
    window = MainWindow(settings, checker_scene())
    qtbot.addWidget(window)
    window.resize(1366, 768)
    window.show()
    qtbot.waitExposed(window)
    label = window.eval_bar.labels["exposure"]
    window.eval_bar.refresh()
    assert label.text() == "Exposure EV -1.3 (fixed)"
    assert "EV" in label.toolTip() and "automatic" in label.toolTip()
    mode = window.panel.editors["render.exposure_mode"]
    mode.setCurrentIndex(mode.findData("auto"))
    window.panel.editors["render.brightness"].setValue(50)  # one EV of compensation

    def metered() -> bool:
        window.eval_bar.refresh()
        return label.text().endswith("(auto)") and label.text() != "Exposure EV -0.3 (auto)"

    qtbot.waitUntil(metered, timeout=5000)
    # The quad metered on its own (3 EV brighter than the default), one EV darker for 50%.
    ev = window.view.renderer.exposure.base_ev + 1.0
    assert label.text() == f"Exposure EV {ev:.1f} (auto)" and ev > 1.0
    window.tcr_panel.poll()
    assert window.tcr_panel.brightness.text().startswith("50%")  # l reads the Brightness
    window.close()


def test_the_opening_exposure_is_unfit_for_daylight_and_a_files_own_lamps():
    """The fixed exposure a room opens with is the settings' default, made for the built-in
    scenes' lamps and the default lights; daylight or a file's own lamps ask for the
    automatic one, unless the user chose an exposure."""
    from app.exposure import unfit_opening_exposure
    from app.settings import RenderSettings

    opening = RenderSettings()
    assert (opening.exposure_mode, opening.exposure_ev) == ("manual", EV_DEFAULT)
    assert unfit_opening_exposure("manual", EV_DEFAULT, False, False) is None
    assert unfit_opening_exposure("manual", EV_DEFAULT, True, True) == "daylight"
    assert unfit_opening_exposure("manual", EV_DEFAULT, False, True) == "lamps"
    assert unfit_opening_exposure("manual", 4.0, True, True) is None  # the user's own
    assert unfit_opening_exposure("auto", EV_DEFAULT, True, True) is None
