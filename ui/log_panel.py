"""The log and warnings panel (Ctrl+L, View > Log and warnings, the status bar's warnings link).

:class:`QtLogHandler` is a ``logging.Handler`` on the root logger that hands every record to the
UI thread through a Qt signal (queued when a worker thread logs: loads, photon tracing), so the
panel lists the app's messages from any thread. The panel shows them with the level in plain
words, above them the current scene's load warnings, and copies both with one button.
"""

from __future__ import annotations

import logging
import time
from collections import deque
from collections.abc import Callable

from PyQt6.QtCore import QObject, pyqtSignal
from PyQt6.QtGui import QFont, QGuiApplication
from PyQt6.QtWidgets import (
    QDialog,
    QHBoxLayout,
    QLabel,
    QPlainTextEdit,
    QPushButton,
    QVBoxLayout,
    QWidget,
)

MAX_RECORDS = 2000  # the panel keeps the latest records; older ones stay in the terminal's log


def plain_level(levelno: int) -> str:
    """A log level as a word a designer reads."""
    if levelno >= logging.CRITICAL:
        return "serious error"
    if levelno >= logging.ERROR:
        return "error"
    if levelno >= logging.WARNING:
        return "warning"
    if levelno >= logging.INFO:
        return "note"
    return "detail"


class _Bridge(QObject):
    record = pyqtSignal(float, int, str)  # time, level, message


class QtLogHandler(logging.Handler):
    """Forwards log records to Qt through a signal; safe to call from any thread."""

    def __init__(self, level: int = logging.INFO) -> None:
        super().__init__(level)
        self.bridge = _Bridge()

    def emit(self, record: logging.LogRecord) -> None:
        try:
            message = record.getMessage()
            if record.exc_info and record.exc_info[1] is not None:
                message += f" ({type(record.exc_info[1]).__name__}: {record.exc_info[1]})"
            self.bridge.record.emit(record.created, record.levelno, message)
        except RuntimeError:  # the panel is gone (its window closed without detaching)
            logging.getLogger().removeHandler(self)
        except Exception:  # noqa: BLE001 - logging must never raise into the caller
            self.handleError(record)


class LogPanel(QDialog):
    """Load warnings of the current scene, then the app's messages; Copy puts both on the
    clipboard."""

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.setWindowTitle("Log and warnings")
        self.records: deque[tuple[float, int, str]] = deque(maxlen=MAX_RECORDS)
        self.scene_name = ""
        self.scene_warnings: list[str] = []
        mono = QFont("monospace")
        mono.setStyleHint(QFont.StyleHint.TypeWriter)
        layout = QVBoxLayout(self)
        self.warnings_title = QLabel()
        layout.addWidget(self.warnings_title)
        self.warnings_view = QPlainTextEdit(readOnly=True)
        self.warnings_view.setMaximumHeight(160)
        layout.addWidget(self.warnings_view)
        layout.addWidget(QLabel("<b>Messages</b> (newest last)"))
        self.log_view = QPlainTextEdit(readOnly=True)
        self.log_view.setFont(mono)
        layout.addWidget(self.log_view, 1)
        buttons = QHBoxLayout()
        self.copy_button = QPushButton("Copy")
        self.copy_button.setToolTip("Copy the warnings and the messages to the clipboard")
        self.copy_button.clicked.connect(self.copy)
        close = QPushButton("Close")
        close.clicked.connect(self.hide)
        buttons.addStretch(1)
        buttons.addWidget(self.copy_button)
        buttons.addWidget(close)
        layout.addLayout(buttons)
        self.resize(720, 480)
        self.handler = QtLogHandler()
        self.handler.bridge.record.connect(self.add_record)
        self._show_warnings()

    # -- the log ---------------------------------------------------------------------------------
    def attach(self, logger: logging.Logger | None = None) -> None:
        """Start listing ``logger``'s records (default: the root logger, i.e. everything)."""
        (logger or logging.getLogger()).addHandler(self.handler)

    def detach(self, logger: logging.Logger | None = None) -> None:
        (logger or logging.getLogger()).removeHandler(self.handler)

    def add_record(self, created: float, levelno: int, message: str) -> None:
        self.records.append((created, levelno, message))
        self.log_view.appendPlainText(_line(created, levelno, message))

    # -- the scene's load warnings ---------------------------------------------------------------
    def set_scene_warnings(self, scene_name: str, warnings: list[str]) -> None:
        self.scene_name = scene_name
        self.scene_warnings = list(warnings)
        self._show_warnings()

    def _show_warnings(self) -> None:
        n = len(self.scene_warnings)
        if not self.scene_name:
            self.warnings_title.setText("<b>Load warnings</b>: no scene loaded")
        elif n == 0:
            self.warnings_title.setText(f"<b>Load warnings</b> for {self.scene_name}: none")
        else:
            self.warnings_title.setText(
                f"<b>Load warnings</b> for {self.scene_name}: {_count(n, 'warning')}"
            )
        self.warnings_view.setPlainText("\n".join(f"• {w}" for w in self.scene_warnings))

    # -- actions ---------------------------------------------------------------------------------
    def text(self) -> str:
        """What Copy puts on the clipboard."""
        head = f"Load warnings for {self.scene_name or 'no scene'}:"
        warnings = [f"  {w}" for w in self.scene_warnings] or ["  none"]
        messages = [_line(*r) for r in self.records] or ["  none"]
        lines = [head, *warnings, "", "Messages:", *messages]
        return "\n".join(lines)

    def copy(self) -> None:
        QGuiApplication.clipboard().setText(self.text())

    def open_panel(self) -> None:
        self.show()
        self.raise_()
        self.activateWindow()
        self.log_view.verticalScrollBar().setValue(self.log_view.verticalScrollBar().maximum())


class WarningsLink(QPushButton):
    """The status bar's "N warnings" as a link that opens the panel; hidden when there are
    none."""

    def __init__(self, open_panel: Callable[[], None], parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.setFlat(True)
        self.setStyleSheet(
            "QPushButton { border: none; color: palette(link); text-decoration: underline; "
            "padding: 0 6px; }"
        )
        self.setToolTip("Show what the load reported (Ctrl+L)")
        self.clicked.connect(open_panel)
        self.set_count(0)

    def set_count(self, n: int) -> None:
        self.setText(f"{_count(n, 'warning')} (show)")
        self.setVisible(n > 0)


def _count(n: int, word: str) -> str:
    return f"{n:,} {word}" + ("" if n == 1 else "s")


def _line(created: float, levelno: int, message: str) -> str:
    stamp = time.strftime("%H:%M:%S", time.localtime(created))
    return f"{stamp}  {plain_level(levelno):<7}  {message}"
