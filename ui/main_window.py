"""Main window: the stereo view, panels, the evaluation bar, files, screenshots, viewpoints.

Evaluation mode shows panels and the evaluation bar; normal mode shows only the scene (Tab
toggles while the view has the keyboard focus; elsewhere Tab moves between controls). The
panels scroll, so the window fits a laptop screen; they sit beside or below the view (View
menu), and the window remembers its geometry, the panels' layout, the last scene and the recent
files (``ui.window_state``). Loading a scene (``ui.scene_loading``) runs on a worker thread
behind a progress dialog; a file that cannot be loaded gives an error dialog and the current
scene stays. Viewpoints and recorded paths are in ``ui.viewpoints``.
"""

from __future__ import annotations

import concurrent.futures
import logging
import sys
import time
from importlib import resources
from pathlib import Path

from PyQt6.QtCore import QBuffer, QByteArray, QEvent, QIODevice, QObject, QRect, QSize, Qt, QTimer
from PyQt6.QtGui import QAction, QActionGroup, QIcon, QKeySequence, QSurfaceFormat
from PyQt6.QtWidgets import (
    QApplication,
    QDockWidget,
    QFileDialog,
    QFrame,
    QMainWindow,
    QMessageBox,
    QScrollArea,
    QSizePolicy,
    QTabWidget,
    QWidget,
)

from app.exposure import unfit_opening_exposure
from app.fileio import atomic_write_bytes
from app.indirect import PhotonService, refine_target, wanted
from app.paths import CameraPath
from app.scene import Scene
from app.session import Session
from app.settings import Settings, SettingsError
from app.tcr import phase_name, terms_from_settings
from ui import guard, window_state
from ui.controls import ControlsDialog
from ui.cps_panel import CpsPanel
from ui.frame_graph import frame_graph_dock
from ui.gl_view import StereoView, default_format
from ui.governor_panel import GovernorPanel
from ui.log_panel import LogPanel, WarningsLink
from ui.overlay import KeysOverlay
from ui.panels import EvaluationBar, SettingsPanel
from ui.photon_panel import PhotonPanel
from ui.presenter import Presenter
from ui.quality_panel import QualityPanel
from ui.samples_menu import fill_samples_menu
from ui.scene_loading import SceneLoading, _Loading
from ui.sky_panel import SkyPanel
from ui.survey_runner import open_session_dialog
from ui.tcr_panel import TcrPanel
from ui.viewpoints import ViewpointActions, data_dir

log = logging.getLogger(__name__)


class MainWindow(SceneLoading, ViewpointActions, QMainWindow):
    def __init__(
        self,
        settings: Settings | None = None,
        scene: Scene | None = None,
        path: CameraPath | None = None,
    ) -> None:
        super().__init__()
        self.settings = settings or Settings()
        self.session = Session(self.settings)
        # A study session's conditions are its protocol's settings, exactly: the window adjusts
        # nothing of them (ui.survey_runner sets this while a session runs).
        self.settings_as_given = False
        if scene is not None:
            self.session.set_scene(scene, path)
        self.setWindowTitle("VR Preview")
        self.view = StereoView(self.session)
        self.view.gl_failed.connect(self._gl_failed)
        self.setCentralWidget(self.view)
        self.setAcceptDrops(True)
        self._loader = concurrent.futures.ThreadPoolExecutor(max_workers=1)
        self._load_poll = QTimer(self)
        self._load_poll.timeout.connect(self._check_load)
        self._loading: _Loading | None = None
        self.normal_mode = False
        # Photon maps are traced on the service's worker thread; the view keeps rendering meanwhile.
        self.photon_cache = PhotonService(sky=lambda: self.settings.sky)
        self._photons_shown: object = None
        self._photon_timer = QTimer(self)
        self._photon_timer.timeout.connect(self._check_photons)
        self._photon_timer.start(100)

        self.panel = SettingsPanel(
            self.settings, ("stereo", "render", "navigation", "gaze", "scene")
        )
        self.tcr_panel = TcrPanel(self.session, on_change=self._setting_changed)
        self.cps_panel = CpsPanel(self.settings, self._cps_stats, on_change=self._setting_changed)
        self.photon_panel = PhotonPanel(
            self.settings, self._photon_stats, on_change=self._setting_changed
        )
        self.panel.on_change = self._setting_changed
        self.tabs = tabs = QTabWidget()
        tabs.setUsesScrollButtons(True)  # many tabs in a narrow dock: arrows, not a wider dock
        self.add_panel(self.tcr_panel, "TCR")
        self.add_panel(self.cps_panel, "CPS")
        self.add_panel(self.photon_panel, "Photons")
        self.governor_panel = GovernorPanel(self.view.governor_lines)
        self.add_panel(self.governor_panel, "Frame rate")
        self.quality_panel = QualityPanel(
            lambda: self.view.measure_quality(self._photons_shown), self.view.show_heat_map
        )
        self.add_panel(self.quality_panel, "Quality")
        self.view.heat_map_cleared.connect(
            self.quality_panel.heat_cleared, Qt.ConnectionType.QueuedConnection
        )
        self.sky_panel = SkyPanel(self.settings, on_change=self._setting_changed)
        self.add_panel(self.sky_panel, "Sun and sky")
        self.add_panel(self.panel, "Settings")
        self.dock = QDockWidget("Evaluation", self)
        self.dock.setObjectName("evaluation-panels")
        self.dock.setWidget(tabs)
        self.dock.setAllowedAreas(
            Qt.DockWidgetArea.RightDockWidgetArea
            | Qt.DockWidgetArea.BottomDockWidgetArea
            | Qt.DockWidgetArea.LeftDockWidgetArea
        )
        self.addDockWidget(Qt.DockWidgetArea.RightDockWidgetArea, self.dock)
        self._dock_wanted = True  # shown again when evaluation mode comes back
        self._eval_state = None  # the panels' layout in evaluation mode, kept in normal mode
        self.eval_bar = EvaluationBar(self._poll)
        # Long texts (a gazed object's name) are cut, never widen the window.
        self.eval_bar.setSizePolicy(QSizePolicy.Policy.Ignored, QSizePolicy.Policy.Preferred)
        self.statusBar().addPermanentWidget(self.eval_bar, 1)
        self.frame_dock = frame_graph_dock(
            self, self.view.frame_log, self.settings, self.view.display_hz
        )  # F3
        self.log_panel = LogPanel(self)
        self.log_panel.attach()
        self.warnings_link = WarningsLink(self.log_panel.open_panel)
        self.statusBar().addPermanentWidget(self.warnings_link)
        self.controls_dialog: ControlsDialog | None = None
        self._build_menus()
        self._update_title()
        if scene is not None:
            self._note_warnings(scene)
        self.keys_overlay = KeysOverlay(self.view)
        self.keys_overlay.show_if_first_run()
        QApplication.instance().installEventFilter(self)
        self._scroll_panels()
        self._expose_for_light()  # daylight on the command line, or a file's own lamps
        self.restored_geometry = self.restore_window()
        self.view.setFocus()  # the keys walk from the start (the view takes no Tab focus)

    def add_panel(self, panel: QWidget, title: str) -> None:
        """A tab in the panels' dock; its page scrolls when the dock is smaller than it."""
        self.tabs.addTab(_scrolling(panel), title)

    def _scroll_panels(self) -> None:
        """Every tab page scrolls, also one added with ``self.tabs.addTab`` directly."""
        for i in range(self.tabs.count()):
            page = self.tabs.widget(i)
            if isinstance(page, QScrollArea):
                continue
            title = self.tabs.tabText(i)
            self.tabs.removeTab(i)
            self.tabs.insertTab(i, _scrolling(page), title)

    # -- menus ---------------------------------------------------------------------------------
    def _build_menus(self) -> None:
        def action(menu, text: str, slot, shortcut: str | None = None) -> QAction:
            a = QAction(text, self)
            if shortcut:
                a.setShortcut(QKeySequence(shortcut))
            a.triggered.connect(slot)
            menu.addAction(a)
            self.addAction(a)  # shortcuts keep working while the menu bar is hidden
            return a

        bar = self.menuBar()
        f = bar.addMenu("&File")
        action(f, "&Open scene…", self.open_dialog, "Ctrl+O")
        self.recent_menu = f.addMenu("&Recent files")
        self.recent_menu.aboutToShow.connect(self._refresh_recent)
        self._refresh_recent()
        f.addSeparator()
        action(f, "Save &screenshot", self.save_screenshot, "F12")
        action(f, "Measure &quality against full quality", self.measure_quality, "F9")
        action(f, "Heat map of the error on/off", self.toggle_heat_map, "F8")
        action(f, "Save settings preset…", self.save_preset)
        action(f, "Load settings preset…", self.load_preset)
        f.addSeparator()
        action(f, "&Quit", self.close, "Ctrl+Q")
        self.samples_menu = bar.addMenu("S&amples")
        fill_samples_menu(self.samples_menu, self, self.load)
        v = bar.addMenu("&View")
        self.mode_action = action(v, "Normal mode (scene only)\tTab", self.toggle_mode)
        self.panels_action = self.dock.toggleViewAction()
        self.panels_action.setText("&Panels")
        self.panels_action.setShortcut(QKeySequence("Ctrl+Shift+D"))
        self.panels_action.triggered.connect(self._panels_toggled)
        v.addAction(self.panels_action)
        self.addAction(self.panels_action)
        sides = QActionGroup(self)
        sides.setExclusionPolicy(QActionGroup.ExclusionPolicy.ExclusiveOptional)
        self.dock_side_actions: dict[str, QAction] = {}
        for side, text in (
            ("right", "Panels beside the view"),
            ("bottom", "Panels below the view"),
        ):
            a = action(v, text, lambda _=False, s=side: self.set_dock_side(s))
            a.setCheckable(True)
            sides.addAction(a)
            self.dock_side_actions[side] = a
        self.dock.dockLocationChanged.connect(self._dock_moved)
        self._dock_moved(self.dockWidgetArea(self.dock))
        self.full_screen_action = action(v, "Full screen", self.toggle_full_screen, "F11")
        v.addSeparator()
        action(v, "Play walkthrough", self.toggle_play, "P")
        action(v, "Record path", self.toggle_recording, "Ctrl+R")
        v.addAction(self.frame_dock.toggleViewAction())
        self.presenter = Presenter(
            self.view, self.settings, self._setting_changed, self.statusBar().showMessage, self.load
        )
        self.presenter.add_actions(v, self)  # F5 presenter mode, M mitigation, [ ] divider
        action(v, "Log and warnings…", self.log_panel.open_panel, "Ctrl+L")
        self.viewpoint_menu = bar.addMenu("View&points")
        action(self.viewpoint_menu, "Save viewpoint…", self.save_viewpoint, "Ctrl+B")
        self.viewpoint_menu.addSeparator()
        self._refresh_viewpoints()
        study = bar.addMenu("&Study")
        action(study, "Run a session…", lambda _=False: open_session_dialog(self))
        h = bar.addMenu("&Help")
        action(h, "Getting around (first-run help)", self.keys_overlay_toggle, "F1")
        action(h, "Controls: every key…", self.show_controls)
        action(h, "Log and warnings…", self.log_panel.open_panel)

    def keys_overlay_toggle(self) -> None:
        self.keys_overlay.toggle()

    def show_controls(self) -> ControlsDialog:
        """Help > Controls: every key, built from the window's actions when opened."""
        if self.controls_dialog is not None:
            self.controls_dialog.close()
        self.controls_dialog = ControlsDialog(self)
        self.controls_dialog.show()
        return self.controls_dialog

    def toggle_heat_map(self) -> None:
        """F8: the heat map on or off, measuring first when there is none for this view."""
        if self.quality_panel.report.get("heat") is not None:
            self.quality_panel.toggle_heat()
        else:
            self.measure_quality()

    # -- modes ---------------------------------------------------------------------------------
    def eventFilter(self, obj: QObject, event: QEvent) -> bool:
        # Tab toggles the mode only in the view; in the panels it moves between controls.
        if (
            event.type() == QEvent.Type.KeyPress
            and obj is self.view
            and event.key() == Qt.Key.Key_Tab
        ):
            self.toggle_mode()
            return True
        return super().eventFilter(obj, event)

    def toggle_mode(self) -> None:
        self.set_normal_mode(not self.normal_mode)

    def set_normal_mode(self, normal: bool) -> None:
        if normal and not self.normal_mode:
            self._dock_wanted = not self.dock.isHidden()
            self._eval_state = self.saveState()
        self.normal_mode = normal
        for w in (self.statusBar(), self.menuBar()):
            w.setVisible(not normal)
        self.dock.setVisible(not normal and self._dock_wanted)
        self.view.session.settings.render.overlay = not normal
        if normal:
            self.keys_overlay.dismiss()  # scene only (a study's exposure, too)
        self.view.setFocus()

    def _panels_toggled(self, shown: bool) -> None:
        """View > Panels (Ctrl+Shift+D): showing them from normal mode goes back to evaluation."""
        self._dock_wanted = shown
        if shown and self.normal_mode:
            self.set_normal_mode(False)

    def set_dock_side(self, side: str) -> None:
        """The panels beside ("right") or below ("bottom") the view."""
        area = {
            "right": Qt.DockWidgetArea.RightDockWidgetArea,
            "bottom": Qt.DockWidgetArea.BottomDockWidgetArea,
        }[side]
        if self.dock.isFloating():
            self.dock.setFloating(False)
        self.addDockWidget(area, self.dock)
        self._dock_moved(area)
        if side == "bottom":  # a third of the height; the eyes keep the rest
            self.resizeDocks([self.dock], [self.height() // 3], Qt.Orientation.Vertical)
        else:
            self.resizeDocks([self.dock], [min(400, self.width() // 3)], Qt.Orientation.Horizontal)
        if not self.normal_mode:
            self._dock_wanted = True
            self.dock.show()

    def _dock_moved(self, area) -> None:
        self.dock_side_actions["right"].setChecked(area == Qt.DockWidgetArea.RightDockWidgetArea)
        self.dock_side_actions["bottom"].setChecked(area == Qt.DockWidgetArea.BottomDockWidgetArea)

    def toggle_full_screen(self) -> None:
        if self.isFullScreen():
            self.showNormal()
        else:
            self.showFullScreen()

    # -- what the window remembers -------------------------------------------------------------
    def restore_window(self) -> bool:
        """Geometry and panel layout of the last run; False on a first run."""
        p = window_state.prefs()
        geometry, state = p.value("window/geometry"), p.value("window/state")
        # A hand-edited or foreign file may hold anything there: only Qt's own bytes count.
        restored = isinstance(geometry, QByteArray) and self.restoreGeometry(geometry)
        if isinstance(state, QByteArray) and self.restoreState(state):
            self._dock_wanted = not self.dock.isHidden()
        self._dock_moved(self.dockWidgetArea(self.dock))
        return restored

    def save_window(self) -> None:
        p = window_state.prefs()
        p.setValue("window/geometry", self.saveGeometry())
        state = self._eval_state if self.normal_mode and self._eval_state is not None else None
        p.setValue("window/state", state if state is not None else self.saveState())

    def fit_to_screen(self) -> None:
        """A first run's size: 1600x900, or 90% of a smaller screen."""
        screen = self.screen() or QApplication.primaryScreen()
        size = QSize(1600, 900)
        if screen is not None:
            free = screen.availableGeometry()
            size = size.boundedTo(QSize(int(free.width() * 0.9), int(free.height() * 0.9)))
        self.resize_to(size.width(), size.height())

    def resize_to(self, width: int, height: int) -> None:
        """The window at ``width`` x ``height``, the panels beside the view a third of it wide
        (400 px at most)."""
        self.resize(width, height)
        self.resizeDocks([self.dock], [min(400, width // 3)], Qt.Orientation.Horizontal)

    def _refresh_recent(self) -> None:
        menu = self.recent_menu
        menu.clear()
        files = window_state.recent_files()
        for i, name in enumerate(files, 1):
            a = QAction(f"&{i % 10} {Path(name).name}", self)
            a.setToolTip(name)
            a.setStatusTip(name)
            a.triggered.connect(lambda _=False, n=name: self.load(n))
            menu.addAction(a)
        if not files:
            empty = menu.addAction("(no files opened yet)")
            empty.setEnabled(False)

    def show_error(self, title: str, text: str) -> None:
        QMessageBox.critical(self, title, text)

    def _gl_failed(self, message: str) -> None:
        self.show_error("OpenGL 4.3 is not available", message)

    def _update_title(self) -> None:
        scene = self.session.scene
        self.setWindowTitle(f"VR Preview — {scene.name}" if scene else "VR Preview")

    def dragEnterEvent(self, event) -> None:
        urls = event.mimeData().urls()
        if urls and urls[0].isLocalFile():
            event.acceptProposedAction()

    def dropEvent(self, event) -> None:
        urls = event.mimeData().urls()
        if urls and urls[0].isLocalFile():
            self.load(urls[0].toLocalFile())

    # -- files ---------------------------------------------------------------------------------
    def save_screenshot(self) -> Path | None:
        """PNG of both eyes as shown (without the letterbox bars), into the data folder; the
        path goes to the status bar."""
        image = self.view.grabFramebuffer().copy(QRect(*self.view.eye_layout().pair_rect()))
        buf = QBuffer()
        buf.open(QIODevice.OpenModeFlag.WriteOnly)
        image.save(buf, "PNG")
        name = time.strftime("screenshot-%Y%m%d-%H%M%S.png")
        target = data_dir() / "screenshots" / name
        try:
            atomic_write_bytes(target, bytes(buf.data()))
        except OSError as exc:
            self.show_error("Cannot save screenshot", str(exc))
            return None
        self.statusBar().showMessage(f"Screenshot saved: {target}", 8000)
        return target

    def save_preset(self) -> None:
        path, _ = QFileDialog.getSaveFileName(
            self, "Save settings preset", str(data_dir() / "preset.json"), "JSON (*.json)"
        )
        if path:
            try:
                self.settings.save(path)
            except OSError as exc:
                self.show_error("Cannot save preset", str(exc))

    def load_preset(self) -> None:
        path, _ = QFileDialog.getOpenFileName(
            self, "Load settings preset", str(data_dir()), "JSON (*.json)"
        )
        if path:
            self.apply_preset(path)

    def apply_preset(self, path: str) -> None:
        try:
            loaded = Settings.load(path)
        except SettingsError as exc:
            self.show_error("Cannot load preset", str(exc))
            return
        for key in loaded.keys():  # in place: the session, renderer and panels share it
            self.settings.set(key, loaded.get(key))
        self._setting_changed("")

    def _setting_changed(self, key: str) -> None:
        """Keep the panels showing the one model, and redraw."""
        if key in ("sky.enabled", ""):  # the tab, or a preset
            self._expose_for_light()
        if key.startswith(("render.", "tcr.", "cps.", "photons.")) or not key:
            self.panel.refresh()
            self.tcr_panel.refresh()
            self.cps_panel.refresh()
            self.photon_panel.refresh()
        if key.startswith("photons.") or not key:
            self._check_photons()
        if key.startswith("cps."):
            self.session.edge = self.session.edge_caps()  # caps show at once, even when paused
        if key == "scene.unit_scale":
            self._reload_file()
        self.view.update()

    def _expose_for_light(self) -> str | None:
        """Daylight turned on (in the tab, on the command line or by a preset), or a model lit
        by its own lamps, at the fixed exposure a room opens with (made for the built-in
        scenes' lamps and the default lights): a sunlit room, or a bathroom under a 60 W
        bulb, showed as a white screen. The exposure turns automatic and the window says so
        (the Sun and sky tab; the load's note); a fixed exposure the user chose stays, and a
        study's conditions stay as its protocol gives them (``settings_as_given``). What it
        says, or None."""
        if self.settings_as_given:
            return None
        r, scene = self.settings.render, self.session.scene
        why = unfit_opening_exposure(
            r.exposure_mode,
            r.exposure_ev,
            self.settings.sky.enabled,
            scene is not None and scene.lamps_from_file,
        )
        if why is None:
            return None
        self.settings.set("render.exposure_mode", "auto")
        self.panel.refresh()
        fix = "(Settings, Exposure, to fix it again)"
        if why == "daylight":
            self.sky_panel.status.setText(f"Exposure set to automatic for daylight {fix}.")
            return None
        text = f"exposure set to automatic for the model's own lamps {fix}"
        log.info("%s: %s", scene.name if scene is not None else "", text)
        return text

    def _reload_file(self) -> None:
        """Load the open model file again (its units changed); built-in scenes stay as they are."""
        scene = self.session.scene
        if (
            scene is not None
            and scene.source not in ("", "built-in")
            and Path(scene.source).is_file()
        ):
            self.load(scene.source)

    def _cps_stats(self) -> dict:
        """Live CPS figures for the panel: the renderer's level shares and samples, and the
        session's edge-ray caps and distances."""
        stats = self.view.cps_stats()
        edge = self.session.edge
        if edge:
            stats["edge_caps"] = [[e.caps[s] for s in ("left", "right", "bottom")] for e in edge]
            stats["edge_distances"] = [
                [e.distances[s] for s in ("left", "right", "bottom")] for e in edge
            ]
        return stats

    def measure_quality(self) -> dict:
        """F9: the live frame against full quality; figures in the Quality tab, heat map over
        the view."""
        report = self.quality_panel.measure()
        if report:
            frame = report.get("frame") or {}
            self.statusBar().showMessage(
                f"Against full quality: FLIP {frame.get('flip', float('nan')):.3f}, "
                f"PSNR {frame.get('psnr_db', float('nan')):.1f} dB (Quality tab)",
                8000,
            )
        return report

    # -- photon mapping ------------------------------------------------------------------------
    def _check_photons(self) -> None:
        """Keep the view's photon map in step with the scene and the settings; the service
        traces on its worker thread and hands the map over when done."""
        # The map grows while the viewpoint rests (not while walking: the frames need the CPU).
        rest = not self.session.motion.viewpoint_moving
        current = self.photon_cache.poll(self.settings.photons, self.session.scene, rest)
        error = self.photon_cache.take_error()
        if error:
            self.show_error("Cannot trace photons", error)
        if current is not self._photons_shown:
            self._photons_shown = current
            self.view.set_photons(current)

    def _photon_stats(self) -> dict:
        scene, s = self.session.scene, self.settings.photons
        stats = self.view.photon_stats() if self._photons_shown is not None else {}
        if not wanted(s, scene):
            why = "turned off" if s.enabled == "off" else "the scene does not ask for it"
            stats["status"] = f"off ({why}; choose On above to add it)"
        elif self.photon_cache.refining and self.photon_cache.map is not None:
            paths = self.photon_cache.map.emitted
            stats["status"] = (
                f"on; smoothing while you stand: {paths:,} of {refine_target(s):,} photons"
            )
        elif self.photon_cache.tracing:
            stats["status"] = "tracing photons…"
            stats["tracing"] = self.photon_cache.progress
        elif stats.get("error"):
            stats["status"] = f"unavailable: {stats['error']}"
        elif self.photon_cache.failed(s, scene):
            stats["status"] = "tracing failed (see the log)"
        else:
            why = "turned on" if s.enabled == "on" else "the scene asks for it"
            stats["status"] = f"on ({why})"
        if self.photon_cache.map is not None and self._photons_shown is not None:
            stats["trace_ms"] = self.photon_cache.trace_ms
        return stats

    # -- statistics ----------------------------------------------------------------------------
    def _poll(self) -> dict:
        s = self.session
        scene = s.scene
        t = self.settings.tcr
        phase = phase_name(terms_from_settings(t)) if t.enabled else "TCR off"
        return {
            "state": s.state,
            "phase": phase,
            "fps": self.view.timer.fps,
            "gazed": s.gazed_object(),
            "resident_mb": self.view.texture_resident_bytes() / 1e6,
            "scene": scene_label(scene),
            "scene_tip": scene_tip(scene),
            "exposure": self.view.renderer.exposure_readout() if self.view.renderer else "",
        }

    def closeEvent(self, event) -> None:
        self.save_window()
        QApplication.instance().removeEventFilter(self)
        self.log_panel.detach()
        if self._loading is not None:  # closing mid-load: stop it, give the cursor back
            self._loading.progress.cancel.set()
            self._loading = None
            QApplication.restoreOverrideCursor()
        self.view.release_gl()
        self._loader.shutdown(wait=False, cancel_futures=True)
        self.photon_cache.close()
        super().closeEvent(event)


def scene_label(scene: Scene | None) -> str:
    """The status bar's scene: its name and the model's own triangle count."""
    return f"{scene.name} · {scene.model_triangle_count:,} triangles" if scene else ""


def scene_tip(scene: Scene | None) -> str:
    """The scene label's tooltip: where the model came from, and the triangles drawn after
    long edges were split when there are more."""
    if scene is None:
        return "The model shown, and how many triangles it is made of"
    tip = f"{scene.source or scene.name}: {scene.model_triangle_count:,} triangles in the model"
    if scene.triangle_count != scene.model_triangle_count:
        tip += (
            f"; {scene.triangle_count:,} drawn: long edges are split so that the light kept "
            "per point of a surface (the sky through a window) has points to land on"
        )
    return tip


def app_icon() -> QIcon:
    """The project's icon (assets/icons, drawn by packaging/make_icon.py) at every size."""
    icon = QIcon()
    folder = resources.files("assets") / "icons"
    for entry in sorted(folder.iterdir(), key=lambda e: e.name):
        if entry.name.endswith(".png"):
            with resources.as_file(entry) as png:
                icon.addFile(str(png))
    return icon


def create_app(argv: list[str] | None = None) -> QApplication:
    QSurfaceFormat.setDefaultFormat(default_format())
    app = QApplication.instance() or QApplication(argv or sys.argv[:1])
    app.setApplicationName("VR Preview")
    app.setDesktopFileName("vrpreview")  # the desktop entry (packaging/vrpreview.desktop)
    app.setWindowIcon(app_icon())
    guard.install()
    return app  # type: ignore[return-value]


def _scrolling(panel: QWidget) -> QScrollArea:
    """The panel in a scroll area (itself, when it is one already)."""
    if isinstance(panel, QScrollArea):
        return panel
    area = QScrollArea()
    area.setWidget(panel)
    area.setWidgetResizable(True)
    area.setFrameShape(QFrame.Shape.NoFrame)
    return area


def open_main_window(
    scene_name: str | None, settings: Settings, path: CameraPath | None = None
) -> MainWindow:
    """The window as the ``vrpreview`` command opens it: where it was last time (or fitted to
    the screen), on ``scene_name`` (None: the last scene; the showroom on a first run)."""
    window = MainWindow(settings)
    if not window.restored_geometry:
        window.fit_to_screen()
    window.show()
    window.load(scene_name or window_state.last_scene())
    if path is not None:
        window.wait_for_load()
        window.session.path = path
        window.view.playing = True
    return window


def run(scene_name: str | None, settings: Settings, path: CameraPath | None = None) -> int:
    app = create_app()
    _window = open_main_window(scene_name, settings, path)  # alive until the loop ends
    return app.exec()
