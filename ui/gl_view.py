"""The stereo view: a thin QOpenGLWidget that forwards to the shared renderer.

initializeGL/resizeGL/paintGL hand over to ``render.Renderer``; the widget only turns Qt input
into session state (keys -> walking, cursor -> gaze, right-drag -> looking) and draws into
``defaultFramebufferObject()`` at the device pixel ratio. The eyes keep a headset's shape
(``ui.window_state.eye_layout``: letterboxed when the view is far from it); the session's eye
size, the gaze ray and the cursor mapping all come from that one layout, in device pixels.
"""

from __future__ import annotations

import logging
import os
import time
from typing import TYPE_CHECKING

import moderngl
from PyQt6.QtCore import QPointF, Qt, QTimer, pyqtSignal
from PyQt6.QtGui import QKeyEvent, QMouseEvent, QSurfaceFormat
from PyQt6.QtOpenGLWidgets import QOpenGLWidget

from app.frame_log import FrameLog
from app.overlay_text import text_image, with_status
from app.scene import Scene
from app.session import Session
from app.stats import FrameTimer, overlay_lines
from render.context import GLUnavailableError, check
from render.renderer import Renderer
from ui.window_state import EyeLayout, eye_layout

if TYPE_CHECKING:
    from ui.presenter import Presenter

log = logging.getLogger(__name__)

MOVE_KEYS = {
    Qt.Key.Key_W: (1, 0, 0),
    Qt.Key.Key_Up: (1, 0, 0),
    Qt.Key.Key_S: (-1, 0, 0),
    Qt.Key.Key_Down: (-1, 0, 0),
    Qt.Key.Key_A: (0, -1, 0),
    Qt.Key.Key_D: (0, 1, 0),
    Qt.Key.Key_E: (0, 0, 1),
    Qt.Key.Key_Q: (0, 0, -1),
}
TURN_KEYS = {Qt.Key.Key_Left: 1.0, Qt.Key.Key_Right: -1.0}
TURN_DEG_S = 60.0
BUSY_FRAME_MS = 250  # the view's frame interval while a scene loads


def default_format() -> QSurfaceFormat:
    fmt = QSurfaceFormat()
    fmt.setVersion(4, 3)
    fmt.setProfile(QSurfaceFormat.OpenGLContextProfile.CoreProfile)
    fmt.setDepthBufferSize(24)
    fmt.setSwapInterval(0)  # measure the renderer, not the display's refresh
    return fmt


class StereoView(QOpenGLWidget):
    gl_failed = pyqtSignal(str)
    heat_map_cleared = pyqtSignal()  # the view, the gaze or a setting changed under it

    def __init__(self, session: Session, parent=None) -> None:
        super().__init__(parent)
        self.session = session
        self.renderer: Renderer | None = None
        self.ctx: moderngl.Context | None = None
        self.timer = FrameTimer()
        self.frame_log = FrameLog()  # the last seconds of frames, for the frame-time graph
        self._pending_scene: Scene | None = session.scene
        self._pending_photons: tuple | None = None  # (PhotonMap | None,) once set
        self._probe = None  # render.quality.QualityProbe, made on the first measurement
        self._heat_key: tuple | None = None  # the view the heat map measured (None: none)
        self.heat_map_shown = False
        self._keys: set[int] = set()
        self._last_tick = time.perf_counter()
        self._drag_from: QPointF | None = None
        self._text_at = 0.0
        self.status_line: str | None = None  # the refinement line last drawn in the overlay
        self.overlay_text: list[str] = []  # the overlay's lines as last drawn
        self.playing = False
        self._play_frame = 0
        self.recording: list = []
        self.is_recording = False
        self.presenter: Presenter | None = None  # draws the frame while presenting (F5)
        # Clicks give the view the keyboard; Tab in the panels passes it by (in the view, Tab
        # toggles the mode).
        self.setFocusPolicy(Qt.FocusPolicy.ClickFocus)
        self.setMouseTracking(True)
        self.setMinimumSize(320, 180)
        self._tick = QTimer(self)
        self._tick.timeout.connect(self._advance)
        self._tick.start(0)

    # -- GL forwarding -------------------------------------------------------------------------
    def initializeGL(self) -> None:
        try:
            self.ctx = check(moderngl.create_context())
            self.renderer = Renderer(self.ctx, self.session.settings)
        except (GLUnavailableError, moderngl.Error, Exception) as exc:  # noqa: BLE001
            log.error("OpenGL unavailable: %s", exc)
            self.renderer = None
            self.gl_failed.emit(str(exc))
            return
        if self._pending_scene is not None:
            self.renderer.set_scene(self._pending_scene, stream_in=True)
            self._pending_scene = None

    def paintGL(self) -> None:
        if self.renderer is None or self.ctx is None:
            return
        if self._pending_scene is not None:
            self.renderer.set_scene(self._pending_scene, stream_in=True)
            self._clear_heat_map()  # measured on the scene before
            self._pending_scene = None
        if self._pending_photons is not None:
            self.renderer.set_photons(self._pending_photons[0])
            self._pending_photons = None
        layout = self.eye_layout()
        fbo = self.ctx.detect_framebuffer(self.defaultFramebufferObject())
        fbo.viewport = (0, 0, layout.view_width, layout.view_height)
        fbo.clear(0.0, 0.0, 0.0, 1.0)  # the letterbox bars
        hz = self.display_hz()  # render.target_fps and render.refine "auto"
        self.session.display_hz = hz
        frame = self.session.frame_input(layout.eye_width, layout.eye_height)
        self._drop_stale_heat_map(frame)
        now = time.perf_counter()
        status = self.session.refinement.status_line()  # "refining 63%" while still
        # Redraw the statistics text at 4 Hz, not every frame (and when refinement starts/ends).
        if now - self._text_at > 0.25 or (status is None) != (self.status_line is None):
            self._text_at = now
            self.status_line = status
            lines = overlay_lines(
                self.timer.fps, self.renderer.pass_ms(), self.session.settings, frame.gaze_fixed
            )
            self.overlay_text = with_status(lines, status)
            self.renderer.overlay.set_text_image(text_image(self.overlay_text))
        # Automatic exposure adapts by the last frame's wall time (the headless hosts' fixed step).
        self.renderer.frame_dt = min(0.25, self.timer.times[-1]) if self.timer.times else 1 / 60
        self.renderer.display_hz = hz
        if self.presenter is not None and self.presenter.active:
            self.presenter.render(self.renderer, frame, fbo, layout.gl_origin)
        else:
            self.renderer.render(frame, fbo, layout.gl_origin)
        if self.renderer.refine_restarted:  # finer textures arrived: refine them from sample 0
            self.session.refinement.restart()
        self.session.exposure_state = self.renderer.exposure_state()  # TCR's l reads it
        self.timer.tick(now)
        self.frame_log.record(now, self.renderer.pass_ms())

    def display_hz(self) -> float | None:
        """The refresh rate of the screen showing the view, for ``render.target_fps = auto``
        (and ``render.refine = auto``: refinement only with a known rate).
        ``VRPREVIEW_DISPLAY_HZ`` overrides it (0: no display, fixed settings: the tests)."""
        forced = os.environ.get("VRPREVIEW_DISPLAY_HZ")
        if forced is not None:
            try:
                return float(forced) or None
            except ValueError:
                return None
        screen = self.screen()
        hz = screen.refreshRate() if screen is not None else 0.0
        return float(hz) if hz and hz > 0 else None

    def governor_lines(self) -> list[str]:
        """The frame-rate panel's words (app.governor.Governor.explain)."""
        if self.renderer is None:
            return ["Frame rate: no picture yet."]
        return self.renderer.governor.explain(self.session.settings)

    def resizeGL(self, w: int, h: int) -> None:
        self._update_eye_size()

    def resizeEvent(self, event) -> None:
        super().resizeEvent(event)
        self._update_eye_size()  # the gaze ray of the next tick already uses the new size

    def eye_layout(self) -> EyeLayout:
        """Where the eyes are drawn, in device pixels (the view's size times its pixel ratio)."""
        ratio = self.devicePixelRatioF()  # rounded as Qt sizes the framebuffer (half up)
        return eye_layout(int(self.width() * ratio + 0.5), int(self.height() * ratio + 0.5))

    def _update_eye_size(self) -> None:
        layout = self.eye_layout()
        self.session.eye_size = (layout.eye_width, layout.eye_height)

    def set_scene(self, scene: Scene) -> None:
        """Swap the scene; the GPU upload happens in the next paintGL (context current)."""
        self._pending_scene = scene
        self._play_frame = 0
        self.update()

    def set_photons(self, photons) -> None:
        """The photon map (or None) for the renderer; handed over in the next paintGL."""
        self._pending_photons = (photons,)
        self.update()

    def photon_stats(self) -> dict:
        if self.renderer is None:
            return {}
        self.makeCurrent()
        try:
            return self.renderer.photon_stats()
        finally:
            self.doneCurrent()

    def measure_quality(self, photons) -> dict:
        """Render the current frame at full quality and measure the live frame against it
        (see render.quality.QualityProbe); shows the heat map over the view."""
        if self.renderer is None or self.ctx is None or self.session.scene is None:
            return {}
        from render.quality import QualityProbe

        self.makeCurrent()
        try:
            if self._probe is None:
                self._probe = QualityProbe(self.ctx)
            layout = self.eye_layout()
            frame = self.session.frame_input(layout.eye_width, layout.eye_height)
            fov = self.session.camera.horizontal_fov_deg(layout.eye_width, layout.eye_height)
            report = self._probe.measure(self.renderer, self.session.scene, photons, frame, fov)
            self.renderer.overlay.set_heat_map(report["heat"])
            self._heat_key = self._view_key(frame) if report["heat"] is not None else None
            self.heat_map_shown = self._heat_key is not None
        finally:
            self.doneCurrent()
        self.update()
        return report

    def show_heat_map(self, rgba) -> None:
        """Show (an (h, w, 4) image of the view as it is now) or hide (None) the error heat
        map over the view; it goes away by itself once the view changes."""
        if self.renderer is None:
            return
        self.makeCurrent()
        try:
            self.renderer.overlay.set_heat_map(rgba)
        finally:
            self.doneCurrent()
        self.heat_map_shown = rgba is not None
        if rgba is not None and self._heat_key is None:
            layout = self.eye_layout()
            frame = self.session.frame_input(layout.eye_width, layout.eye_height)
            self._heat_key = self._view_key(frame)
        self.update()

    def set_busy(self, busy: bool) -> None:
        """While a load runs behind its window-modal dialog the view draws 4 frames a second,
        not as many as it can: the loader (and llvmpipe) get the CPU, the dialog stays lively."""
        self._tick.setInterval(BUSY_FRAME_MS if busy else 0)

    @property
    def busy(self) -> bool:
        return self._tick.interval() == BUSY_FRAME_MS

    def _view_key(self, frame) -> tuple:
        """Everything the measured picture depends on besides the scene: the pose, the gaze,
        the texture levels, the size and every setting."""
        walker = self.session.walker
        return (
            tuple(float(v) for v in walker.position),
            float(walker.yaw_deg),
            float(walker.pitch_deg),
            tuple(frame.gaze),
            bool(frame.gaze_fixed),
            None if frame.levels is None else tuple(frame.levels),
            self.eye_layout(),
            self.session.settings.to_dict(),
        )

    def _drop_stale_heat_map(self, frame) -> None:
        """In paintGL (context current): a heat map never outlives the view it measured (hidden
        or shown: one measured before a move is never shown after it)."""
        if self._heat_key is not None and self._view_key(frame) != self._heat_key:
            self._clear_heat_map()

    def _clear_heat_map(self) -> None:
        """With the context current."""
        if self.renderer is not None:
            self.renderer.overlay.set_heat_map(None)
        self.heat_map_shown = False
        if self._heat_key is not None:
            self._heat_key = None
            self.heat_map_cleared.emit()

    def texture_resident_bytes(self) -> int:
        return self.renderer.texture_resident_bytes() if self.renderer is not None else 0

    def cps_stats(self) -> dict:
        """The renderer's CPS statistics (reads the level maps: needs the GL context)."""
        if self.renderer is None:
            return {}
        self.makeCurrent()
        try:
            return self.renderer.cps_stats()
        finally:
            self.doneCurrent()

    def release_gl(self) -> None:
        if self.renderer is not None:
            self.makeCurrent()
            if self._probe is not None:
                self._probe.release()
                self._probe = None
            if self.presenter is not None:
                self.presenter.release_gl()
            self.renderer.release()
            self.renderer = None
            self.doneCurrent()

    # -- input -> session ----------------------------------------------------------------------
    def _advance(self) -> None:
        now = time.perf_counter()
        dt = min(0.1, now - self._last_tick)
        self._last_tick = now
        s = self.session
        if self.playing and s.path is not None:
            s.apply_path_frame(self._play_frame)
            self._play_frame = (self._play_frame + max(1, round(dt * 60))) % s.path.frame_count()
        else:
            fwd = sum(MOVE_KEYS[k][0] for k in self._keys if k in MOVE_KEYS)
            strafe = sum(MOVE_KEYS[k][1] for k in self._keys if k in MOVE_KEYS)
            rise = sum(MOVE_KEYS[k][2] for k in self._keys if k in MOVE_KEYS)
            turn = sum(TURN_KEYS[k] for k in self._keys if k in TURN_KEYS)
            if turn:
                s.walker.yaw_deg = (s.walker.yaw_deg + turn * TURN_DEG_S * dt) % 360.0
            if fwd or strafe or rise:
                s.walker.step(fwd, strafe, rise, dt)
            s.tick(dt)
            s.time += dt
        if self.is_recording:
            self.recording.append(s.current_key())
        self.update()

    def keyPressEvent(self, event: QKeyEvent) -> None:
        if event.key() in MOVE_KEYS or event.key() in TURN_KEYS:
            if not event.isAutoRepeat():
                self._keys.add(event.key())
            return
        super().keyPressEvent(event)

    def keyReleaseEvent(self, event: QKeyEvent) -> None:
        if not event.isAutoRepeat():
            self._keys.discard(event.key())
        super().keyReleaseEvent(event)

    def focusOutEvent(self, event) -> None:
        self._keys.clear()  # a key released while another widget had focus must not stick
        super().focusOutEvent(event)

    def _set_gaze_from(self, pos: QPointF) -> None:
        ratio = self.devicePixelRatioF()
        layout = self.eye_layout()
        self.session.eye_size = (layout.eye_width, layout.eye_height)
        u, v = layout.to_eye(pos.x() * ratio, pos.y() * ratio)
        self.session.gaze.set_cursor(u, v)

    def mouseMoveEvent(self, event: QMouseEvent) -> None:
        pos = event.position()
        if self._drag_from is not None:
            d = pos - self._drag_from
            self._drag_from = pos
            self.session.walker.look(d.x(), d.y())
        else:
            self._set_gaze_from(pos)

    def mousePressEvent(self, event: QMouseEvent) -> None:
        self.setFocus()
        if event.button() == Qt.MouseButton.LeftButton:
            self._set_gaze_from(event.position())
            self.session.gaze.button_held = True
            self.session.tick(0.0)
        elif event.button() in (Qt.MouseButton.RightButton, Qt.MouseButton.MiddleButton):
            self._drag_from = event.position()

    def mouseReleaseEvent(self, event: QMouseEvent) -> None:
        if event.button() == Qt.MouseButton.LeftButton:
            self.session.gaze.button_held = False
            self.session.tick(0.0)
        elif event.button() in (Qt.MouseButton.RightButton, Qt.MouseButton.MiddleButton):
            self._drag_from = None
