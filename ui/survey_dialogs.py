"""The study's dialogs: questionnaires (one item a page, keys or mouse), instructions, rest.

Participants answer with the number keys (or by clicking); Left or Backspace goes back to change
an answer. Every answer is handed to ``on_answer`` at once (the runner appends it to disk) and
the dialog moves on only when that succeeded. The dialogs cannot be closed with Escape: a
session is ended by the runner, never by a stray key.
"""

from __future__ import annotations

import functools
import logging
import time
from collections.abc import Callable

from PyQt6.QtCore import Qt, QTimer
from PyQt6.QtGui import QFont, QKeyEvent
from PyQt6.QtWidgets import (
    QDialog,
    QHBoxLayout,
    QLabel,
    QMessageBox,
    QProgressBar,
    QPushButton,
    QVBoxLayout,
    QWidget,
)

from app.survey.questionnaires import Questionnaire

log = logging.getLogger(__name__)


def guarded(fn):
    """A Qt slot that must not let an exception escape (PyQt6 would abort the process)."""

    @functools.wraps(fn)
    def wrapper(*args, **kwargs):
        try:
            return fn(*args, **kwargs)
        except Exception as exc:  # noqa: BLE001 - report, keep the window alive
            log.exception("study: %s failed", fn.__name__)
            parent = args[0] if args and isinstance(args[0], QWidget) else None
            show_message(parent, "Study error", f"{type(exc).__name__}: {exc}", error=True)
            return None

    return wrapper


def show_message(parent, title: str, text: str, error: bool = False) -> QMessageBox:
    """A message box that does not block the event loop (the session's timers keep running)."""
    box = QMessageBox(
        QMessageBox.Icon.Critical if error else QMessageBox.Icon.Information, title, text
    )
    if parent is not None:
        box.setParent(parent, box.windowFlags())
    box.setAttribute(Qt.WidgetAttribute.WA_DeleteOnClose)
    box.open()
    return box


class _NoEscapeDialog(QDialog):
    def keyPressEvent(self, event: QKeyEvent) -> None:
        if event.key() == Qt.Key.Key_Escape:
            event.accept()  # not a way out of a questionnaire
            return
        super().keyPressEvent(event)

    def closeEvent(self, event) -> None:
        if getattr(self, "_may_close", False):
            super().closeEvent(event)
        else:
            event.ignore()

    def finish(self) -> None:
        self._may_close = True
        self.done(0)
        self.deleteLater()


class QuestionnaireDialog(_NoEscapeDialog):
    """One item per page: the item text and one button per rating."""

    def __init__(
        self,
        q: Questionnaire,
        answers: dict[str, int],
        heading: str,
        on_answer: Callable[[str, int], bool],
        on_done: Callable[[], None],
        parent: QWidget | None = None,
    ) -> None:
        super().__init__(parent)
        self.q = q
        self.answers = dict(answers)
        self.on_answer = on_answer
        self.on_done = on_done
        self._finished = False
        self.setWindowTitle(q.title)
        self.setModal(True)
        self.setMinimumWidth(560)
        layout = QVBoxLayout(self)
        self.heading = QLabel(heading)
        self.instructions = QLabel(q.instructions)
        self.instructions.setWordWrap(True)
        self.progress = QLabel()
        self.item_label = QLabel()
        self.item_label.setWordWrap(True)
        font = QFont(self.item_label.font())
        font.setPointSizeF(font.pointSizeF() * 1.6)
        self.item_label.setFont(font)
        self.item_label.setMinimumHeight(60)
        row = QHBoxLayout()
        self.buttons: list[QPushButton] = []
        for value, label in zip(range(q.lo, q.hi + 1), q.labels):
            b = QPushButton(f"{value}\n{label}")
            b.setCheckable(True)
            b.setMinimumSize(90, 56)
            b.setFocusPolicy(Qt.FocusPolicy.NoFocus)  # keys go to the dialog: digits answer
            b.clicked.connect(lambda _=False, v=value: self._answer(v))
            row.addWidget(b)
            self.buttons.append(b)
        nav = QHBoxLayout()
        self.back = QPushButton("← Back")
        self.back.setFocusPolicy(Qt.FocusPolicy.NoFocus)
        self.back.clicked.connect(lambda _=False: self._back())
        self.hint = QLabel(f"Press {q.lo}-{q.hi} or click. ← / Backspace: previous item.")
        nav.addWidget(self.back)
        nav.addStretch(1)
        nav.addWidget(self.hint)
        for w in (self.heading, self.instructions, self.progress, self.item_label):
            layout.addWidget(w)
        layout.addLayout(row)
        layout.addLayout(nav)
        ids = q.item_ids()
        self.index = next((n for n, i in enumerate(ids) if i not in self.answers), len(ids) - 1)
        self._show()

    @property
    def current_item(self) -> str:
        return self.q.item_ids()[self.index]

    def _show(self) -> None:
        item = self.q.items[self.index]
        self.progress.setText(f"Item {self.index + 1} of {len(self.q.items)}")
        self.item_label.setText(item.text)
        chosen = self.answers.get(item.id)
        for value, b in zip(range(self.q.lo, self.q.hi + 1), self.buttons):
            b.setChecked(value == chosen)
        self.back.setEnabled(self.index > 0)

    @guarded
    def _answer(self, value: int) -> None:
        if self._finished:
            return
        item = self.current_item
        if not self.on_answer(item, value):  # not saved: stay on this item
            self._show()
            return
        self.answers[item] = value
        ids = self.q.item_ids()
        missing = [n for n, i in enumerate(ids) if i not in self.answers]
        if not missing:
            self._finished = True
            self.on_done()
            return
        later = [n for n in missing if n > self.index]
        self.index = later[0] if later else missing[0]
        self._show()

    @guarded
    def _back(self) -> None:
        if self.index > 0 and not self._finished:
            self.index -= 1
            self._show()

    def keyPressEvent(self, event: QKeyEvent) -> None:
        key = event.key()
        zero = Qt.Key.Key_0.value
        if zero <= int(key) <= zero + 9:
            value = int(key) - zero
            if self.q.lo <= value <= self.q.hi:
                self._answer(value)
            event.accept()
            return
        if key in (Qt.Key.Key_Left, Qt.Key.Key_Backspace):
            self._back()
            event.accept()
            return
        if key == Qt.Key.Key_Right:
            if self.current_item in self.answers and self.index < len(self.q.items) - 1:
                self.index += 1
                self._show()
            event.accept()
            return
        if key in (Qt.Key.Key_Return, Qt.Key.Key_Enter):
            event.accept()  # Enter must not close the dialog half-answered
            return
        super().keyPressEvent(event)


class MessageDialog(_NoEscapeDialog):
    """A message with one button (Enter or a click): "Start", "Continue"."""

    def __init__(
        self, title: str, text: str, button: str, on_ok: Callable[[], None], parent=None
    ) -> None:
        super().__init__(parent)
        self.setWindowTitle(title)
        self.setModal(True)
        self.setMinimumWidth(480)
        self.on_ok = on_ok
        self._done = False
        layout = QVBoxLayout(self)
        self.label = QLabel(text)
        self.label.setWordWrap(True)
        layout.addWidget(self.label)
        self.ok = QPushButton(button)
        self.ok.setDefault(True)
        self.ok.clicked.connect(lambda _=False: self._ok())
        layout.addWidget(self.ok)

    @guarded
    def _ok(self) -> None:
        if not self._done:
            self._done = True
            self.on_ok()

    def keyPressEvent(self, event: QKeyEvent) -> None:
        if event.key() in (Qt.Key.Key_Return, Qt.Key.Key_Enter, Qt.Key.Key_Space):
            self._ok()
            event.accept()
            return
        super().keyPressEvent(event)


class RestDialog(_NoEscapeDialog):
    """The rest between conditions: a countdown; the experimenter may skip it."""

    def __init__(
        self, seconds: float, on_done: Callable[[bool], None], parent: QWidget | None = None
    ) -> None:
        super().__init__(parent)
        self.setWindowTitle("Rest")
        self.setModal(True)
        self.setMinimumWidth(420)
        self.seconds = float(seconds)
        self.on_done = on_done
        self._start = time.monotonic()
        self._done = False
        layout = QVBoxLayout(self)
        self.label = QLabel()
        self.bar = QProgressBar()
        self.bar.setRange(0, 1000)
        self.skip = QPushButton("Skip rest (experimenter)")
        self.skip.setFocusPolicy(Qt.FocusPolicy.NoFocus)
        self.skip.clicked.connect(lambda: self._finish(True))
        layout.addWidget(QLabel("Please rest. The next run starts after the rest."))
        layout.addWidget(self.label)
        layout.addWidget(self.bar)
        layout.addWidget(self.skip)
        self.timer = QTimer(self)
        self.timer.timeout.connect(self._tick)
        self.timer.start(250)
        self._tick()

    @guarded
    def _tick(self) -> None:
        left = self.seconds - (time.monotonic() - self._start)
        if left <= 0:
            self._finish(False)
            return
        self.label.setText(f"{int(left // 60)}:{int(left % 60):02d} left")
        self.bar.setValue(int(1000 * (1 - left / self.seconds)))

    @guarded
    def _finish(self, skipped: bool) -> None:
        if self._done:
            return
        self._done = True
        self.timer.stop()
        self.on_done(skipped)
