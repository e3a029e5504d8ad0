"""The live frame-time graph: the last seconds of frames, stacked per render pass, with the
target frame time as a line and a legend of the passes (F3 shows or hides its dock).

The data is :class:`app.frame_log.FrameLog` (the view records every frame into it); this widget
only paints it, at 5 Hz while it is shown.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable

from PyQt6.QtCore import QPointF, QRectF, Qt, QTimer
from PyQt6.QtGui import QAction, QColor, QKeySequence, QPainter, QPen, QPolygonF
from PyQt6.QtWidgets import QDockWidget, QMainWindow, QWidget

from app.frame_log import FrameLog, nice_ceiling, pass_label, target_fps
from app.frame_log import pass_colour as pass_hex
from app.settings import Settings

log = logging.getLogger(__name__)

REFRESH_MS = 200  # 5 Hz: a graph one reads, not a second view
TARGET_COLOUR = QColor(220, 0, 0)
BACKGROUND = QColor(255, 255, 255)
GRID = QColor(225, 225, 225)
TEXT = QColor(40, 40, 40)


def pass_colour(name: str) -> QColor:
    return QColor(pass_hex(name))


class FrameGraph(QWidget):
    """Frame times of the last ``log.seconds`` (x: seconds ago, y: ms), one coloured layer per
    pass, the target frame time (``render.target_fps`` if the settings have it, else 30 fps)
    as a red line, and the legend on the right."""

    LEFT, TOP, BOTTOM = 40, 20, 18  # room for the ms labels, the title and the seconds
    LEGEND_W = 170

    def __init__(
        self,
        frame_log: FrameLog,
        settings: Settings,
        clock: Callable[[], float] = time.perf_counter,
        parent: QWidget | None = None,
        display_hz: Callable[[], float | None] | None = None,
    ) -> None:
        super().__init__(parent)
        self.frame_log = frame_log
        self.settings = settings
        self.display_hz = display_hz  # the screen's refresh, for render.target_fps = auto
        self.clock = clock
        self.top_ms = 50.0  # the y axis' top, set by each paint
        self._failed = False
        self.setMinimumSize(300, 100)  # a strip under the view; it must not grow the window
        self.setToolTip(
            "Frame time of the last seconds: each colour is one render pass's GPU time, grey "
            "is the rest of the frame (CPU work, waiting); the red line is the target frame "
            "time. Below the line the view keeps up."
        )
        self.timer = QTimer(self)
        self.timer.timeout.connect(self.update)

    def showEvent(self, event) -> None:
        self.timer.start(REFRESH_MS)
        super().showEvent(event)

    def hideEvent(self, event) -> None:
        self.timer.stop()
        super().hideEvent(event)

    # -- geometry (the tests read it too) -------------------------------------------------------
    def plot_rect(self) -> QRectF:
        """The plotting area in widget pixels (left of the legend)."""
        right = self.width() - self.LEGEND_W - 8
        return QRectF(
            self.LEFT, self.TOP, max(10, right - self.LEFT), self.height() - self.TOP - self.BOTTOM
        )

    def y_of(self, ms: float) -> float:
        r = self.plot_rect()
        return r.bottom() - min(ms, self.top_ms) / self.top_ms * r.height()

    def x_of(self, seconds_ago: float) -> float:
        r = self.plot_rect()
        return r.right() + seconds_ago / self.frame_log.seconds * r.width()

    def target_fps(self) -> float:
        return target_fps(self.settings, self.display_hz() if self.display_hz else None)

    def target_ms(self) -> float:
        return 1000.0 / self.target_fps()

    # -- painting -------------------------------------------------------------------------------
    def paintEvent(self, event) -> None:
        painter = QPainter(self)
        try:
            self._paint(painter)
        except Exception as exc:  # noqa: BLE001 - a paint must never take the window down
            if not self._failed:
                log.error("frame-time graph: %s", exc)
                self._failed = True
        finally:
            painter.end()

    def _paint(self, p: QPainter) -> None:
        p.fillRect(self.rect(), BACKGROUND)
        stack = self.frame_log.stack(self.clock())
        target = self.target_ms()
        self.top_ms = nice_ceiling(max(target * 1.25, stack.peak_ms * 1.05))
        r = self.plot_rect()
        fm = p.fontMetrics()
        # Grid and the ms scale.
        p.setPen(QPen(GRID, 1))
        for k in range(5):
            y = round(self.y_of(self.top_ms * k / 4))
            p.drawLine(round(r.left()), y, round(r.right()), y)
        p.setPen(TEXT)
        for k in range(5):
            ms = self.top_ms * k / 4
            y = round(self.y_of(ms))
            p.drawText(QRectF(0, y - 8, self.LEFT - 4, 16), _right, _ms_text(ms))
        seconds = self.frame_log.seconds
        for s in range(int(seconds) + 1):
            x = self.x_of(-s)
            label = "now" if s == 0 else f"-{s} s"
            p.drawText(QRectF(x - 20, r.bottom() + 2, 40, 16), _centre, label)
        # The stacked layers, the top one first so each lower layer paints over it.
        if len(stack.t) >= 1:
            xs = [self.x_of(max(t, -seconds)) for t in stack.t]
            for j in range(len(stack.names) - 1, -1, -1):
                tops = stack.tops[:, j]
                poly = QPolygonF([QPointF(xs[0], r.bottom())])
                for x, ms in zip(xs, tops):
                    poly.append(QPointF(x, self.y_of(float(ms))))
                poly.append(QPointF(xs[-1], r.bottom()))
                p.setPen(Qt.PenStyle.NoPen)
                p.setBrush(pass_colour(stack.names[j]))
                p.drawPolygon(poly)
            p.setBrush(Qt.BrushStyle.NoBrush)
        # The target line, drawn last of the plot so no layer hides it.
        y = round(self.y_of(target))
        p.setPen(QPen(TARGET_COLOUR, 1))
        p.drawLine(round(r.left()), y, round(r.right()), y)
        p.drawText(
            QRectF(r.left() + 4, y - fm.height() - 1, r.width() - 8, fm.height()),
            _left,
            f"target {target:.1f} ms ({self.target_fps():g} fps)",
        )
        p.setPen(TEXT)
        p.drawRect(r)
        title = f"Frame time in ms, last {seconds:g} s"
        if len(stack.t):
            last = float(stack.tops[-1, -1])
            rate = f"{1000.0 / last:.0f} fps" if last > 0 else "-"
            title += f"   now {last:.1f} ms ({rate})"
        p.drawText(QRectF(r.left(), 0, r.width(), self.TOP), _left, title)
        self._paint_legend(p, stack.names)

    def _paint_legend(self, p: QPainter, names: tuple[str, ...]) -> None:
        x = self.width() - self.LEGEND_W
        y = self.TOP
        row = max(14, p.fontMetrics().height())
        for name in reversed(names):  # top to bottom as the layers are stacked
            if y + row > self.height():
                break
            p.fillRect(QRectF(x, y + 2, 10, row - 4), pass_colour(name))
            p.setPen(TEXT)
            p.drawText(QRectF(x + 14, y, self.LEGEND_W - 14, row), _left, pass_label(name))
            y += row


_left = Qt.AlignmentFlag.AlignLeft | Qt.AlignmentFlag.AlignVCenter
_right = Qt.AlignmentFlag.AlignRight | Qt.AlignmentFlag.AlignVCenter
_centre = Qt.AlignmentFlag.AlignHCenter | Qt.AlignmentFlag.AlignVCenter


def _ms_text(ms: float) -> str:
    return f"{ms:.0f}" if float(ms).is_integer() else f"{ms:.1f}"


def frame_graph_dock(
    window: QMainWindow,
    frame_log: FrameLog,
    settings: Settings,
    display_hz: Callable[[], float | None] | None = None,
) -> QDockWidget:
    """The graph in its own dock "Frame time" at the bottom, hidden until F3 (the dock's
    toggle action, also for the View menu; a window action, so it works with the menus
    hidden). ``display_hz``: the view's screen refresh (the line for a target of ``auto``)."""
    dock = QDockWidget("Frame time", window)
    dock.setObjectName("frame-time-graph")
    dock.setWidget(FrameGraph(frame_log, settings, display_hz=display_hz))
    window.addDockWidget(Qt.DockWidgetArea.BottomDockWidgetArea, dock)
    dock.hide()
    action: QAction = dock.toggleViewAction()
    action.setText("Frame-time graph")
    action.setShortcut(QKeySequence("F3"))
    action.setToolTip("Show or hide the live frame-time graph (F3)")
    window.addAction(action)
    return dock
