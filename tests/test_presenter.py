"""Presenter mode: the A/B split's pixels (headless), and F5 / M / [ ] / the divider drag, the
fps readout and the corridor walk in the real window (pytest-qt, Xvfb)."""

from __future__ import annotations

import logging
import re

import numpy as np
import pytest
from PyQt6.QtCore import QPoint, Qt
from PyQt6.QtGui import QMouseEvent

from app import scenes
from app.quality import full_quality
from app.session import Session
from app.settings import Settings
from render.ab_frame import ABFrame, draw_offscreen
from render.ab_split import WITHOUT, SplitView, caption_rects, technique_caption
from render.offscreen import OffscreenHost
from tests.test_gui import grab, send_mouse
from ui.main_window import MainWindow

W, H = 320, 120  # the whole side-by-side view of the headless checks
EYE = W // 2


@pytest.fixture(scope="module")
def showroom():
    return scenes.BUILTIN["showroom"]()


def live_settings(**values) -> Settings:
    s = Settings()
    s.render.overlay = False
    for key, value in values.items():
        s.set(key.replace("__", "."), value)
    return s


def frame_for(settings: Settings, scene, size=(EYE, H), gaze=(0.15, 0.5)):
    session = Session(settings)
    session.set_scene(scene)
    session.gaze.set_cursor(*gaze)  # the ring left of the divider in both eyes
    session.tick(0.0)
    return session.frame_input(*size)


def headless(settings: Settings, scene) -> OffscreenHost:
    host = OffscreenHost(W, H, settings)
    host.set_scene(scene)
    host.set_text_image(None)
    return host


def outside(rects, shape) -> np.ndarray:
    """A mask of one eye (row 0 at the top) without the caption rectangles."""
    keep = np.ones(shape, bool)
    for rect in rects:
        if rect is not None:
            x, y, w, h = rect
            keep[shape[0] - y - h : shape[0] - y, x : x + w] = False
    return keep


@pytest.mark.parametrize("divider", [0.5, 0.3])
def test_left_of_the_divider_is_the_technique_right_is_full_quality_in_both_eyes(showroom, divider):
    settings = live_settings(cps__mode="black-mask")
    fi = frame_for(settings, showroom)
    host = headless(settings, showroom)
    ref_host = headless(full_quality(settings, converged_photons=False), showroom)
    ab = ABFrame(host.ctx)
    try:
        technique = host.draw(fi)
        reference = ref_host.draw(fi)
        shot = draw_offscreen(host, ab, fi, SplitView(divider))
        rects = host.renderer.ab_split.caption_rects
        after = host.draw(fi)  # no split: the normal frame again
        assert not host.renderer.errors and not ab.errors
    finally:
        with host.ctx:
            ab.release()
        host.close()
        ref_host.close()
    d = round(divider * EYE)
    keep = outside(rects, (H, EYE))
    for eye in (0, 1):
        x0 = eye * EYE
        got, tech, ref = (img[:, x0 : x0 + EYE].astype(int) for img in (shot, technique, reference))
        # Left of the line (its dark edge at d - 2): the technique's frame, pixel for pixel.
        left = keep[:, : d - 2]
        assert np.array_equal(got[:, : d - 2][left], tech[:, : d - 2][left]), eye
        # Right of it: the full-quality frame, which the black mask visibly differs from.
        right = keep[:, d + 2 :]
        assert np.array_equal(got[:, d + 2 :][right], ref[:, d + 2 :][right]), eye
        assert np.abs(tech[:, d + 2 :] - ref[:, d + 2 :]).mean() > 10, "mask shows no change"
        # The divider: two light columns between two dark ones, top to bottom.
        rows = keep[:, d - 2 : d + 2].all(axis=1)
        assert (got[rows, d - 1 : d + 1] == 255).all(), eye
        assert (got[rows, d - 2] == 0).all() and (got[rows, d + 1] == 0).all(), eye
        # The captions: white text on each side where it fits, in both eyes at one place.
        for rect in rects:
            if rect is not None:
                x, y, cw, ch = rect
                box = got[H - y - ch : H - y, x : x + cw]
                assert (box.min(axis=2) > 240).sum() > 30, (eye, rect)
    assert rects[1] is not None  # "Without (full quality)" fits the right side at 0.3 and 0.5
    assert np.array_equal(after, technique)


def test_the_captions_say_what_the_technique_is_in_plain_words():
    s = Settings()
    assert technique_caption(s) == "No technique on: both sides at full quality"
    s.cps.mode = "cps"
    assert technique_caption(s) == "With coarse shading in the periphery"
    s.cps.mode = "blur-mask"
    s.tcr.enabled = True
    assert technique_caption(s) == (
        "With the periphery blurred (blur mask) and texture detail chosen per object (TCR)"
    )
    s.tcr.enabled = False
    s.render.path = "forward"  # the masks run on the deferred path only
    assert "needs the deferred rendering path" in technique_caption(s)
    s.render.path = "deferred"
    s.photons.stereo_reuse = True
    assert technique_caption(s) == "With the periphery blurred (blur mask)"  # no photon map
    assert technique_caption(s, has_photons=True).endswith("and faster indirect light")


def test_a_side_too_narrow_for_its_caption_shows_none():
    sizes = ((120, 30), (80, 30))
    assert caption_rects(SplitView(0.5), (400, 300), sizes) == [(70, 7, 120, 30), (210, 7, 80, 30)]
    left, right = caption_rects(SplitView(0.95), (400, 300), sizes)
    assert left == (250, 7, 120, 30) and right is None
    assert caption_rects(SplitView(0.1), (400, 300), sizes)[0] is None
    assert SplitView(float("nan")).divider_px(400) == 200  # a bad value: the middle
    assert SplitView(7.0).divider_px(400) == 400


# -- the window -----------------------------------------------------------------------------
VIEW_W, VIEW_H = 480, 270


@pytest.fixture
def window(qtbot, showroom):
    settings = Settings()
    settings.render.overlay = False  # fps text changes every run; the picture must not
    w = MainWindow(settings, showroom)
    qtbot.addWidget(w)
    w.view.setFixedSize(VIEW_W, VIEW_H)
    w.show()
    qtbot.waitExposed(w)
    activate(qtbot, w)  # shortcuts (F5, M, [ ]) go to the active window
    qtbot.waitUntil(lambda: w.view.renderer is not None, timeout=10000)
    yield w
    w.close()


def activate(qtbot, w: MainWindow) -> None:
    w.raise_()
    w.activateWindow()
    qtbot.waitUntil(w.isActiveWindow, timeout=5000)
    w.view.setFocus()


def frames_later(qtbot, window, n: int = 2) -> None:
    """Wait until the view has drawn ``n`` more frames."""
    start = window.view.renderer.frames
    qtbot.waitUntil(lambda: window.view.renderer.frames >= start + n, timeout=20000)


def test_f5_splits_the_view_and_m_and_the_divider_keys_and_drag_work(
    window, qtbot, compare_reference
):
    view, p = window.view, window.presenter
    (menu,) = [a.menu() for a in window.menuBar().actions() if a.text() == "&View"]
    entry = {a.text(): a for a in menu.actions()}["Presenter mode"]
    assert entry.shortcut().toString() == "F5" and entry.isCheckable()
    frames_later(qtbot, window)
    normal = grab(window)
    qtbot.keyClick(view, Qt.Key.Key_F5)
    assert p.active and entry.isChecked()
    # The readout: big (48 px) in the top-right corner, an integer of frames per second.
    label = p.fps_label
    qtbot.waitUntil(lambda: "ms without" in label.text(), timeout=5000)
    fps, detail = p.readout_lines()
    assert re.fullmatch(r"\d+ fps", fps) and label.text().startswith(fps)
    assert re.fullmatch(r"GPU per frame: \d+ ms with, \d+ ms without", detail)
    assert label.isVisible() and label.font().pixelSize() == 48
    assert label.geometry().right() > VIEW_W - 40 and label.geometry().top() < 40
    # M: the next mitigation mode, and the caption says it.
    assert window.settings.cps.mode == "none" and p.caption.startswith("No technique")
    qtbot.keyClick(view, Qt.Key.Key_M)
    assert window.settings.cps.mode == "black-mask"
    assert p.caption == "With the periphery darkened (black mask)"
    assert window.statusBar().currentMessage().startswith("Mitigation mode")
    # [ and ]: the divider steps a twentieth of the eye.
    qtbot.keyClick(view, Qt.Key.Key_BracketLeft)
    assert p.split.divider == pytest.approx(0.45)
    qtbot.keyClick(view, Qt.Key.Key_BracketRight)
    qtbot.keyClick(view, Qt.Key.Key_BracketRight)
    assert p.split.divider == pytest.approx(0.55)
    # Dragging the divider in the right eye moves it in both; the gaze stays where it was.
    gaze = (window.session.gaze.state.u, window.session.gaze.state.v)
    eye_w = VIEW_W // 2
    at = QPoint(eye_w + round(0.55 * eye_w), VIEW_H // 2)
    send_mouse(view, QMouseEvent.Type.MouseButtonPress, at, Qt.MouseButton.LeftButton)
    assert p.dragging
    to = QPoint(eye_w + round(0.7 * eye_w), VIEW_H // 3)
    send_mouse(view, QMouseEvent.Type.MouseMove, to, Qt.MouseButton.LeftButton)
    send_mouse(view, QMouseEvent.Type.MouseButtonRelease, to, Qt.MouseButton.LeftButton)
    assert not p.dragging and p.split.divider == pytest.approx(0.7, abs=0.01)
    assert (window.session.gaze.state.u, window.session.gaze.state.v) == gaze
    assert not window.session.gaze.state.fixed
    frames_later(qtbot, window)
    shot = grab(window)
    d = round(p.split.divider * eye_w)
    for x0 in (0, eye_w):  # each eye its own divider, at the same place
        assert (shot[20 : VIEW_H // 2, x0 + d - 1 : x0 + d + 1] == 255).all()
    compare_reference("presenter_split_480x270", shot, max_mean=1.0, max_frac=0.003)
    # Off again: exactly the normal picture (M four times is round to "none" again).
    for _ in range(3):
        qtbot.keyClick(view, Qt.Key.Key_M)
    assert window.settings.cps.mode == "none"
    qtbot.keyClick(view, Qt.Key.Key_F5)
    assert not p.active and not label.isVisible() and p._ab is None
    frames_later(qtbot, window)
    assert np.array_equal(grab(window), normal)
    # Outside presenter mode [ and ] leave the divider alone.
    qtbot.keyClick(view, Qt.Key.Key_BracketLeft)
    assert p.split.divider == pytest.approx(0.7, abs=0.01)
    assert not window.view.renderer.errors


def test_presenting_the_corridor_walk_cycles_the_modes_while_it_plays(window, qtbot):
    view, p = window.view, window.presenter
    window.load("corridor")
    window.wait_for_load()
    assert window.session.scene.name == "corridor"
    activate(qtbot, window)  # the loading dialog (shown after 0.3 s) had the focus
    qtbot.keyClick(view, Qt.Key.Key_F5)
    assert p.active
    captions = [p.caption]
    modes = [window.settings.cps.mode]
    for _ in range(4):
        qtbot.keyClick(view, Qt.Key.Key_M)
        frames_later(qtbot, window)
        modes.append(window.settings.cps.mode)
        captions.append(p.split.left)  # what the last frame's caption said
    assert modes == ["none", "black-mask", "blur-mask", "cps", "none"]
    assert len(set(captions[:4])) == 4 and captions[4] == captions[0]
    assert p.split.right == WITHOUT
    start = tuple(window.session.walker.position)
    qtbot.keyClick(view, Qt.Key.Key_P)
    assert view.playing
    frames_later(qtbot, window, 4)
    assert tuple(window.session.walker.position) != start  # walking the corridor
    assert not view.renderer.errors and not p._ab.errors


def test_present_the_corridor_walk_loads_it_and_starts_the_walk(window, qtbot):
    p = window.presenter
    p.actions["demo"].trigger()
    assert p.active
    qtbot.waitUntil(lambda: window.view.playing, timeout=30000)
    assert window.session.scene.name == "corridor"


def test_a_failing_comparison_gives_the_normal_picture_and_says_so(
    window, qtbot, monkeypatch, caplog
):
    view, p = window.view, window.presenter
    window.session.settings.render.refine = "off"  # the same picture frame after frame
    frames_later(qtbot, window)
    normal = grab(window)

    def broken(*_args, **_kwargs) -> None:  # say, the GPU has no memory for a second scene
        raise MemoryError("out of GPU memory for the full-quality half")

    monkeypatch.setattr(ABFrame, "render", broken)
    qtbot.keyClick(view, Qt.Key.Key_F5)
    frames_later(qtbot, window, 3)
    assert p.active and "cannot draw the comparison" in window.statusBar().currentMessage()
    assert np.array_equal(grab(window), normal)  # the view keeps showing the scene
    records = [r for r in caplog.records if r.levelno >= logging.ERROR]
    assert len(records) == 1 and "full-quality half failed" in records[0].getMessage()
    for r in records:
        r.expected = True  # this test's own error
