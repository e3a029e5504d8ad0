"""The F9 heat map belongs to the view it measured: moving, looking elsewhere or changing a
setting removes it (the pixels are the live view's again), and F8 toggles it from anywhere."""

from __future__ import annotations

import numpy as np
import pytest
from PyQt6.QtCore import QPoint, Qt
from PyQt6.QtGui import QKeySequence, QMouseEvent

from app.settings import Settings
from tests.test_gui import grab, send_mouse
from ui.main_window import MainWindow

VIEW_W, VIEW_H = 480, 270


@pytest.fixture
def window(qtbot):
    settings = Settings()
    settings.render.overlay = False  # the statistics text changes every frame; the picture not
    w = MainWindow(settings)
    qtbot.addWidget(w)
    w.view.setFixedSize(VIEW_W, VIEW_H)
    w.show()
    qtbot.waitExposed(w)
    qtbot.waitUntil(lambda: w.view.renderer is not None, timeout=10000)
    w.keys_overlay.dismiss()
    w.load("showroom")
    w.wait_for_load()
    # Coarse shading away from the gaze: the live frame differs from full quality, so the
    # heat map has something to show.
    w.settings.cps.mode = "cps"
    w._setting_changed("cps.mode")
    qtbot.waitUntil(lambda: len(w.session.edge) == 2, timeout=5000)
    grab(w)
    yield w
    w.close()


def diff(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.abs(a.astype(int) - b.astype(int)).mean())


def shortcut(w: MainWindow, key: str):
    return next(a for a in w.actions() if a.shortcut() == QKeySequence(key))


def test_moving_removes_the_heat_map(window, qtbot):
    view, walker = window.view, window.session.walker
    live = grab(window)
    window.measure_quality()  # F9
    assert view.heat_map_shown and window.quality_panel.heat.isChecked()
    assert diff(grab(window), live) > 1.0  # the heat map is drawn over the view
    pose = (walker.position.copy(), walker.yaw_deg, walker.pitch_deg)
    qtbot.keyPress(view, Qt.Key.Key_W)
    qtbot.waitUntil(lambda: walker.position[2] != pose[0][2], timeout=5000)
    qtbot.keyRelease(view, Qt.Key.Key_W)
    grab(window)
    assert not view.heat_map_shown
    qtbot.waitUntil(lambda: not window.quality_panel.heat.isEnabled(), timeout=2000)
    assert not window.quality_panel.heat.isChecked()
    assert "earlier view" in window.quality_panel.state.text()
    # Back where it was measured: the live view, no heat map (it never comes back by itself).
    walker.place(*pose)
    assert diff(grab(window), live) < 0.5


def test_a_setting_or_the_gaze_removes_it_and_f8_toggles_it(window, qtbot):
    view, s = window.view, window.settings
    live = grab(window)
    f8 = shortcut(window, "F8")
    f8.trigger()  # nothing measured yet: F8 measures first, and shows the map
    assert window.quality_panel.report["frame"]["psnr_db"] < 80
    heat = grab(window)
    assert view.heat_map_shown and diff(heat, live) > 1.0
    f8.trigger()  # off
    assert not view.heat_map_shown and diff(grab(window), live) < 0.5
    # Another tab, the keyboard in one of its controls: the F8 key still works.
    window.dock.widget().setCurrentWidget(window.tcr_panel)
    window.activateWindow()
    qtbot.waitUntil(window.isActiveWindow, timeout=5000)
    window.tcr_panel.enabled.setFocus()
    qtbot.keyClick(window.tcr_panel.enabled, Qt.Key.Key_F8)  # on again: the same map
    assert view.heat_map_shown and diff(grab(window), heat) < 0.5

    # A setting changes (and changes back): the map is gone, the pixels are the live view's.
    s.render.exposure = s.render.exposure * 1.5
    window._setting_changed("render.exposure")
    grab(window)
    assert not view.heat_map_shown
    s.render.exposure = s.render.exposure / 1.5
    window._setting_changed("render.exposure")
    assert diff(grab(window), live) < 0.5
    qtbot.waitUntil(lambda: not window.quality_panel.heat.isEnabled(), timeout=2000)

    f8.trigger()  # stale measurement dropped: F8 measures this view again
    assert view.heat_map_shown and diff(grab(window), live) > 1.0
    gaze = window.session.gaze.state
    u, v = gaze.u, gaze.v
    # The cursor moves over the view: the gaze (and the foveal region) moved.
    send_mouse(view, QMouseEvent.Type.MouseMove, QPoint(VIEW_W // 8, VIEW_H // 3))
    grab(window)
    assert (gaze.u, gaze.v) != (u, v) and not view.heat_map_shown


def test_a_new_scene_removes_the_heat_map(window, qtbot):
    window.measure_quality()
    assert window.view.heat_map_shown
    window.load("corridor")
    window.wait_for_load()
    grab(window)
    assert not window.view.heat_map_shown
    qtbot.waitUntil(lambda: not window.quality_panel.heat.isEnabled(), timeout=2000)
