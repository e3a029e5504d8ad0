"""Presenter mode (F5), for demonstrations: the A/B split, a large fps readout, one-key
mitigation modes.

While it is on, each eye shows the current technique left of a divider and the same view at
full quality right of it (``render.ab_frame``), with a caption on each side; the divider is
dragged with the mouse or stepped with [ and ]. M steps through the mitigation modes
(``cps.mode``) whether presenting or not, and the caption follows. A big fps readout sits in
the view's top-right corner, refreshed 4 times a second. Off again, the view draws exactly the
normal frame (presenting changes no setting).
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from typing import TYPE_CHECKING

import moderngl
from PyQt6.QtCore import QEvent, QObject, Qt, QTimer
from PyQt6.QtGui import QAction, QKeySequence, QMouseEvent
from PyQt6.QtWidgets import QLabel, QMenu, QWidget

from app.frame import FrameInput
from app.settings import Settings
from render.ab_frame import ABFrame
from render.ab_split import WITHOUT, SplitView, technique_caption
from render.renderer import Renderer

if TYPE_CHECKING:
    from ui.gl_view import StereoView

log = logging.getLogger(__name__)

DIVIDER_STEP = 0.05  # [ and ]: a twentieth of the eye's width
GRAB_PX = 8  # the divider is caught within this many pixels of the line
FPS_PX = 48  # the readout's text height, readable from the back of a room
DETAIL_PX = 16  # the readout's second line: each half's GPU time
REFRESH_MS = 250  # the readout's refresh (4 Hz)
SPLIT_PASSES = ("ab_split", "overlay")  # drawn once over both halves: neither half's cost
DEMO_SCENE = "corridor"  # the built-in scene of the CPS paper's walk


class Presenter(QObject):
    """The mode's controller: its actions, the split's state, the divider drag and the
    readout. The view asks it to draw the frame while it is on (``StereoView.presenter``)."""

    def __init__(
        self,
        view: StereoView,
        settings: Settings,
        on_change: Callable[[str], None],
        status: Callable[[str, int], None],
        load: Callable[[str], None],
    ) -> None:
        super().__init__(view)
        self.view = view
        self.settings = settings
        self.on_change = on_change  # as a panel's: the window refreshes panels and redraws
        self.status = status
        self.load = load
        self.active = False
        self.split = SplitView()
        self.dragging = False
        self._ab: ABFrame | None = None
        self._failed = False
        self._play_on: str | None = None  # start the walk once this scene is in
        self.fps_label = QLabel(view)
        self.fps_label.setObjectName("presenter-fps")
        self.fps_label.setStyleSheet(
            "QLabel { color: white; background: rgba(0, 0, 0, 160); padding: 6px 14px;"
            " border-radius: 8px; }"
        )
        font = self.fps_label.font()
        font.setPixelSize(FPS_PX)
        font.setBold(True)
        self.fps_label.setFont(font)
        self.fps_label.setTextFormat(Qt.TextFormat.RichText)
        self.fps_label.setAttribute(Qt.WidgetAttribute.WA_TransparentForMouseEvents)
        self.fps_label.hide()
        self._timer = QTimer(self)
        self._timer.setInterval(REFRESH_MS)
        self._timer.timeout.connect(self._refresh)
        self.actions: dict[str, QAction] = {}
        view.installEventFilter(self)
        view.presenter = self

    # -- actions -------------------------------------------------------------------------------
    def add_actions(self, menu: QMenu, window: QWidget) -> None:
        """The mode's entries in ``menu`` (the View menu), shortcuts live on ``window``."""

        def action(key: str, text: str, slot, shortcut: str) -> QAction:
            a = QAction(text, window)
            a.setShortcut(QKeySequence(shortcut))
            if slot is not None:
                a.triggered.connect(slot)
            menu.addAction(a)
            window.addAction(a)  # shortcuts keep working while the menu bar is hidden
            self.actions[key] = a
            return a

        menu.addSeparator()
        mode = action("presenter", "Presenter mode", None, "F5")
        mode.setToolTip("Each eye: the current technique left of a divider, full quality right")
        mode.setCheckable(True)
        mode.toggled.connect(self.set_active)
        action("mitigation", "Next mitigation mode", self.next_mitigation, "M")
        action("left", "Move the divider left", lambda: self.step_divider(-1), "[")
        action("right", "Move the divider right", lambda: self.step_divider(1), "]")
        action("demo", "Present the corridor walk", self.present_corridor_walk, "Shift+F5")
        self._enable_divider_keys()

    def _enable_divider_keys(self) -> None:
        for key in ("left", "right"):
            if key in self.actions:
                self.actions[key].setEnabled(self.active)

    # -- the mode ------------------------------------------------------------------------------
    def set_active(self, on: bool) -> None:
        """Presenter mode on or off (F5); off releases the full-quality half's GPU objects."""
        on = bool(on)
        if on == self.active:
            return
        self.active = on
        self.dragging = False
        self._failed = False
        action = self.actions.get("presenter")
        if action is not None and action.isChecked() != on:
            action.setChecked(on)  # toggled -> set_active again: a no-op now
        self._enable_divider_keys()
        if on:
            self._refresh()
            self.fps_label.show()
            self.fps_label.raise_()
            self._timer.start()
            self.status(f"Presenter mode: {self.caption} | {WITHOUT}  (F5 ends it)", 6000)
        else:
            self._timer.stop()
            self.fps_label.hide()
            self.view.unsetCursor()
            self._release_frame()
        self.view.update()

    @property
    def caption(self) -> str:
        """The left side's caption: what the current settings change against full quality."""
        renderer = self.view.renderer
        photons = renderer is not None and renderer.photons.photons is not None
        return technique_caption(self.settings, photons)

    def next_mitigation(self) -> None:
        """M: the next of the mitigation modes (``cps.mode``), round to the first again."""
        meta = self.settings.describe("cps.mode")
        choices = list(meta.get("choices") or ())
        if not choices:
            return
        current = self.settings.cps.mode
        mode = choices[(choices.index(current) + 1) % len(choices)] if current in choices else ""
        self.settings.set("cps.mode", mode or choices[0])
        self.on_change("cps.mode")
        name = (meta.get("choice_labels") or {}).get(self.settings.cps.mode, self.settings.cps.mode)
        self.status(f"Mitigation mode: {name}. {self.caption}", 6000)

    def step_divider(self, direction: int) -> None:
        """[ / ]: the divider a step left or right (presenter mode only)."""
        if not self.active:
            return
        self.set_divider(self.split.divider + direction * DIVIDER_STEP)

    def set_divider(self, share: float) -> None:
        self.split.divider = round(min(max(float(share), 0.0), 1.0), 4)
        self.view.update()

    def present_corridor_walk(self) -> None:
        """Shift+F5: presenter mode on the built-in corridor, its walk playing."""
        self.set_active(True)
        scene = self.view.session.scene
        if scene is not None and scene.name == DEMO_SCENE:
            self._start_walk()
        else:
            self._play_on = DEMO_SCENE  # started by the readout's refresh once loaded
            self.load(DEMO_SCENE)

    def _start_walk(self) -> None:
        self._play_on = None
        self.view.playing = True

    # -- drawing (called by the view's paintGL, its GL context current) ------------------------
    def render(
        self,
        renderer: Renderer,
        frame: FrameInput,
        fbo: moderngl.Framebuffer,
        origin: tuple[int, int] = (0, 0),
    ) -> None:
        """The A/B frame into ``fbo`` with the eyes' lower-left at ``origin``; the normal frame
        when there is no scene, or after the full-quality half failed (said once in the log
        and the status bar)."""
        scene = self.view.session.scene
        if scene is None or self._failed or self.view.ctx is None:
            renderer.render(frame, fbo, origin)
            return
        try:
            if self._ab is None:
                self._ab = ABFrame(self.view.ctx, stream_in=True)  # as the view's own scene
            self.split.left = self.caption
            self._ab.render(renderer, scene, frame, fbo, self.split, origin)
        except Exception as exc:  # noqa: BLE001 - a demo aid must never take the view down
            log.exception("presenter mode: the full-quality half failed")
            self._failed = True
            self.status(f"Presenter mode cannot draw the comparison: {exc}", 10000)
            fbo.use()
            renderer.render(frame, fbo, origin)

    def release_gl(self) -> None:
        """Release the full-quality half (the view's GL context current)."""
        if self._ab is not None:
            self._ab.release()
            self._ab = None

    def _release_frame(self) -> None:
        if self._ab is None or self.view.renderer is None:
            self._ab = None
            return
        self.view.makeCurrent()
        try:
            self.release_gl()
        finally:
            self.view.doneCurrent()

    # -- the readout ---------------------------------------------------------------------------
    def readout_lines(self) -> tuple[str, str]:
        """The readout: frames per second as shown (both halves are drawn every frame), and
        what each half took on the GPU in the last frame, as whole numbers."""
        fps = f"{round(self.view.timer.fps)} fps"
        renderer = self.view.renderer
        if self._ab is None or renderer is None or not self._ab.pass_ms():
            return fps, ""
        live = sum(ms for name, ms in renderer.pass_ms().items() if name not in SPLIT_PASSES)
        full = sum(self._ab.pass_ms().values())
        return fps, f"GPU per frame: {round(live)} ms with, {round(full)} ms without"

    def _refresh(self) -> None:
        try:
            fps, detail = self.readout_lines()
            small = f"<br><span style='font-size:{DETAIL_PX}px; font-weight:normal'>{detail}</span>"
            self.fps_label.setText(fps + (small if detail else ""))
            self.fps_label.adjustSize()
            self._place_label()
            scene = self.view.session.scene
            if self._play_on and scene is not None and scene.name == self._play_on:
                self._start_walk()
        except Exception:  # noqa: BLE001 - no exception may escape a timer
            log.exception("presenter readout failed")

    def _place_label(self) -> None:
        margin = 12
        self.fps_label.move(max(0, self.view.width() - self.fps_label.width() - margin), margin)

    # -- the divider drag (events of the view) -------------------------------------------------
    def _eyes(self) -> tuple[float, float]:
        """The left eye's left edge and the eye width, in view (logical) pixels."""
        ratio = self.view.devicePixelRatioF() or 1.0
        eyes = self.view.eye_layout()  # letterboxed eyes, in device pixels
        return eyes.x / ratio, max(1.0, eyes.eye_width / ratio)

    def _divider_x(self, eye: int) -> float:
        x0, eye_w = self._eyes()
        return x0 + (eye + self.split.divider) * eye_w

    def _near_divider(self, x: float) -> int | None:
        """The eye whose divider is within GRAB_PX of ``x`` (view pixels), or None."""
        for eye in (0, 1):
            if abs(x - self._divider_x(eye)) <= GRAB_PX:
                return eye
        return None

    def eventFilter(self, obj: QObject | None, event: QEvent | None) -> bool:
        try:
            return self._filter(obj, event)
        except Exception:  # noqa: BLE001 - no exception may escape an event handler
            log.exception("presenter: event handling failed")
            return False

    def _filter(self, obj: QObject | None, event: QEvent | None) -> bool:
        if obj is not self.view or event is None:
            return False
        kind = event.type()
        if kind == QEvent.Type.Resize:
            self._place_label()
            return False
        if not self.active or not isinstance(event, QMouseEvent):
            return False
        x = event.position().x()
        left = event.button() == Qt.MouseButton.LeftButton
        if kind == QEvent.Type.MouseButtonPress and left and self._near_divider(x) is not None:
            self.dragging = True
            self.view.setFocus()
            return True
        if kind == QEvent.Type.MouseMove:
            if self.dragging:
                x0, eye_w = self._eyes()
                eye = 1 if x >= x0 + eye_w else 0
                self.set_divider((x - x0 - eye * eye_w) / eye_w)
                return True
            if self._near_divider(x) is not None:
                self.view.setCursor(Qt.CursorShape.SplitHCursor)
            else:
                self.view.unsetCursor()
            return False
        if kind == QEvent.Type.MouseButtonRelease and left and self.dragging:
            self.dragging = False
            return True
        return False
