"""The frame-time graph: its data (the ring buffer and the stacking) and its pixels."""

from __future__ import annotations

import numpy as np
import pytest
from PyQt6.QtCore import Qt

from app.frame_log import OTHER, FrameLog, nice_ceiling, target_fps
from app.settings import Settings
from tests.test_gui import qimage_to_array
from tests.test_render import checker_scene
from ui.frame_graph import TARGET_COLOUR, FrameGraph, pass_colour
from ui.main_window import MainWindow


def test_frame_times_are_the_intervals_and_the_first_is_its_passes():
    log = FrameLog()
    log.record(10.0, {"gbuffer": 4.0, "lighting": 6.0})
    log.record(10.025, {"gbuffer": 5.0, "lighting": 7.0})
    assert [round(f.frame_ms, 6) for f in log.frames] == [10.0, 25.0]


def test_the_ring_buffer_keeps_the_newest_frames_of_the_last_seconds():
    log = FrameLog(seconds=5.0, capacity=100)
    for i in range(250):  # 0.1 s apart: 25 s in all, more than the buffer holds
        log.record(i * 0.1, {"gbuffer": 1.0})
    assert len(log) == 100 and log.frames[0].t == pytest.approx(15.0)
    recent = log.recent()
    assert len(recent) == 51  # 19.9 s back to 24.9 s, both ends kept
    assert recent[0].t == pytest.approx(19.9) and recent[-1].t == pytest.approx(24.9)
    assert log.recent(now=100.0) == []  # nothing rendered for a while: an empty graph
    log.clear()
    assert len(log) == 0 and log.stack().tops.shape == (0, 1)


def test_stacking_puts_passes_in_order_and_tops_up_to_the_frame_time():
    log = FrameLog()
    log.record(0.0, {"gbuffer": 5.0, "lighting": 10.0})
    log.record(0.020, {"gbuffer": 5.0, "lighting": 10.0})  # 20 ms: 5 ms of other work
    log.record(0.030, {"gbuffer": 6.0, "photons": 2.0, "lighting": 9.0})  # GPU 17 > 10 ms
    log.record(0.070, {"gbuffer": 5.0})  # lighting off this frame: it adds nothing
    s = log.stack()
    assert s.names == ("gbuffer", "lighting", "photons", OTHER)
    np.testing.assert_allclose(s.t, [-0.070, -0.050, -0.040, 0.0])
    np.testing.assert_allclose(
        s.tops,
        [
            [5.0, 15.0, 15.0, 15.0],  # the first frame: its passes, no other
            [5.0, 15.0, 15.0, 20.0],
            [6.0, 15.0, 17.0, 17.0],  # GPU longer than the interval: no negative "other"
            [5.0, 5.0, 5.0, 40.0],
        ],
    )
    assert s.peak_ms == pytest.approx(40.0)


def test_the_target_line_is_the_governors_target_else_30_fps_and_the_axis_top_is_round():
    s = Settings()
    assert target_fps(s) == 30.0  # "auto" without a display: the governor is off
    assert target_fps(s, display_hz=90.0) == 90.0
    s.set("render.target_fps", "45")
    assert target_fps(s) == 45.0
    s.set("render.target_fps", "0")
    assert target_fps(s, display_hz=90.0) == 30.0
    assert [nice_ceiling(v) for v in (41.7, 50.0, 51.0, 0.3, 120.0, 0.0)] == [
        50.0,
        50.0,
        100.0,
        0.5,
        200.0,
        1.0,
    ]


def steady_log() -> FrameLog:
    """Five seconds at 20 ms a frame: geometry 5 ms, lighting 10 ms, 5 ms of other work."""
    log = FrameLog(seconds=5.0)
    for i in range(251):
        log.record(i * 0.020, {"gbuffer": 5.0, "lighting": 10.0})
    return log


@pytest.fixture
def graph(qtbot):
    log = steady_log()
    w = FrameGraph(log, Settings(), clock=lambda: log.frames[-1].t)
    w.setFixedSize(640, 180)
    qtbot.addWidget(w)
    w.show()
    qtbot.waitExposed(w)
    return w


def rgb(colour) -> tuple[int, int, int]:
    return (colour.red(), colour.green(), colour.blue())


def test_graph_draws_the_target_line_and_the_stacked_passes_at_their_heights(
    graph, compare_reference
):
    img = qimage_to_array(graph.grab().toImage())
    assert img.shape == (180, 640, 3)
    assert graph.top_ms == 50.0  # 33.3 ms * 1.25 rounded up to a round figure
    r = graph.plot_rect()
    # 33.3 ms of 50 ms on a plot from row 20 to row 162: 47.3 rows below the top.
    y_target = round(r.bottom() - 1000.0 / 30.0 / 50.0 * r.height())
    assert y_target == round(graph.y_of(1000.0 / 30.0))
    columns = range(int(r.left()) + 200, int(r.right()) - 20, 37)  # clear of the line's label
    for x in columns:
        assert tuple(img[y_target, x]) == rgb(TARGET_COLOUR), x
        assert tuple(img[y_target - 3, x]) != rgb(TARGET_COLOUR)
        assert tuple(img[y_target + 3, x]) != rgb(TARGET_COLOUR)
    x = int(r.center().x())
    layers = {2.5: "gbuffer", 10.0: "lighting", 17.5: OTHER}  # the middle of each layer
    for ms, name in layers.items():
        assert tuple(img[round(graph.y_of(ms)), x]) == rgb(pass_colour(name)), name
    assert tuple(img[round(graph.y_of(28.0)), x]) == (255, 255, 255)  # above the 20 ms frames
    # The legend: a swatch per layer, the top layer first.
    legend = img[:, graph.width() - graph.LEGEND_W + 5]
    for name in ("gbuffer", "lighting", OTHER):
        assert (legend == rgb(pass_colour(name))).all(axis=1).any(), name
    compare_reference("frame_graph", img, max_mean=2.0, max_frac=0.02)


def test_graph_of_an_empty_log_shows_the_axes_and_target_only(qtbot):
    w = FrameGraph(FrameLog(), Settings(), clock=lambda: 0.0)
    w.setFixedSize(400, 150)
    qtbot.addWidget(w)
    w.show()
    qtbot.waitExposed(w)
    img = qimage_to_array(w.grab().toImage())
    r = w.plot_rect()
    y = round(w.y_of(1000.0 / 30.0))
    assert tuple(img[y, int(r.right()) - 10]) == rgb(TARGET_COLOUR)
    inside = img[int(r.top()) + 2 : int(r.bottom()) - 2, int(r.left()) + 2 : int(r.right()) - 2]
    colours = {tuple(c) for c in inside.reshape(-1, 3)}
    assert not colours & {rgb(pass_colour(n)) for n in ("gbuffer", "lighting", OTHER)}


def test_with_auto_the_line_is_the_screens_refresh(qtbot, monkeypatch):
    w = FrameGraph(FrameLog(), Settings(), clock=lambda: 0.0, display_hz=lambda: 60.0)
    assert w.target_ms() == pytest.approx(1000.0 / 60.0)
    w.display_hz = lambda: None  # no screen known: the 30 fps line
    assert w.target_ms() == pytest.approx(1000.0 / 30.0)
    monkeypatch.setenv("VRPREVIEW_DISPLAY_HZ", "75")  # the window's view reads the screen
    settings = Settings()
    settings.render.overlay = False
    win = MainWindow(settings, checker_scene())
    qtbot.addWidget(win)
    try:
        assert win.frame_dock.widget().target_ms() == pytest.approx(1000.0 / 75.0)
    finally:
        win.close()


def test_f3_shows_the_live_graph_of_the_window_and_hides_it_again(qtbot):
    settings = Settings()
    settings.render.overlay = False
    w = MainWindow(settings, checker_scene())
    qtbot.addWidget(w)
    w.resize(1000, 700)
    w.show()
    qtbot.waitExposed(w)
    try:
        qtbot.waitUntil(lambda: w.view.renderer is not None, timeout=10000)
        w.activateWindow()  # a window shortcut needs the window active
        qtbot.waitUntil(w.isActiveWindow, timeout=5000)
        assert not w.frame_dock.isVisible()
        qtbot.keyClick(w.view, Qt.Key.Key_F3)
        assert w.frame_dock.isVisible() and w.frame_dock.windowTitle() == "Frame time"
        qtbot.waitUntil(lambda: len(w.view.frame_log) > 5, timeout=10000)
        names = w.view.frame_log.stack().names
        assert "gbuffer" in names and "present" in names and names[-1] == OTHER
        graph = w.frame_dock.widget()
        assert graph.timer.isActive()  # repainting while shown
        qtbot.keyClick(w.view, Qt.Key.Key_F3)
        assert not w.frame_dock.isVisible() and not graph.timer.isActive()
        view_menu = next(a.menu() for a in w.menuBar().actions() if a.text() == "&View")
        assert "Frame-time graph" in [a.text() for a in view_menu.actions()]
    finally:
        w.close()
