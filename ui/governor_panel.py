"""Frame-rate panel: what the frame-time governor (app/governor.py) holds and why.

Polled at 4 Hz from a ``lines()`` callable (the governor's :meth:`~app.governor.Governor.explain`
for the window's settings): the budget and the measured frame time first, then each part of
the picture it simplified, with the reason in words. The target itself is set in the Settings
tab ("Frame rate to hold"), where every setting has its one control.
"""

from __future__ import annotations

import logging
from collections.abc import Callable

from PyQt6.QtCore import QTimer
from PyQt6.QtWidgets import QGroupBox, QLabel, QVBoxLayout, QWidget

log = logging.getLogger(__name__)

HELP = (
    "To hold the frame rate while you walk, the picture is simplified where you would notice "
    "least: first distant objects and the edges of the view, then the resolution; shadows "
    "only when nothing else is left, the area around your gaze last. Standing still brings "
    "back full quality."
)


class GovernorPanel(QWidget):
    def __init__(self, lines: Callable[[], list[str]], parent=None) -> None:
        super().__init__(parent)
        self.lines = lines
        self._warned = False
        layout = QVBoxLayout(self)
        box = QGroupBox("Frame rate")
        inner = QVBoxLayout(box)
        self.budget = QLabel("")
        self.budget.setWordWrap(True)
        self.knobs = QLabel("")
        self.knobs.setWordWrap(True)
        help_label = QLabel(HELP)
        help_label.setWordWrap(True)
        inner.addWidget(self.budget)
        inner.addWidget(self.knobs)
        inner.addWidget(help_label)
        layout.addWidget(box)
        layout.addStretch(1)
        self.timer = QTimer(self)
        self.timer.timeout.connect(self.refresh)
        self.timer.start(250)
        self.refresh()

    def refresh(self) -> None:
        try:
            lines = [str(line) for line in self.lines()]
        except Exception as exc:  # noqa: BLE001 - no exception may escape a Qt slot
            if not self._warned:  # once, not four times a second
                self._warned = True
                log.warning("frame-rate panel: %s", exc)
            lines = ["Frame rate: not available."]
        self.budget.setText(lines[0] if lines else "")
        self.knobs.setText("\n".join(lines[1:]))
