"""Changing scenes in the window: nothing of the old scene leaks into the new one, loads show
progress and can be cancelled, and a file that fails keeps the current scene."""

from __future__ import annotations

import logging
import time
from pathlib import Path

import numpy as np
import pytest
from PyQt6.QtWidgets import QApplication, QMessageBox, QPushButton

import app.placement
from app.scene import Material, Mesh, Scene, Viewpoint, vertex_normals
from app.session import Session
from app.settings import Settings
from ui.main_window import MainWindow

VIEW_W, VIEW_H = 320, 180


def box_obj(path: Path, count: int) -> Path:
    """``count`` 0.3 m boxes in a row, each its own material (so its own mesh), in a closed
    12 x 3 x 8 m room."""
    lines: list[str] = []
    base = 0

    def add_box(name: str, lo: np.ndarray, hi: np.ndarray, inward: bool) -> None:
        nonlocal base
        lines.append(f"o {name}")
        lines.append(f"usemtl {name}")  # a material each: trimesh makes one mesh per material
        corners = [
            (x, y, z) for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])
        ]
        lines.extend(f"v {x} {y} {z}" for x, y, z in corners)
        quads = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
        for a, b, c, d in quads:
            tri = [(a, b, c), (a, c, d)]
            for t in tri:
                t = t[::-1] if inward else t
                lines.append("f " + " ".join(str(base + i + 1) for i in t))
        base += 8

    add_box("room", np.array([-6.0, 0.0, -4.0]), np.array([6.0, 3.0, 4.0]), inward=True)
    for i in range(count):
        x = -5.0 + 10.0 * i / max(count - 1, 1)
        add_box(f"box{i}", np.array([x, 1.0, -3.5]), np.array([x + 0.15, 1.3, -3.2]), False)
    path.write_text(f"mtllib {path.stem}.mtl\n" + "\n".join(lines) + "\n")
    names = ["room"] + [f"box{i}" for i in range(count)]
    mtl = "".join(f"newmtl {n}\nKd 0.{3 + i % 6} 0.5 0.5\n" for i, n in enumerate(names))
    path.with_suffix(".mtl").write_text(mtl)
    return path


def two_mesh_scene() -> Scene:
    pos = np.array([[-1, 0, -2], [1, 0, -2], [0, 2, -2]], np.float32)
    idx = np.array([[0, 1, 2]], np.uint32)
    mesh = Mesh("tri", pos, vertex_normals(pos, idx), np.zeros((3, 2), np.float32), idx)
    return Scene("one", [mesh], [Material("m")], spawn=Viewpoint((0.0, 1.0, 0.0)))


@pytest.fixture
def window(qtbot):
    settings = Settings()
    settings.render.overlay = False
    w = MainWindow(settings)
    qtbot.addWidget(w)
    w.view.setFixedSize(VIEW_W, VIEW_H)
    w.show()
    qtbot.waitExposed(w)
    qtbot.waitUntil(lambda: w.view.renderer is not None, timeout=10000)
    yield w
    w.close()


def test_a_gazed_index_from_the_previous_scene_names_nothing():
    session = Session(Settings())
    many = Scene(
        "many",
        [two_mesh_scene().meshes[0] for _ in range(8)],
        [Material("m")],
    )
    session.set_scene(many)
    session.gazed = 7  # the last tick's answer in the old scene
    session.set_scene(two_mesh_scene())
    assert session.gazed is None and session.levels is None
    assert session.gazed_object() is None
    session.gazed = 5  # and an out-of-range index never raises
    assert session.gazed_object() is None


def test_switching_scenes_fifty_times_logs_no_error(window, qtbot, tmp_path, scenes_dir, caplog):
    many = box_obj(tmp_path / "many.obj", 40)
    few = scenes_dir / "gltf-samples" / "Duck" / "glTF-Binary" / "Duck.glb"
    shown = []
    window.show_error = lambda *a: shown.append(a)  # type: ignore[method-assign]
    caplog.set_level(logging.WARNING)
    names = []
    gazed_in_many: list[int] = []
    for i in range(50):
        window.load(str(many if i % 2 == 0 else few))
        window.wait_for_load()
        # the panels poll the gazed object before and after the new scene's first frames
        for _ in range(2):
            window.tcr_panel.poll()
            window.eval_bar.refresh()
            window.view.repaint()
            QApplication.processEvents()
        gazed = window.session.gazed_object()
        scene = window.session.scene
        if scene.name == "many" and window.session.gazed is not None:
            gazed_in_many.append(window.session.gazed)
        assert gazed is None or gazed in {m.name for m in scene.meshes}
        names.append(scene.name)
    assert names[:2] == ["many", "Duck"] and names[-1] == "Duck"
    # the gaze met an index Duck lacks (trimesh lists the walls, authored first, last)
    assert gazed_in_many and max(gazed_in_many) >= 1
    assert not shown
    assert not [r for r in caplog.records if r.levelno >= logging.ERROR]


def test_a_slow_load_shows_progress_and_can_be_cancelled(window, qtbot, tmp_path, monkeypatch):
    original = app.placement.safe_find_spawn

    def slow_spawn(*args, **kwargs):
        time.sleep(1.5)  # a big room: the spawn search takes a while
        return original(*args, **kwargs)

    monkeypatch.setattr(app.placement, "safe_find_spawn", slow_spawn)
    shown = []
    monkeypatch.setattr(QMessageBox, "critical", lambda *a, **k: shown.append(a))
    before = window.session.scene
    window.load(str(box_obj(tmp_path / "slow.obj", 4)))
    dialog = window._loading.dialog
    qtbot.waitUntil(dialog.isVisible, timeout=5000)
    qtbot.waitUntil(lambda: "Finding where to stand" in dialog.labelText(), timeout=5000)
    assert 0 < dialog.value() < dialog.maximum()
    dialog.findChild(QPushButton).click()  # the Cancel button
    window.wait_for_load()
    assert window.session.scene is before  # nothing half-loaded replaced it
    assert "cancelled" in window.statusBar().currentMessage()
    assert not shown  # cancelling is not an error
    window.load(str(box_obj(tmp_path / "slow.obj", 4)))  # and the next load still works
    window.wait_for_load()
    assert window.session.scene.name == "slow"


def test_typing_a_bad_unit_scale_is_refused_in_the_status_line(window):
    combo = window.panel.editors["scene.unit_scale"]
    combo.setEditText("-1")  # a designer's typo
    combo.lineEdit().editingFinished.emit()
    assert window.settings.scene.unit_scale == "auto"
    assert "unit scale" in window.panel.status.text()
    combo.setEditText("centimetres (0.01)")  # an entry's label means its value
    combo.lineEdit().editingFinished.emit()
    assert window.settings.scene.unit_scale == "0.01"


def test_the_ambient_estimate_is_found_while_loading_not_in_the_first_frame(
    window, qtbot, monkeypatch
):
    """The estimate's scene part (1.6 s on a 380k-triangle room) is found on the loader's
    worker thread, under the progress dialog; the first frame reads it."""
    import threading

    import app.ambient

    threads: list[str] = []
    real = app.ambient.AmbientProbe.__init__

    def probe(self, *a, **k):
        threads.append(threading.current_thread().name)
        real(self, *a, **k)

    monkeypatch.setattr(app.ambient.AmbientProbe, "__init__", probe)
    window.load("showroom")
    window.wait_for_load()
    window.view.grabFramebuffer()  # a frame with the scene: the renderer asks for the estimate
    scene = window.session.scene
    assert scene is not None and scene.ambient_probe is not None
    assert threads and threading.main_thread().name not in threads  # only on the worker
    assert window.view.renderer.ambient_term() > 0.0  # from the probe found while loading
    assert len(threads) == 1
    # With the estimate off nothing is found, neither while loading nor in a frame.
    threads.clear()
    window.settings.set("render.ambient_estimate", False)
    window.load("corridor")
    window.wait_for_load()
    window.view.grabFramebuffer()
    assert not threads and window.session.scene.ambient_probe is None


def test_with_daylight_the_sky_at_the_probes_hits_is_found_while_loading(window, monkeypatch):
    """With daylight on, the sky seen where the probe's rays land (0.4-0.7 s on a real room)
    is found on the loader's worker thread too, not in the first daylit frame."""
    import threading

    import app.ambient

    threads: list[str] = []
    real = app.ambient.AmbientProbe._open_at_hits

    def spy(self, *a, **k):
        threads.append(threading.current_thread().name)
        return real(self, *a, **k)

    monkeypatch.setattr(app.ambient.AmbientProbe, "_open_at_hits", spy)
    window.settings.set("sky.enabled", True)
    window.load("showroom")
    window.wait_for_load()
    window.view.grabFramebuffer()
    assert len(threads) == 1 and threading.main_thread().name not in threads
    assert window.view.renderer.ambient_term() > 0.0
