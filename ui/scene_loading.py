"""Loading a scene in the main window: a worker thread behind a progress dialog.

The dialog appears once a load has taken 0.3 s, has Cancel, and stays until the first frame is
drawn (the upload and the first frame run on the UI thread after the worker is done); a file
that cannot be loaded gives an error dialog and the current scene stays. A mixin of
:class:`ui.main_window.MainWindow`, which owns the state it uses (``_loader``, ``_load_poll``,
``_loading``, the view, the session, the log panel).
"""

from __future__ import annotations

import concurrent.futures
import logging
import threading
import time
from dataclasses import dataclass
from pathlib import Path

from PyQt6.QtCore import Qt
from PyQt6.QtWidgets import QApplication, QFileDialog, QProgressDialog

from app import scenes
from app.ambient import probe_for
from app.loaders import SUPPORTED_EXTENSIONS, LoadOptions, SceneLoadError
from app.paths import CameraPath
from app.progress import LoadCancelled, Progress
from app.raycast import RayCaster
from app.scene import Scene
from render.texture_stream import prepare_textures
from ui import window_state

log = logging.getLogger(__name__)


class SceneLoading:
    """File > Open, drops, Recent files and the Samples menu all end in :meth:`load`."""

    def open_dialog(self) -> None:
        patterns = " ".join(f"*{e}" for e in SUPPORTED_EXTENSIONS)
        path, _ = QFileDialog.getOpenFileName(
            self, "Open scene", window_state.last_folder(), f"Scenes ({patterns});;All files (*)"
        )
        if path:
            self.load(path)

    def load(self, name_or_path: str) -> None:
        """Load on a worker thread behind a progress dialog with Cancel (shown after 0.3 s)."""
        if self._loading is not None:
            return
        dialog = QProgressDialog(f"Loading {Path(name_or_path).name}…", "Cancel", 0, 1000, self)
        dialog.setWindowTitle("Loading scene")
        dialog.setWindowModality(Qt.WindowModality.WindowModal)
        dialog.setAutoClose(False)
        dialog.setAutoReset(False)
        dialog.setMinimumDuration(1 << 30)  # shown by _check_load once the load takes 0.3 s
        report = _LatestProgress()
        progress = Progress(report, threading.Event())
        dialog.canceled.connect(progress.cancel.set)
        options = LoadOptions.from_settings(self.settings.scene)
        estimate = bool(self.settings.render.ambient_estimate)
        daylight = estimate and bool(self.settings.sky.enabled)
        future = self._loader.submit(
            _load_with_session, name_or_path, options, progress, estimate, daylight
        )
        self._loading = _Loading(future, name_or_path, dialog, report, progress, time.monotonic())
        QApplication.setOverrideCursor(Qt.CursorShape.BusyCursor)  # at once, before the dialog
        self.view.set_busy(True)
        self._load_poll.start(30)

    def cancel_load(self) -> None:
        """Stop the load in progress (the Cancel button); the current scene stays."""
        if self._loading is not None:
            self._loading.progress.cancel.set()

    def wait_for_load(self, timeout: float = 60.0) -> None:
        """Block (processing events) until the current load finished (tests and scripts)."""
        end = time.monotonic() + timeout
        while self._loading is not None and time.monotonic() < end:
            QApplication.processEvents()
            time.sleep(0.01)
        QApplication.processEvents()

    def _check_load(self) -> None:
        loading = self._loading
        if loading is None:
            return
        if not loading.future.done():
            if loading.dialog.wasCanceled():
                loading.progress.cancel.set()
            fraction, text = loading.report.latest
            if time.monotonic() - loading.started > _SHOW_PROGRESS_AFTER_S:
                if not loading.dialog.isVisible() and not loading.progress.cancel.is_set():
                    loading.dialog.show()
                loading.dialog.setLabelText(
                    f"Loading {Path(loading.name).name}…\n{text}"
                    if not loading.progress.cancel.is_set()
                    else "Cancelling…"
                )
                loading.dialog.setValue(int(1000 * fraction))
            return
        self._loading = None
        self._load_poll.stop()
        try:
            self._finish_load(loading)
        finally:
            self._end_busy(loading)

    def _end_busy(self, loading: _Loading) -> None:
        """The dialog goes and the cursor comes back, once per load."""
        if loading.ended:
            return
        loading.ended = True
        loading.dialog.reset()
        loading.dialog.hide()
        loading.dialog.deleteLater()
        QApplication.restoreOverrideCursor()
        self.view.set_busy(False)

    def _finish_load(self, loading: _Loading) -> None:
        """The worker is done: show the scene (or the error). The upload to the graphics card
        and the first frame run here on the UI thread, so the dialog stays up through them: a
        load is busy until its first frame is on screen."""
        name = loading.name
        try:
            failed = loading.future.exception() is not None
        except concurrent.futures.CancelledError:
            failed = True
        if failed:
            self._end_busy(loading)  # the dialog goes before any message box
        try:
            scene, session_path = loading.future.result()
        except LoadCancelled:
            self.statusBar().showMessage(f"Loading {Path(name).name} cancelled", 8000)
            return
        except (SceneLoadError, OSError, ValueError) as exc:
            if Path(name).suffix and not Path(name).is_file():
                window_state.forget_recent(name)  # gone: no longer offered in File > Recent
            self.show_error("Cannot open scene", str(exc))
            return
        except Exception as exc:  # noqa: BLE001 - any loader bug: report it, keep running
            log.exception("loading %s failed", name)
            self.show_error("Cannot open scene", f"{name}: unexpected error: {exc}")
            return
        dialog = loading.dialog
        if dialog.isVisible() or time.monotonic() - loading.started > _SHOW_PROGRESS_AFTER_S:
            dialog.setLabelText(f"Showing {Path(name).name}…")
            dialog.setValue(dialog.maximum())
            dialog.setCancelButton(None)  # too late to cancel: the scene is ready
            dialog.show()
            dialog.repaint()  # painted now: the UI thread is busy until the first frame
        self.session.set_scene(scene, session_path)
        exposure_note = self._expose_for_light()  # before the first frame is drawn
        self.view.set_scene(scene)
        window_state.remember_opened(name)
        self._refresh_recent()
        # Upload and draw the first frame now, under the dialog: grabFramebuffer() always renders
        # (repaint() may be deferred by Qt until after the dialog has gone).
        self.view.grabFramebuffer()
        self._update_title()
        self._refresh_viewpoints()
        note = f"Loaded {scene.name}: {scene.triangle_count:,} triangles"
        if exposure_note:
            note += f"; {exposure_note}"
        if scene.warnings:
            note += f" ({len(scene.warnings)} warnings: View > Log and warnings, Ctrl+L)"
            for w in scene.warnings:
                log.warning("%s: %s", scene.name, w)
        self._note_warnings(scene)
        self.statusBar().showMessage(note, 8000)

    def _note_warnings(self, scene: Scene) -> None:
        """The scene's load warnings go to the log panel and the status bar's link."""
        self.log_panel.set_scene_warnings(scene.name, scene.warnings)
        self.warnings_link.set_count(len(scene.warnings))


_SHOW_PROGRESS_AFTER_S = 0.3


class _LatestProgress:
    """The load's last report, written by the worker and read by the UI thread's poll (one
    tuple assignment: atomic under the GIL)."""

    def __init__(self) -> None:
        self.latest: tuple[float, str] = (0.0, "")

    def __call__(self, fraction: float, text: str) -> None:
        self.latest = (fraction, text)


@dataclass
class _Loading:
    future: concurrent.futures.Future
    name: str
    dialog: QProgressDialog
    report: _LatestProgress
    progress: Progress
    started: float
    ended: bool = False  # the dialog and the busy cursor are gone


def _load_with_session(
    name: str,
    options: LoadOptions,
    progress: Progress,
    estimate: bool = False,
    daylight: bool = False,
) -> tuple[Scene, CameraPath]:
    scene = scenes.resolve(name, options, progress.span(0.0, 0.85))
    # Texture pyramids are CPU work: built here, so the UI thread only uploads them.
    prepare_textures(scene.textures, progress.span(0.85, 0.95))
    if estimate:  # the ambient estimate's scene part, here and not in a frame
        progress.span(0.95, 1.0).report(0.0, "Estimating the light between surfaces")
        try:
            probe = probe_for(
                scene, scene.ray_caster if isinstance(scene.ray_caster, RayCaster) else None
            )
            if daylight:  # the sky seen where the probe's rays land (else at the first frame)
                probe.hit_open()
        except Exception:  # noqa: BLE001 - the renderer tries again (and reports) at the frame
            log.exception("ambient estimate for %s failed", name)
    return scene, scenes.default_path(scene)
