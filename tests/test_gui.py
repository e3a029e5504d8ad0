"""The real window under a virtual X server, driven with pytest-qt; we look at its pixels."""

from __future__ import annotations

import json

import numpy as np
import pytest
from PyQt6.QtCore import QPoint, QPointF, Qt
from PyQt6.QtGui import QImage, QMouseEvent
from PyQt6.QtWidgets import QApplication, QMessageBox

from app.settings import Settings
from render.offscreen import OffscreenHost
from tests.test_render import checker_scene
from ui.main_window import MainWindow

VIEW_W, VIEW_H = 480, 270


def qimage_to_array(img: QImage) -> np.ndarray:
    img = img.convertToFormat(QImage.Format.Format_RGB888)
    ptr = img.constBits()
    ptr.setsize(img.sizeInBytes())
    rows = np.frombuffer(ptr, np.uint8).reshape(img.height(), img.bytesPerLine())
    return rows[:, : img.width() * 3].reshape(img.height(), img.width(), 3).copy()


@pytest.fixture
def window(qtbot):
    settings = Settings()
    settings.render.overlay = False  # fps text changes every run; the picture must not
    w = MainWindow(settings, checker_scene())
    qtbot.addWidget(w)
    w.view.setFixedSize(VIEW_W, VIEW_H)
    w.show()
    qtbot.waitExposed(w)
    qtbot.waitUntil(lambda: w.view.renderer is not None, timeout=10000)
    yield w
    w.close()


def grab(w: MainWindow) -> np.ndarray:
    return qimage_to_array(w.view.grabFramebuffer())


def send_mouse(view, kind, pos: QPoint, button=Qt.MouseButton.NoButton):
    buttons = button if kind != QMouseEvent.Type.MouseButtonRelease else Qt.MouseButton.NoButton
    p = QPointF(pos)
    ev = QMouseEvent(kind, p, view.mapToGlobal(p), button, buttons, Qt.KeyboardModifier.NoModifier)
    QApplication.sendEvent(view, ev)


def test_window_shows_the_same_picture_as_the_headless_host(window, compare_reference):
    shot = grab(window)
    assert shot.shape == (VIEW_H, VIEW_W, 3)
    ratio = window.view.devicePixelRatioF()
    host = OffscreenHost(int(VIEW_W * ratio), int(VIEW_H * ratio), window.settings)
    try:
        host.set_scene(window.session.scene)
        host.set_text_image(None)
        headless = host.draw(window.session.frame_input(*host.eye_size))
    finally:
        host.close()
    # One renderer, two hosts: the same frame must give the same pixels.
    assert np.abs(shot.astype(int) - headless.astype(int)).mean() < 0.5
    compare_reference("gui_checker_480x270", shot, max_mean=1.0, max_frac=0.003)


def test_tab_toggles_evaluation_and_normal_mode(window, qtbot):
    assert not window.normal_mode and window.dock.isVisible()
    assert window.statusBar().isVisible()
    qtbot.keyClick(window.view, Qt.Key.Key_Tab)
    assert window.normal_mode
    assert not window.dock.isVisible() and not window.statusBar().isVisible()
    assert not window.menuBar().isVisible()
    qtbot.keyClick(window.view, Qt.Key.Key_Tab)
    assert not window.normal_mode and window.dock.isVisible()


def test_cursor_is_the_gaze_and_a_held_button_fixes_it(window, qtbot):
    view = window.view
    gaze = window.session.gaze
    # The right eye's viewport: the same normalised point as in the left eye.
    pos = QPoint(VIEW_W // 2 + VIEW_W // 8, VIEW_H // 4)
    send_mouse(view, QMouseEvent.Type.MouseMove, pos)
    assert gaze.state.u == pytest.approx(0.25, abs=0.01)
    assert gaze.state.v == pytest.approx(0.25, abs=0.01)
    assert not gaze.state.fixed
    send_mouse(view, QMouseEvent.Type.MouseButtonPress, pos, Qt.MouseButton.LeftButton)
    assert gaze.state.fixed and window.session.state in (2, 3)
    shot = grab(window)
    # The fixed-gaze marker (filled orange disc) is drawn at the cursor in both eyes.
    for x in (VIEW_W // 8, VIEW_W // 2 + VIEW_W // 8):
        r, g, b = shot[VIEW_H // 4, x].astype(int)
        assert r > 200 and 60 < g < 150 and b < 80, (x, r, g, b)
    send_mouse(view, QMouseEvent.Type.MouseButtonRelease, pos, Qt.MouseButton.LeftButton)
    assert not gaze.state.fixed


def test_bad_file_gives_an_error_dialog_and_the_scene_stays(window, tmp_path, monkeypatch):
    shown = []
    monkeypatch.setattr(QMessageBox, "critical", lambda *a, **k: shown.append(a))
    bad = tmp_path / "broken.glb"
    bad.write_bytes(b"glTF\x02\x00\x00\x00garbage" * 10)
    before = window.session.scene
    window.load(str(bad))
    window.wait_for_load()
    assert len(shown) == 1 and "broken.glb" in shown[0][2]
    assert window.session.scene is before
    assert grab(window).max() > 100  # still rendering


def test_open_a_model_file_replaces_the_scene(window, scenes_dir):
    window.load(str(scenes_dir / "gltf-samples" / "Duck" / "glTF-Binary" / "Duck.glb"))
    window.wait_for_load()
    assert window.session.scene.name == "Duck"
    assert "Duck" in window.windowTitle()
    shot = grab(window)
    assert shot.std() > 10  # a model is visible, not a flat background


def test_screenshot_and_viewpoint_are_saved(window, tmp_path):
    path = window.save_screenshot()
    assert path is not None and path.exists()
    img = QImage(str(path))
    assert (img.width(), img.height()) == (VIEW_W, VIEW_H)
    window.save_viewpoint("by the quad")
    window.session.walker.place((5.0, 1.6, 5.0), 45.0)
    vp_actions = [a for a in window.viewpoint_menu.actions() if a.text() == "by the quad"]
    assert vp_actions
    vp_actions[0].trigger()
    np.testing.assert_allclose(window.session.walker.position, [0.0, 1.6, 0.0], atol=1e-9)


def test_damaged_saved_viewpoints_are_left_out_and_the_good_one_still_works(window):
    """viewpoints.json edited by hand or cut short: a bad entry is left out of the menu (no
    error escapes the load or the menu's slot) and the good one still moves the viewer."""
    window.save_viewpoint("good")
    path = window._viewpoints_file()
    saved = json.loads(path.read_text(encoding="utf-8"))
    mine = saved[window.session.scene.name]
    mine["no position"] = {"yaw_deg": 10.0}
    mine["short"] = {"position": [1.0, 2.0]}
    mine["words"] = {"position": ["a", "b", "c"]}
    mine["not finite"] = {"position": [1.0, float("nan"), 0.0]}
    mine["not a dict"] = [1, 2, 3]
    path.write_text(json.dumps(saved), encoding="utf-8")
    window._refresh_viewpoints()
    names = [a.text() for a in window.viewpoint_menu.actions()[2:]]
    assert names == ["good"]
    window.session.walker.place((5.0, 1.6, 5.0), 45.0)
    window.viewpoint_menu.actions()[2].trigger()
    np.testing.assert_allclose(window.session.walker.position, [0.0, 1.6, 0.0], atol=1e-9)
    # A file whose scene entry is not a table at all gives an empty list, no error.
    path.write_text(json.dumps({window.session.scene.name: [1, 2]}), encoding="utf-8")
    window._refresh_viewpoints()
    assert window.viewpoint_menu.actions()[2:] == []


def test_tcr_panel_toggles_and_presets_change_the_model_and_the_picture(window, qtbot):
    panel, s, session = window.tcr_panel, window.settings, window.session
    s.render.refine = "off"  # at rest refinement shows the finest levels: TCR's own picture here
    # The quad (2 m away: level 1 by distance) fills the left eye's middle; a point inside its
    # white quadrant, beside where the gaze marker will be.
    white = (VIEW_H // 2 + 30, VIEW_W // 4 + 30)

    def shot_after(level: int) -> np.ndarray:
        qtbot.waitUntil(lambda: session.levels == [level], timeout=5000)
        return grab(window)

    # TCR's light term l reads how bright the picture shows the room: with automatic
    # exposure (adapted) that is the Brightness alone (a fixed exposure shows this brightly
    # lit quad 3 EV above 18% grey: l would stay 0 at 50%).
    mode = window.panel.editors["render.exposure_mode"]
    mode.setCurrentIndex(mode.findData("auto"))
    assert s.render.exposure_mode == "auto"
    before = grab(window)
    panel.enabled.setChecked(True)
    panel.tint.setChecked(True)
    assert s.tcr.enabled and s.tcr.tint and s.tcr.preset == "ergonomics"
    tinted = shot_after(1)
    assert np.abs(tinted.astype(int) - before.astype(int)).mean() > 10
    r, g, b = tinted[white].astype(int)
    assert b > r + 40, (r, g, b)  # level 1's legend colour is blue

    # Psychology: the held gaze on the quad takes one level off (1 -> 0: not tinted).
    panel.preset.setCurrentIndex(panel.preset.findData("psychology"))
    assert s.tcr.preset == "psychology"
    assert [panel.terms[t].isChecked() for t in "dvgl"] == [True, False, True, True]
    pos = QPoint(VIEW_W // 4, VIEW_H // 2)
    send_mouse(window.view, QMouseEvent.Type.MouseButtonPress, pos, Qt.MouseButton.LeftButton)
    gazed = shot_after(0)
    r, g, b = gazed[white].astype(int)
    assert abs(b - r) < 30, (r, g, b)  # the white quadrant, untinted
    # Ergonomics ignores the gaze: back to level 1.
    panel.preset.setCurrentIndex(panel.preset.findData("ergonomics"))
    shot_after(1)
    send_mouse(window.view, QMouseEvent.Type.MouseButtonRelease, pos, Qt.MouseButton.LeftButton)

    # Editing a term of a preset makes a custom set; Brightness (the Settings tab's one
    # control) feeds l (how bright the picture shows the quad) and darkens the scene.
    panel.terms["v"].setChecked(False)
    assert s.tcr.preset == "custom" and not s.tcr.use_v and s.tcr.use_d and s.tcr.use_l
    assert panel.preset.currentData() == "custom"
    panel.tint.setChecked(False)
    bright = shot_after(1)
    brightness = window.panel.editors["render.brightness"]
    brightness.setValue(50)  # 50%, half the brightness: l = +1
    assert s.render.brightness == pytest.approx(0.5)
    dim = shot_after(2)  # = n, the 4x4 texture's coarsest level
    assert np.abs(dim.astype(int) - bright.astype(int)).mean() > 5
    panel.enabled.setChecked(False)
    assert not s.tcr.enabled
    dim_full = shot_after(0)
    brightness.setValue(100)
    bright_full = shot_after(0)
    quad = (slice(VIEW_H // 2 - 50, VIEW_H // 2 + 50), slice(VIEW_W // 4 - 50, VIEW_W // 4 + 50))
    # Half the light: the quad is darker by 15+ of 255 levels everywhere on average (the tone
    # curve's shoulder keeps it from halving on screen).
    assert dim_full[quad].mean() < bright_full[quad].mean() - 15


def test_cps_panel_drives_the_model_the_picture_and_shows_live_statistics(window, qtbot):
    panel, s = window.cps_panel, window.settings
    window.load("showroom")
    window.wait_for_load()
    full = grab(window)
    # One control for the mitigation modes: CPS in the graphics pipeline.
    index = next(
        i for i in range(panel.mode.count()) if panel.mode.itemData(i) == ("cps", "fragment")
    )
    panel.mode.setCurrentIndex(index)
    assert s.cps.mode == "cps" and s.render.lighting == "fragment"
    assert not panel.dispatch.isEnabled()  # dispatch only means something in compute
    qtbot.waitUntil(lambda: len(window.session.edge) == 2, timeout=5000)
    coarse = grab(window)
    assert np.abs(coarse.astype(int) - full.astype(int)).mean() > 0.5
    panel.visualize.setChecked(True)
    assert s.cps.visualize
    painted = grab(window).astype(int)
    # Coarse levels are painted blue, cyan, green, yellow or red: much more colourful.
    chroma = lambda img: (img.max(axis=2) - img.min(axis=2)).mean()  # noqa: E731
    assert chroma(painted) > chroma(coarse.astype(int)) + 20
    panel.max_level.setCurrentIndex(panel.max_level.findData(2))
    assert s.cps.max_level == 2
    grab(window)  # a frame with the new maximum
    panel.poll()
    stats = window._cps_stats()
    shares = stats["level_share"]
    assert abs(sum(shares) - 1.0) < 1e-6 and shares[3:] == [0.0, 0.0, 0.0]
    assert 0 < stats["shaded_samples"] < stats["full_samples"]
    assert "%" in panel.share_label.text() and panel.samples_label.text() != "-"
    assert len(stats["edge_caps"]) == 2 and all(len(e) == 3 for e in stats["edge_caps"])
    # The compute pipeline enables the dispatch choice; "none" restores the full-rate picture.
    index = next(
        i for i in range(panel.mode.count()) if panel.mode.itemData(i) == ("cps", "compute")
    )
    panel.mode.setCurrentIndex(index)
    assert s.render.lighting == "compute" and panel.dispatch.isEnabled()
    panel.visualize.setChecked(False)
    panel.mode.setCurrentIndex(0)
    assert (s.cps.mode, s.render.lighting) == ("none", "fragment")
    assert np.abs(grab(window).astype(int) - full.astype(int)).mean() < 0.5


def test_photon_panel_traces_in_the_background_and_adds_indirect_light(window, qtbot):
    s, panel = window.settings, window.photon_panel
    window.load("showroom")
    window.wait_for_load()
    panel.refresh_stats()
    assert panel.labels["status"].text().startswith("off (the scene does not ask")
    assert window.photon_cache.map is None  # nothing traced for a scene that does not ask
    # Against the fixed ambient light the bounce comes on top of (the estimate from the lamps
    # is about as bright as the photon map: app/ambient.py, docs/reference_flip.md).
    s.render.ambient_estimate = False
    before = grab(window)
    s.photons.indirect = "gather"  # the paper's gather: its grid, reuse and overlay
    panel.controls.editors["photons.photons"].setValue(4096)
    panel.controls.editors["photons.radius_m"].setValue(0.4)
    enabled = panel.controls.editors["photons.enabled"]
    enabled.setCurrentIndex(enabled.findData("on"))
    assert s.photons.enabled == "on" and s.photons.photons == 4096
    qtbot.waitUntil(lambda: window.photon_cache.map is not None, timeout=20000)
    window._check_photons()  # hand the map to the view now rather than on the next tick
    after = grab(window)
    assert after.astype(float).mean() > before.astype(float).mean() + 1.0  # bounced light
    panel.refresh_stats()
    assert panel.labels["status"].text().startswith("on (turned on)")
    assert panel.labels["stored"].text() not in ("", "-")
    assert "%" in panel.labels["reuse"].text()
    assert "cells" in panel.labels["grid"].text()
    # The reuse overlay paints the right eye green (reused) and red (gathered).
    panel.controls.editors["photons.show_reuse"].setChecked(True)
    painted = grab(window).astype(int)
    right = painted[:, painted.shape[1] // 2 :]
    assert (right[..., 1] - right[..., 0]).mean() > (
        after[:, after.shape[1] // 2 :, 1].astype(int) - after[:, after.shape[1] // 2 :, 0]
    ).mean()
    # A radius that needs too many cells: a clear message, the window keeps drawing.
    panel.controls.editors["photons.show_reuse"].setChecked(False)
    panel.controls.editors["photons.radius_m"].setValue(0.001)
    grab(window)
    panel.refresh_stats()
    assert "cells" in panel.labels["status"].text()
    enabled.setCurrentIndex(enabled.findData("off"))
    qtbot.waitUntil(lambda: window._photons_shown is None, timeout=5000)
    assert np.abs(grab(window).astype(int) - before.astype(int)).mean() < 0.5


def test_standing_still_the_bounced_light_grows_smoother_in_the_background(window, qtbot):
    s, panel, service = window.settings, window.photon_panel, window.photon_cache
    window.load("showroom-gi")  # asks for indirect light; the precomputed method (default)
    window.wait_for_load()
    panel.controls.editors["photons.photons"].setValue(4096)
    panel.controls.editors["photons.refine_photons"].setValue(1 << 18)
    assert s.photons.refine_photons == 1 << 18
    qtbot.waitUntil(lambda: service.map is not None and service.refining, timeout=30000)
    first = service.traced
    assert first is not None and first.emitted == 4096
    assert "smoothing while you stand" in window._photon_stats()["status"]
    qtbot.waitUntil(lambda: service.map.emitted == 1 << 18 and not service.tracing, timeout=120000)
    window._check_photons()
    assert window._photons_shown is service.map  # the view shows the grown map
    grab(window)
    panel.refresh_stats()
    assert panel.labels["status"].text().startswith("on (")
    assert int(panel.labels["stored"].text().replace(",", "")) > 32 * len(first)
    assert not window.view.renderer.errors


def test_quality_panel_measures_against_full_quality_and_shows_a_heat_map(window, qtbot):
    s = window.settings
    s.render.refine = "off"  # at rest refinement draws full quality: CPS's error is measured
    window.load("showroom")
    window.wait_for_load()
    grab(window)
    same = window.measure_quality()  # default settings are full quality: no error
    assert same["frame"]["psnr_db"] == float("inf") and same["fovea_max_abs_diff"] == 0
    assert window.quality_panel.cells["frame", "psnr_db"].text() == "identical"
    plain = grab(window)
    s.cps.mode = "cps"
    window._setting_changed("cps.mode")
    qtbot.waitUntil(lambda: len(window.session.edge) == 2, timeout=5000)
    grab(window)
    report = window.measure_quality()
    assert report["fovea_max_abs_diff"] == 0  # full rate around the gaze
    assert report["periphery"]["flip"] > report["fovea"]["flip"]
    assert 10 < report["frame"]["psnr_db"] < 80
    assert window.quality_panel.cells["periphery", "flip"].text() not in ("-", "identical")
    assert window.quality_panel.heat.isChecked()
    shown = grab(window).astype(int)
    window.quality_panel.heat.setChecked(False)
    hidden = grab(window).astype(int)
    assert np.abs(shown - hidden).mean() > 1.0  # the heat map was drawn over the view
    assert hidden.shape == plain.shape
    assert not window.view.renderer.errors


def test_a_z_up_room_opens_upright_with_a_note(window, tmp_path):
    """A room saved with Z up (as 3ds Max, Rhino or a scanner may) opens in the window with
    the viewer standing inside it at eye height, and the log panel lists the note that it
    was turned upright."""
    from tests.test_spawn import CLASS_HI, CLASS_LO, _z_up, furnished_room, write_obj

    path = write_obj(tmp_path / "z_up.obj", _z_up(furnished_room(CLASS_LO, CLASS_HI, "room")))
    window.load(str(path))
    window.wait_for_load()
    assert window.session.scene.name == "z_up"
    x, y, z = window.session.walker.position
    assert y == pytest.approx(1.6, abs=0.05)  # standing on the floor, not on a wall
    assert CLASS_LO[0] < x < CLASS_HI[0] and CLASS_LO[2] < z < CLASS_HI[2]
    assert any("turned upright" in w for w in window.log_panel.scene_warnings)
    assert grab(window).std() > 10  # the room is drawn


def test_the_files_saved_views_are_in_the_viewpoints_menu(window, tmp_path):
    """A glTF with two cameras (views saved in Blender): the window starts at the first, and
    View > Viewpoints lists both; choosing the second goes there."""
    from tests.test_gltf_rules import _quat, _room_with_camera

    g = _room_with_camera(translation=[1.0, 1.6, 2.0], name="Entrance")
    g.doc["cameras"].append({"type": "perspective", "name": "Kitchen", "perspective": {}})
    g.node(camera=1, translation=[-2.0, 1.5, -1.0], rotation=_quat((0, 1, 0), 180.0).tolist())
    window.load(str(g.write(tmp_path)))
    window.wait_for_load()
    np.testing.assert_allclose(window.session.walker.position, [1.0, 1.6, 2.0], atol=1e-6)
    actions = {a.text(): a for a in window.viewpoint_menu.actions()}
    assert "Entrance (saved in the file)" in actions
    actions["Kitchen (saved in the file)"].trigger()
    np.testing.assert_allclose(window.session.walker.position, [-2.0, 1.5, -1.0], atol=1e-6)
    # A bad state behind the action (a camera gone NaN): the viewer stays where it is.
    from app.scene import Viewpoint

    nan = float("nan")
    window.session.scene.cameras.append(("Broken", Viewpoint((nan, nan, nan), nan, nan)))
    window._refresh_viewpoints()
    actions = {a.text(): a for a in window.viewpoint_menu.actions()}
    actions["Broken (saved in the file)"].trigger()
    np.testing.assert_allclose(window.session.walker.position, [-2.0, 1.5, -1.0], atol=1e-6)
    assert np.isfinite([window.session.walker.yaw_deg, window.session.walker.pitch_deg]).all()
    assert grab(window).std() > 10  # still drawing
