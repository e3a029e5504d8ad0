"""The window as a designer meets it on a laptop: it fits, the eyes keep a headset's shape, the
ring's object is the one named, panels scroll, and the window remembers how it was left.

Real ``MainWindow`` under Xvfb with pytest-qt; the checks look at the window's pixels and at
what its menus and bar say.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from PyQt6.QtCore import QPoint, Qt
from PyQt6.QtGui import QImage, QMouseEvent
from PyQt6.QtWidgets import QApplication, QCheckBox, QFileDialog, QMessageBox, QScrollArea

from app.frame import FrameInput
from app.settings import Settings
from tests.test_gui import grab, qimage_to_array, send_mouse
from tests.test_render import checker_scene
from ui import window_state
from ui.main_window import MainWindow, open_main_window
from ui.prefs import config_dir

ROOT = Path(__file__).resolve().parents[1]
# Set by the device-pixel-ratio test for its child run of the gaze test.
EXPECTED_RATIO = float(os.environ.get("VRPREVIEW_TEST_RATIO", "1"))


def _pump(window: MainWindow, frames: int = 2) -> None:
    for _ in range(frames):
        QApplication.processEvents()
        window.view.repaint()


@pytest.fixture
def make_window(qtbot):
    made: list[MainWindow] = []

    def make(width: int, height: int, scene=None, overlay: bool = False) -> MainWindow:
        settings = Settings()
        settings.render.overlay = overlay  # fps text changes every run; the picture must not
        w = MainWindow(settings, scene if scene is not None else checker_scene())
        qtbot.addWidget(w)
        made.append(w)
        if not w.restored_geometry:
            w.resize_to(width, height)
        w.show()
        qtbot.waitExposed(w)
        qtbot.waitUntil(lambda: w.view.renderer is not None, timeout=10000)
        return w

    yield make
    for w in made:
        if w.isVisible():
            w.close()


def _eyes_in(shot: np.ndarray) -> tuple[int, int, int, int]:
    """(x, y, width, height) of the drawn pair, found from the black bars around it."""
    lit = shot.max(axis=2) > 0
    rows, cols = np.flatnonzero(lit.any(axis=1)), np.flatnonzero(lit.any(axis=0))
    return cols[0], rows[0], cols[-1] + 1 - cols[0], rows[-1] + 1 - rows[0]


def _ring_centres(shot: np.ndarray, base: np.ndarray) -> list[tuple[float, float]]:
    """Centre of the fixed-gaze disc in each half of the picture: the orange pixels that are
    not in ``base`` (the same view with the disc elsewhere)."""
    r, g, b = (shot[..., i].astype(int) for i in range(3))
    orange = (r > 200) & (g > 60) & (g < 150) & (b < 80)
    new = np.abs(shot.astype(int) - base.astype(int)).max(axis=2) > 24
    ys, xs = np.nonzero(orange & new)
    half = shot.shape[1] / 2
    centres = []
    for side in (xs < half, xs >= half):
        assert side.sum() > 40, "no gaze disc found"
        centres.append((xs[side].mean() + 0.5, ys[side].mean() + 0.5))
    return centres


def _id_at(ids: np.ndarray, x: float, y: float, k: int = 5) -> int | None:
    """The object at (x, y) of an eye's ID image; None where it is not the only one within
    k pixels (an edge, where the two eyes' parallax could show either)."""
    xi, yi = int(x), int(y)
    patch = ids[max(0, yi - k) : yi + k + 1, max(0, xi - k) : xi + k + 1]
    values = np.unique(patch)
    return int(values[0]) if len(values) == 1 else None


# Most points near the eyes' sides, where a ray cast for the wrong eye shape strays furthest.
GRID = [
    (u, v)
    for v in (0.1, 0.23, 0.36, 0.5, 0.64, 0.77, 0.9)
    for u in (0.03, 0.09, 0.15, 0.5, 0.85, 0.91, 0.97)
]


SIZES = [(1366, 768), (1600, 900), (800, 600)]


@pytest.mark.parametrize("size", SIZES, ids=lambda s: f"{s[0]}x{s[1]}")
def test_the_object_named_is_the_one_under_the_ring(make_window, size, qtbot):
    """At each window size, with the cursor over either eye: the bar names the object that the
    ring covers in the picture (found from the pixels, then looked up in an ID render)."""
    window = make_window(*size)
    window.load("showroom")
    window.wait_for_load()
    view, session = window.view, window.session
    assert view.devicePixelRatioF() == EXPECTED_RATIO
    ratio = view.devicePixelRatioF()
    scene = session.scene

    def press_at(pos: QPoint) -> np.ndarray:
        send_mouse(view, QMouseEvent.Type.MouseMove, pos)
        send_mouse(view, QMouseEvent.Type.MouseButtonPress, pos, Qt.MouseButton.LeftButton)
        shot = grab(window)
        send_mouse(view, QMouseEvent.Type.MouseButtonRelease, pos, Qt.MouseButton.LeftButton)
        return shot

    base = press_at(QPoint(2, 2))  # the disc in the top-left corners, away from the grid
    ex, ey, pair_w, eye_h = _eyes_in(base)
    eye_w = pair_w // 2
    assert 0.8 <= eye_w / eye_h <= 1.0  # a headset's shape at every size
    walker = session.walker
    session.camera.set_pose(walker.position, walker.yaw_deg, walker.pitch_deg)
    view.makeCurrent()
    try:
        ids = view.renderer.object_ids(FrameInput(session.camera.eyes(eye_w, eye_h)))
    finally:
        view.doneCurrent()
    checked = 0
    for n, (u, v) in enumerate(GRID):
        eye = n % 2  # the cursor over the left eye, then over the right one
        x = (ex + (eye + u) * eye_w) / ratio
        y = (ey + v * eye_h) / ratio
        shot = press_at(QPoint(round(x), round(y)))
        named = session.gazed_object()
        window.eval_bar.refresh()
        assert (named or "-") in window.eval_bar.labels["gazed"].text()
        under = []
        for e, (cx, cy) in enumerate(_ring_centres(shot, base)):
            # The ring is drawn under the cursor in both eyes.
            assert abs(cx - (ex + (e + u) * eye_w)) < 2.0 and abs(cy - (ey + v * eye_h)) < 2.0
            under.append(_id_at(ids[e], cx - ex - e * eye_w, cy - ey))
        if None in under or under[0] != under[1]:
            continue  # an object's edge: either answer could be right
        checked += 1
        expected = scene.meshes[under[0]].name if under[0] >= 0 else None
        assert named == expected, (size, u, v, eye, named, expected)
    # With the fixed 640x720 eye, 1 to 3 of these points name the wrong object at each
    # size (the letterboxed eye is 0.8 to 1.0 wide, 640x720 is 0.89).
    assert checked >= 20, f"only {checked} unambiguous points"


def test_the_gaze_is_right_at_a_device_pixel_ratio_of_2(tmp_path):
    """The same check in a window scaled by 2 (QT_SCALE_FACTOR): the cursor is in logical
    pixels, the picture and the gaze ray in device pixels."""
    env = dict(os.environ, QT_SCALE_FACTOR="2", VRPREVIEW_TEST_RATIO="2")
    test = f"{Path(__file__).relative_to(ROOT)}::test_the_object_named_is_the_one_under_the_ring"
    result = subprocess.run(
        [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", f"{test}[800x600]"],
        cwd=ROOT,
        env=env,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert result.returncode == 0, result.stdout[-3000:] + result.stderr[-2000:]
    assert "1 passed" in result.stdout


def test_evaluation_mode_fits_a_laptop_screen_and_never_grows(make_window, qtbot):
    window = make_window(1366, 768)
    assert not window.normal_mode and window.dock.isVisible()
    assert window.size().width() == 1366 and window.size().height() == 768
    for i in range(window.tabs.count()):  # every tab: the window keeps its size
        window.tabs.setCurrentIndex(i)
        _pump(window)
        assert isinstance(window.tabs.widget(i), QScrollArea), window.tabs.tabText(i)
        assert (window.width(), window.height()) == (1366, 768), window.tabs.tabText(i)
    # A long name in the bar is cut, not widening the window.
    window.session.scene.meshes[0].name = "a very long object name " * 20
    window.session.gazed = 0
    window.eval_bar.refresh()
    _pump(window)
    assert (window.width(), window.height()) == (1366, 768)
    # The eyes keep a headset's shape, letterboxed in the view.
    shot = grab(window)
    x, y, w, h = _eyes_in(shot)
    assert 0.79 <= (w / 2) / h <= 1.0 and y > 10  # bars above and below, no narrow slices
    assert shot[: y - 1].max() == 0 and shot[y + h + 1 :].max() == 0
    # A 640x400 request is honoured; the panels scroll instead of pushing the window.
    window.resize(640, 400)
    _pump(window)
    assert (window.width(), window.height()) == (640, 400)
    window.tabs.setCurrentIndex(window.tabs.indexOf(window.panel))
    _pump(window)
    page = window.tabs.currentWidget()
    assert page.verticalScrollBar().maximum() > 0  # the Settings tab scrolls
    assert window.view.width() >= 320 and window.view.height() >= 180
    for i in range(window.tabs.count()):
        window.tabs.setCurrentIndex(i)
        _pump(window)
        assert (window.width(), window.height()) == (640, 400), window.tabs.tabText(i)


def test_letterboxed_eyes_look_as_the_reference(make_window, compare_reference):
    """A view too tall for two headset eyes: bars above and below, each eye 0.8 wide per unit
    height, the checker quad centred in each."""
    window = make_window(900, 700)
    window.view.setFixedSize(480, 400)
    _pump(window)
    shot = grab(window)
    assert shot.shape == (400, 480, 3)
    assert _eyes_in(shot) == (0, 50, 480, 300)
    compare_reference("window_letterbox_480x400", shot, max_mean=1.0, max_frac=0.003)
    # The screenshot (F12) is the eyes without the bars.
    saved = window.save_screenshot()
    img = qimage_to_array(QImage(str(saved)))
    assert img.shape == (300, 480, 3)
    assert np.abs(img.astype(int) - shot[50:350].astype(int)).mean() < 0.5


def test_panels_beside_or_below_and_back_from_the_view_menu(make_window, qtbot):
    window = make_window(1366, 768)
    view_menu = next(a.menu() for a in window.menuBar().actions() if a.text() == "&View")
    texts = [a.text() for a in view_menu.actions()]
    assert "&Panels" in texts and window.panels_action.shortcut().toString() == "Ctrl+Shift+D"
    assert window.dock_side_actions["right"].isChecked()
    window.dock_side_actions["bottom"].trigger()
    _pump(window)
    assert window.dockWidgetArea(window.dock) == Qt.DockWidgetArea.BottomDockWidgetArea
    assert window.dock_side_actions["bottom"].isChecked()
    assert window.dock.y() > window.view.y() + window.view.height() - 5  # below the view
    assert window.view.width() > 1300  # the eyes get the whole width
    shot = grab(window)
    x, y, w, h = _eyes_in(shot)
    assert 0.8 <= (w / 2) / h <= 1.0 and x > 10  # bars beside now
    window.resize(640, 400)  # below, too, the window can be made small
    _pump(window)
    assert (window.width(), window.height()) == (640, 400)
    window.resize(1366, 768)
    _pump(window)
    # Closed with its title bar's button, the dock comes back from View > Panels.
    window.dock.close()
    _pump(window)
    assert not window.dock.isVisible() and not window.panels_action.isChecked()
    window.panels_action.trigger()
    _pump(window)
    assert window.dock.isVisible()
    # The same with the keys, from the view.
    window.activateWindow()
    qtbot.waitUntil(window.isActiveWindow, timeout=5000)
    window.view.setFocus()
    ctrl_shift = Qt.KeyboardModifier.ControlModifier | Qt.KeyboardModifier.ShiftModifier
    qtbot.keyClick(window.view, Qt.Key.Key_D, ctrl_shift)
    assert not window.dock.isVisible()
    qtbot.keyClick(window.view, Qt.Key.Key_D, ctrl_shift)
    assert window.dock.isVisible()
    assert not window.view._keys  # D, taken by the shortcut, does not walk sideways
    # Closed, then Tab twice (normal mode and back): it stays closed, as left.
    window.dock.close()
    window.set_normal_mode(True)
    window.set_normal_mode(False)
    assert not window.dock.isVisible()
    # From normal mode the Panels shortcut goes back to evaluation mode with the panels.
    window.set_normal_mode(True)
    window.panels_action.trigger()
    _pump(window)
    assert not window.normal_mode and window.dock.isVisible() and window.menuBar().isVisible()


def test_tab_toggles_the_mode_only_in_the_view(make_window, qtbot):
    window = make_window(1366, 768)
    window.activateWindow()
    qtbot.waitUntil(lambda: QApplication.focusWidget() is window.view, timeout=5000)  # walks
    window.tabs.setCurrentWidget(window.tabs.widget(0))
    first = window.tcr_panel.findChildren(QCheckBox)[0]
    first.setFocus()
    qtbot.waitUntil(first.hasFocus, timeout=2000)
    qtbot.keyClick(first, Qt.Key.Key_Tab)
    assert not window.normal_mode  # the mode stays ...
    moved_to = QApplication.focusWidget()
    assert moved_to is not first and moved_to is not window.view  # ... the focus moves on
    assert window.dock.isAncestorOf(moved_to)
    qtbot.keyClick(window.view, Qt.Key.Key_Tab)
    assert window.normal_mode
    qtbot.keyClick(window.view, Qt.Key.Key_Tab)
    assert not window.normal_mode
    assert "Tab" in window.mode_action.text()  # the menu entry for the mode stays


def test_the_window_remembers_its_geometry_panels_and_files(make_window, scenes_dir, monkeypatch):
    duck = scenes_dir / "gltf-samples" / "Duck" / "glTF-Binary" / "Duck.glb"
    first = make_window(1000, 700)
    first.move(40, 30)
    first.dock_side_actions["bottom"].trigger()
    first.load(str(duck))
    first.wait_for_load()
    assert first.session.scene.name == "Duck"
    first.close()

    again = make_window(1366, 768)  # a new run: where and how the last one was left
    assert again.restored_geometry
    assert (again.width(), again.height()) == (1000, 700)
    assert again.dockWidgetArea(again.dock) == Qt.DockWidgetArea.BottomDockWidgetArea
    assert again.dock_side_actions["bottom"].isChecked()
    again._refresh_recent()
    recent = [a for a in again.recent_menu.actions() if a.isEnabled()]
    assert [a.text() for a in recent] == ["&1 Duck.glb"]
    seen = []
    monkeypatch.setattr(
        QFileDialog, "getOpenFileName", lambda *a, **k: (seen.append(a[2]), ("", ""))[1]
    )
    again.open_dialog()
    assert seen == [str(duck.resolve().parent)]  # File > Open starts in the last folder
    recent[0].trigger()
    again.wait_for_load()
    assert again.session.scene.name == "Duck"
    again.close()

    # The command without --scene opens the last scene.
    started = open_main_window(None, Settings())
    try:
        started.wait_for_load()
        assert started.session.scene.name == "Duck"
    finally:
        started.close()


def test_recent_files_keep_the_ten_newest(make_window, tmp_path, monkeypatch):
    for i in range(12):
        f = tmp_path / f"model{i:02d}.glb"
        f.write_bytes(b"")
        window_state.remember_opened(str(f))
    window_state.remember_opened(str(tmp_path / "model03.glb"))  # opened again: first
    window = make_window(800, 600)
    window._refresh_recent()
    names = [a.text().split(" ", 1)[1] for a in window.recent_menu.actions()]
    assert names == ["model03.glb"] + [f"model{i:02d}.glb" for i in (11, 10, 9, 8, 7, 6, 5, 4, 2)]
    (tmp_path / "model11.glb").unlink()  # gone: picked, it says so and leaves the list
    shown = []
    monkeypatch.setattr(QMessageBox, "critical", lambda *a, **k: shown.append(a))
    window.recent_menu.actions()[1].trigger()
    window.wait_for_load()
    assert len(shown) == 1 and "model11.glb" in shown[0][2]
    window._refresh_recent()
    assert not any("model11" in a.text() for a in window.recent_menu.actions())
    assert len(window.recent_menu.actions()) == 9


def test_the_readme_picture_is_the_window_at_1366x768(qtbot, tmp_path):
    """``python -m ui.window_shot`` (the README's picture): the whole window in evaluation mode
    on the showroom, eyes letterboxed beside the panels."""
    from ui.window_shot import shoot

    out = tmp_path / "window.png"
    window = shoot(out, (1366, 768))
    qtbot.addWidget(window)
    try:
        img = qimage_to_array(QImage(str(out)))
        assert img.shape == (768, 1366, 3)
        assert window.dock.isVisible() and not window.normal_mode
        assert window.session.scene.name == "showroom"
        view = grab(window)
        x, y, w, h = _eyes_in(view)
        assert 0.79 <= (w / 2) / h <= 1.0
    finally:
        window.close()


@pytest.mark.parametrize(
    "view, eyes",
    [
        ((480, 270), (0, 0, 240, 270)),  # 16:9 halves are 0.89: filled
        ((1000, 700), (0, 37, 500, 625)),  # too tall: bars above and below
        ((1366, 400), (283, 0, 400, 400)),  # too wide: bars beside
    ],
)
def test_eye_layout(view, eyes):
    layout = window_state.eye_layout(*view)
    assert layout.pair_rect()[:2] == eyes[:2] and (layout.eye_width, layout.eye_height) == eyes[2:]
    # The cursor's (u, v) is the same over either eye, and maps back to where it was.
    for eye in (0, 1):
        x, y = layout.from_eye(eye, 0.25, 0.75)
        assert layout.to_eye(x, y) == pytest.approx((0.25, 0.75))


def test_the_command_without_a_scene_opens_the_last_one(monkeypatch):
    """``vrpreview`` alone hands the window no scene (it opens the last one, see
    ``test_the_window_remembers_its_geometry_panels_and_files``); ``--scene`` still wins."""
    from app.lab import cli

    monkeypatch.setenv("DISPLAY", os.environ.get("DISPLAY") or ":0")
    asked: list = []
    assert cli.main([], lambda scene, settings, path: asked.append(scene) or 0) == 0
    assert cli.main(["--scene", "corridor"], lambda s, *_: asked.append(s) or 0) == 0
    assert asked == [None, "corridor"]


def test_a_damaged_preferences_file_gives_a_first_run(make_window):
    config = config_dir()
    config.mkdir(parents=True, exist_ok=True)
    (config / "vrpreview.ini").write_text(
        "[window]\ngeometry=hello\nstate=42\n[files]\nrecent=7\n"
        "last_scene=/nowhere/gone.glb\nlast_folder=/nowhere\n",
        encoding="utf-8",
    )
    window = make_window(800, 600)
    assert not window.restored_geometry and (window.width(), window.height()) == (800, 600)
    assert window.dock.isVisible()
    assert [a.text() for a in window.recent_menu.actions()] == ["(no files opened yet)"]
    assert window_state.last_scene() == "showroom"
    assert window_state.last_folder() == str(Path.home())


def test_the_app_has_the_projects_icon(qapp):
    from ui.main_window import app_icon, create_app

    app = create_app()
    sizes = {s.width() for s in app_icon().availableSizes()}
    assert {48, 128, 256} <= sizes
    assert not app.windowIcon().isNull()
    assert app.desktopFileName() == "vrpreview"
