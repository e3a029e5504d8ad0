"""Saved viewpoints, path playback and path recording in the main window.

Viewpoints are kept per scene in ``viewpoints.json`` and recorded paths in ``paths/``, under
:func:`data_dir`. A mixin of :class:`ui.main_window.MainWindow` (its view, session, status bar
and View > Viewpoints menu).
"""

from __future__ import annotations

import json
import logging
import math
import os
import time
from pathlib import Path

from PyQt6.QtGui import QAction
from PyQt6.QtWidgets import QInputDialog

from app.fileio import atomic_write_json
from app.paths import CameraPath
from app.scene import Viewpoint

log = logging.getLogger(__name__)


def data_dir() -> Path:
    """Where screenshots, viewpoints and recordings go (VRPREVIEW_DATA overrides)."""
    base = os.environ.get("VRPREVIEW_DATA") or Path.home() / ".local" / "share" / "vrpreview"
    return Path(base)


def saved_viewpoint(entry: object) -> Viewpoint | None:
    """A viewpoints.json entry as a Viewpoint; None when it is not one (three finite
    coordinates, finite angles)."""
    if not isinstance(entry, dict):
        return None
    try:
        position = tuple(float(c) for c in entry["position"])
        yaw, pitch = float(entry.get("yaw_deg", 0.0)), float(entry.get("pitch_deg", 0.0))
    except (KeyError, TypeError, ValueError):
        return None
    if len(position) != 3 or not all(math.isfinite(v) for v in (*position, yaw, pitch)):
        return None
    return Viewpoint(position, yaw, pitch)  # type: ignore[arg-type]


class ViewpointActions:
    """Save a viewpoint, go to one, play the scene's path, record a new one."""

    def _viewpoints_file(self) -> Path:
        return data_dir() / "viewpoints.json"

    def _read_viewpoints(self) -> dict:
        try:
            doc = json.loads(self._viewpoints_file().read_text(encoding="utf-8"))
            return doc if isinstance(doc, dict) else {}
        except (OSError, json.JSONDecodeError):
            return {}

    def save_viewpoint(self, name: str | None = None) -> None:
        scene = self.session.scene
        if scene is None:
            return
        all_vp = self._read_viewpoints()
        mine = all_vp.setdefault(scene.name, {})
        if not name:
            name, ok = QInputDialog.getText(
                self, "Save viewpoint", "Name:", text=f"Viewpoint {len(mine) + 1}"
            )
            if not ok or not name:
                return
        w = self.session.walker
        mine[name] = {
            "position": [float(v) for v in w.position],
            "yaw_deg": w.yaw_deg,
            "pitch_deg": w.pitch_deg,
        }
        atomic_write_json(self._viewpoints_file(), all_vp)
        self._refresh_viewpoints()
        self.statusBar().showMessage(f"Viewpoint '{name}' saved", 5000)

    def _refresh_viewpoints(self) -> None:
        menu = self.viewpoint_menu
        for a in menu.actions()[2:]:
            menu.removeAction(a)
        scene = self.session.scene
        if scene is None:
            return
        for name, vp in scene.cameras:  # the views saved in the file (glTF cameras)
            a = QAction(f"{name} (saved in the file)", self)
            a.triggered.connect(lambda _=False, v=vp: self.go_to(v))
            menu.addAction(a)
        saved = self._read_viewpoints().get(scene.name, {})
        for name, entry in saved.items() if isinstance(saved, dict) else ():
            vp = saved_viewpoint(entry)
            if vp is None:  # a damaged entry in the file: left out, the others stay usable
                log.warning(
                    "viewpoint %r of %s in %s is unreadable",
                    name,
                    scene.name,
                    self._viewpoints_file(),
                )
                continue
            a = QAction(str(name), self)
            a.triggered.connect(lambda _=False, v=vp: self.go_to(v))
            menu.addAction(a)

    def go_to(self, vp: Viewpoint) -> None:
        self.view.playing = False
        self.session.walker.place(vp.position, vp.yaw_deg, vp.pitch_deg)

    def toggle_play(self) -> None:
        self.view.playing = not self.view.playing

    def toggle_recording(self) -> None:
        view = self.view
        if not view.is_recording:
            view.recording = []
            view.is_recording = True
            self.statusBar().showMessage("Recording path… (Ctrl+R stops)")
            return
        view.is_recording = False
        keys = view.recording
        if len(keys) < 2:
            return
        t0 = keys[0].t
        for k in keys:
            k.t -= t0
        name = time.strftime("path-%Y%m%d-%H%M%S.json")
        target = data_dir() / "paths" / name
        scene = self.session.scene
        CameraPath(keys, scene.name if scene else "").save(target)
        self.statusBar().showMessage(f"Path saved: {target} (replay: --path {target})", 10000)
