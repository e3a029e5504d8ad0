"""Coarse pixel shading on the GPU, checked against the numpy reference in app/cps.py and
against the full-rate frame: level maps, block shading, the filters, masks, visualisation."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from app.cps import bilinear_filter, block_image, detail_map, hierarchical_filter
from app.frame import FrameInput
from app.scenes import resolve
from app.session import Session
from app.settings import Settings
from render.offscreen import OffscreenHost
from render.passes import CPS_LEVEL_COLOURS

W, H = 320, 180  # two 160x180 eyes
CAPS = [(5.0, 3.0, 4.0), (2.0, 5.0, 4.0)]
SIDES = ("left", "right", "bottom")


@pytest.fixture(scope="module")
def scene():
    """The showroom without glowing materials: the emissive pass adds glow per pixel after the
    (coarse) lighting, which would hide what is compared here."""
    room = resolve("showroom")
    room.materials = [dataclasses.replace(m, emissive=(0.0, 0.0, 0.0)) for m in room.materials]
    return room


@pytest.fixture(scope="module")
def host(scene):
    h = OffscreenHost(W, H, Settings())
    h.set_scene(scene)
    h.set_text_image(None)
    yield h
    assert not h.renderer.errors
    h.close()


def configure(host: OffscreenHost, **values) -> None:
    s = host.settings
    defaults = Settings()
    for key in s.keys():
        if key.startswith(("cps.", "render.", "tcr.")):
            s.set(key, defaults.get(key))
    s.render.overlay = False
    # Reflections read the lit picture elsewhere on screen (coarse in the periphery): they
    # would carry CPS's periphery into the fovea's floor, which is not what is compared here.
    s.render.reflections = "off"
    s.cps.fovea_deg, s.cps.deg_per_level = 8.0, 5.0
    for key, value in values.items():
        s.set(key.replace("__", "."), value)


def frame(host: OffscreenHost, scene, gaze=(0.4, 0.55), caps=None, t_frame=150) -> FrameInput:
    session = Session(host.settings.copy())
    session.set_scene(scene)
    session.apply_path_frame(t_frame)
    fi = session.frame_input(*host.eye_size)
    fi.gaze = gaze
    fi.cps_caps = list(caps or CAPS)
    fi.edge_hits = None
    return fi


def reference_levels(host: OffscreenHost, fi: FrameInput, eye: int) -> np.ndarray:
    """The numpy detail map, row 0 at the top like the GPU read-back."""
    view = fi.eyes[eye]
    caps = dict(zip(SIDES, fi.cps_caps[eye]))
    return np.flipud(detail_map(view, view.width, view.height, fi.gaze, caps, host.settings.cps))


def hdr(host: OffscreenHost) -> list[np.ndarray]:
    return [host.read_hdr(e)[..., :3] for e in range(2)]


def away_from_marker(fi: FrameInput) -> np.ndarray:
    """(H, W) mask of the side-by-side view without the gaze marker the overlay draws."""
    ok = np.ones((H, W), bool)
    gu, gv = fi.gaze
    for e in range(2):
        cx, cy = int((e + gu) * W / 2), int(gv * H)
        ok[max(0, cy - 14) : cy + 14, max(0, cx - 14) : cx + 14] = False
    return ok


def gl_rows(a: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray(np.flipud(a))


def test_gpu_level_map_matches_the_reference(host, scene):
    for values in (
        {"cps__max_level": 5},
        {"cps__max_level": 3, "cps__fovea_deg": 0.0},
        {"cps__max_level": 5, "cps__deg_per_level": 1.0},
    ):
        configure(host, cps__mode="cps", **values)
        fi = frame(host, scene)
        host.draw(fi)
        with host.ctx:
            maps = host.renderer.cps.read_levels()
        for eye in range(2):
            ref = reference_levels(host, fi, eye)
            agree = (maps[eye] == ref).mean()
            # float32 on the GPU against float64: only block decisions right at a level's
            # boundary may differ.
            assert agree > 0.995, (values, eye, agree)
            assert maps[eye].max() <= host.settings.cps.max_level
        assert len(np.unique(np.concatenate([m.ravel() for m in maps]))) >= 3


def test_blocks_are_the_full_rate_image_at_block_centres(host, scene):
    configure(host)
    fi = frame(host, scene)
    host.draw(fi)
    full = hdr(host)
    configure(host, cps__mode="cps", cps__filter="none", cps__max_level=5)
    host.draw(fi)
    raw = hdr(host)
    with host.ctx:
        maps = host.renderer.cps.read_levels()
    for eye in range(2):
        expected = block_image(gl_rows(full[eye]), gl_rows(maps[eye]))
        np.testing.assert_allclose(gl_rows(raw[eye]), expected, rtol=2e-3, atol=2e-4)
        # Level-5 blocks are flat before filtering.
        lv = gl_rows(maps[eye])
        img = gl_rows(raw[eye])
        for y in range(0, lv.shape[0], 32):
            for x in range(0, lv.shape[1], 32):
                if lv[y, x] == 5:
                    block = img[y : y + 32, x : x + 32].reshape(-1, 3)
                    assert np.ptp(block, axis=0).max() == 0.0


@pytest.mark.parametrize("kind", ["hierarchical", "bilinear"])
def test_gpu_filters_match_the_reference(host, scene, kind):
    configure(host, cps__mode="cps", cps__filter="none", cps__max_level=5)
    fi = frame(host, scene)
    host.draw(fi)
    raw = hdr(host)
    with host.ctx:
        maps = host.renderer.cps.read_levels()
    configure(host, cps__mode="cps", cps__filter=kind, cps__max_level=5)
    host.draw(fi)
    filtered = hdr(host)
    oracle = hierarchical_filter if kind == "hierarchical" else bilinear_filter
    for eye in range(2):
        expected = oracle(gl_rows(raw[eye]), gl_rows(maps[eye]))
        np.testing.assert_allclose(gl_rows(filtered[eye]), expected, rtol=4e-3, atol=4e-4)


def test_pipelines_and_dispatches_give_the_same_image(host, scene):
    images = []
    for lighting, dispatch in (("fragment", "multi"), ("compute", "multi"), ("compute", "single")):
        configure(
            host,
            cps__mode="cps",
            render__lighting=lighting,
            cps__dispatch=dispatch,
            cps__max_level=5,
        )
        images.append(host.draw(frame(host, scene)))
    assert np.array_equal(images[1], images[2])  # multi-level and single dispatch
    assert np.abs(images[0].astype(int) - images[1].astype(int)).max() <= 1


@pytest.mark.parametrize("kind", ["none", "bilinear", "hierarchical"])
def test_foveal_pixels_are_identical_to_the_full_rate_frame(host, scene, kind):
    configure(host)
    fi = frame(host, scene)
    full = host.draw(fi)
    configure(host, cps__mode="cps", cps__filter=kind)
    test = host.draw(fi)
    with host.ctx:
        maps = host.renderer.cps.read_levels()
    fovea = np.hstack(maps) == 0
    assert 0.01 < fovea.mean() < 0.9
    assert np.array_equal(test[fovea], full[fovea])  # the gaze marker is in both
    assert not np.array_equal(test[~fovea], full[~fovea])


def test_hierarchical_filter_lowers_the_periphery_error(host, scene):
    configure(host)
    fi = frame(host, scene)
    full = host.draw(fi).astype(float)
    errors = {}
    for kind in ("none", "bilinear", "hierarchical"):
        configure(host, cps__mode="cps", cps__filter=kind, cps__max_level=4)
        errors[kind] = np.abs(host.draw(fi).astype(float) - full).mean()
    assert errors["hierarchical"] < errors["none"]
    assert errors["bilinear"] < errors["none"]


def test_visualisation_paints_each_level_in_its_colour(host, scene):
    configure(host, cps__mode="cps", cps__max_level=5, cps__fovea_deg=10.0, cps__deg_per_level=4.0)
    fi = frame(host, scene, caps=[(5, 5, 5)] * 2)
    plain = host.draw(fi).astype(float)
    host.settings.cps.visualize = True
    tinted = host.draw(fi).astype(float)
    with host.ctx:
        maps = host.renderer.cps.read_levels()
    levels = np.hstack(maps)
    # tinted = (plain + colour) / 2 on every coarse pixel; level 0 is left as it is.
    assert np.array_equal(tinted[levels == 0], plain[levels == 0])
    for s in range(1, 6):
        sel = (levels == s) & away_from_marker(fi)
        assert sel.any(), s
        colour = (2 * tinted[sel] - plain[sel]).mean(axis=0) / 255.0
        np.testing.assert_allclose(colour, CPS_LEVEL_COLOURS[s], atol=0.02)


def test_masks_darken_or_blur_only_where_detail_would_drop(host, scene):
    configure(host)
    fi = frame(host, scene, caps=[(5, 5, 5)] * 2)
    full = host.draw(fi).astype(float)
    configure(host, cps__mode="cps")
    host.draw(fi)
    with host.ctx:
        levels = np.hstack(host.renderer.cps.read_levels())
    configure(host, cps__mode="black-mask")
    black = host.draw(fi).astype(float)
    configure(host, cps__mode="blur-mask")
    blur = host.draw(fi).astype(float)
    fovea = levels == 0
    far = levels >= 3
    # The masks fade in continuously from the fovea's edge, where the block map still says 0.
    assert np.abs(black[fovea] - full[fovea]).mean() < 0.3
    assert black[far].mean() < 0.6 * full[far].mean()

    def detail(img):
        return np.abs(np.diff(img.mean(axis=2), axis=1))

    d_full, d_blur = detail(full), detail(blur)
    inner = far[:, 1:] & far[:, :-1]
    assert d_blur[inner].mean() < 0.6 * d_full[inner].mean()
    assert np.abs(blur[fovea] - full[fovea]).mean() < 2.0


def test_temporal_filter_alternates_the_eyes_and_keeps_the_fovea(host, scene):
    configure(host, cps__mode="cps", cps__temporal=True, cps__max_level=4)
    fi = frame(host, scene)
    shares = []
    for _ in range(3):
        host.draw(fi)
        with host.ctx:
            maps = host.renderer.cps.read_levels()
        shares.append([m.mean() for m in maps])
    # One eye has the strong (coarser) reduction, the other the weak; they swap every frame.
    (a0, a1), (b0, b1), (c0, c1) = shares
    assert (a0 > a1) == (b0 < b1) == (c0 > c1)
    configure(host)
    full = host.draw(fi)
    configure(host, cps__mode="cps", cps__temporal=True, cps__max_level=4)
    for _ in range(2):
        test = host.draw(fi)
    with host.ctx:
        fovea = np.hstack(host.renderer.cps.read_levels()) == 0
    assert np.array_equal(test[fovea], full[fovea])


@pytest.mark.parametrize("reproject", [True, False])
def test_temporal_filter_on_a_still_view_blends_towards_the_finer_image(host, scene, reproject):
    """A still camera: history and the new frame show the same surfaces, so with or without
    reprojection each coarse pixel is the weighted mix of this frame and the last one."""
    configure(host)
    fi = frame(host, scene)
    full = host.draw(fi).astype(float)
    configure(host, cps__mode="cps", cps__temporal=True, cps__reproject=reproject, cps__max_level=4)
    for _ in range(4):
        out = host.draw(fi).astype(float)
    assert not host.renderer.errors
    with host.ctx:
        coarse = np.hstack(host.renderer.cps.read_levels()) > 0
    configure(host, cps__mode="cps", cps__max_level=4)
    plain = host.draw(fi).astype(float)
    # Blending in the finer frame brings the periphery closer to full rate than CPS alone.
    err_temporal = np.abs(out - full)[coarse].mean()
    err_plain = np.abs(plain - full)[coarse].mean()
    assert err_temporal < err_plain


def test_the_level0_scissor_holds_every_full_rate_pixel():
    """The fragment pipeline lights level 0 only inside fovea_rect: check it against the
    reference map for gazes across the view (corners included), caps and fovea sizes."""
    from app.camera import StereoCamera
    from render.cps import fovea_rect

    rng = np.random.default_rng(7)
    settings = Settings().cps
    cam = StereoCamera(Settings().stereo)
    checked = 0
    for trial in range(40):
        settings.fovea_deg = float(rng.choice([0.0, 3.0, 10.0, 25.0, 60.0]))
        settings.deg_per_level = float(rng.choice([1.0, 5.0, 20.0]))
        settings.max_level = int(rng.integers(0, 6))
        caps = tuple(float(c) for c in rng.integers(0, 6, 3))
        gaze = (float(rng.choice([0.0, 1.0, rng.uniform()])), float(rng.uniform()))
        eye = cam.eyes(160, 180)[trial % 2]
        rect = fovea_rect(eye, gaze, caps, settings)
        if rect is None:
            continue
        levels = detail_map(eye, 160, 180, gaze, dict(zip(SIDES, caps)), settings)
        ys, xs = np.nonzero(levels == 0)  # GL rows, as the rectangle
        x, y, w, h = rect
        assert ((xs >= x) & (xs < x + w) & (ys >= y) & (ys < y + h)).all(), (trial, rect)
        checked += xs.size > 0 and w * h < 160 * 180
    assert checked >= 5  # rectangles smaller than the view, holding level-0 pixels


def test_reprojection_keeps_a_walking_view_from_smearing(host, scene):
    """Frames 0.1 s apart while walking (what a 10 fps preview shows): with reprojection the
    blended history lines up with the new frame; without, it is the old view, offset."""

    def walk(n):
        return frame(host, scene, t_frame=n)

    frames = [walk(n) for n in range(60, 130, 6)]
    configure(host)
    full = host.draw(frames[-1]).astype(float)
    errors = {}
    for reproject in (True, False):
        configure(
            host,
            cps__mode="cps",
            cps__temporal=True,
            cps__reproject=reproject,
            cps__max_level=3,
            cps__history_weight=0.8,
        )
        for fi in frames:
            host.render_only(fi)
        out = host.read_pixels().astype(float)
        errors[reproject] = np.abs(out - full).mean()
    assert errors[True] < 0.9 * errors[False], errors


@pytest.mark.parametrize("scale", [1.0, 0.5])
def test_the_filter_folded_into_the_present_shows_the_same_picture(scale):
    """Where nothing between the CPS filter and the present pass needs the pixels, the present
    pass reconstructs them itself (one full-screen pass fewer): the picture on screen, and the
    colour read back, are the filter's own pass's within half-float rounding, with the
    showroom's glowing lamps added on top of the folded lighting."""
    room = resolve("showroom")  # with its emissive lamps: the colour is cleared and added to
    h = OffscreenHost(W, H, Settings())
    try:
        h.set_scene(room)
        h.set_text_image(None)
        configure(h, cps__mode="cps", render__scale=scale)
        fi = frame(h, room)
        shown, colour = {}, {}
        for fold in (True, False):
            h.renderer.fold_cps_filter = fold
            shown[fold] = h.draw(fi).astype(int)
            assert (h.renderer.present.fold is not None) == fold
            assert h.renderer.cps_filter.folded == fold
            # the lamps glow: light added to a cleared colour
            assert h.renderer.cps_filter.clears == fold
            colour[fold] = hdr(h)
        assert not h.renderer.errors
    finally:
        h.close()
    diff = np.abs(shown[True] - shown[False])
    assert diff.max() <= 4 and diff.mean() < 0.1, (diff.max(), diff.mean())
    for folded, own in zip(colour[True], colour[False]):
        assert np.allclose(folded, own, rtol=2e-3, atol=1e-4)
        assert own.max() > 0.0


@pytest.mark.parametrize(
    "values",
    [{"render__reflections": "screen"}, {"cps__temporal": True}, {"render__exposure_mode": "auto"}],
)
def test_the_filter_keeps_its_pass_when_a_later_pass_reads_the_pixels(host, scene, values):
    """Reflections, the temporal filter and the exposure meter read the lit picture before it
    is shown: the filter must have drawn it, so it is not folded."""
    configure(host, cps__mode="cps")
    for key, value in values.items():
        host.settings.set(key.replace("__", "."), value)
    host.draw(frame(host, scene))
    assert host.renderer.present.fold is None
    assert not host.renderer.cps_filter.folded
    configure(host, cps__mode="cps")
    host.draw(frame(host, scene))
    assert host.renderer.present.fold is not None  # and with them off, it is
    assert not host.renderer.cps_filter.clears  # no glow in this scene: nothing to clear
