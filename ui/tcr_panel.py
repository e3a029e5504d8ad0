"""TCR control panel: rules and presets, texture filtering, state diagram, level legend.

Built on the settings model (controls from :class:`ui.panels.SettingsForm`, every edit through
``Settings.set``, a refused value shown in the panel) and polled at 4 Hz for the live parts
(the lit state, the gazed object's level and why).
"""

from __future__ import annotations

from collections.abc import Callable

from PyQt6.QtCore import QRectF, Qt, QTimer
from PyQt6.QtGui import QColor, QPainter, QPen
from PyQt6.QtWidgets import (
    QCheckBox,
    QFormLayout,
    QGridLayout,
    QGroupBox,
    QLabel,
    QVBoxLayout,
    QWidget,
)

from app.session import Session
from app.tcr import PRESETS, phase_name, terms_from_settings
from render.passes import LEVEL_TINTS
from ui.panels import SettingsForm, setting_label

#: The paper's four states: (number, viewpoint, gaze, the rules in effect), in words.
STATES = (
    (0, "Standing", "eyes wandering", "distance, light"),
    (1, "Walking", "eyes wandering", "+ motion"),
    (2, "Standing", "gaze fixed", "+ gaze"),
    (3, "Walking", "gaze fixed", "+ motion, gaze"),
)
#: The words for the rule set in use (the evaluation bar's "phase").
PHASES = {
    "psychology": "Psychology (distance, gaze, light)",
    "ergonomics": "Ergonomics (distance, motion, light)",
    "custom": "Custom",
}


class StateDiagram(QWidget):
    """The paper's four states in a 2x2 grid; the current one is lit."""

    def __init__(self, parent=None) -> None:
        super().__init__(parent)
        self.state = 0
        self.setMinimumSize(240, 110)
        self.setToolTip(
            "The TCR paper's four states: standing or walking, eyes wandering\n"
            "or fixed on one point. The lit state is the current one; each\n"
            "uses distance and light, plus the rules shown."
        )

    def set_state(self, state: int) -> None:
        if state != self.state:
            self.state = state
            self.update()

    def paintEvent(self, event) -> None:
        p = QPainter(self)
        p.setRenderHint(QPainter.RenderHint.Antialiasing)
        w, h = self.width() / 2, self.height() / 2
        for state, view, gaze, params in STATES:
            col, row = state % 2, state // 2
            r = QRectF(col * w + 3, row * h + 3, w - 6, h - 6)
            lit = state == self.state
            p.setBrush(QColor(255, 140, 40) if lit else QColor(60, 60, 66))
            p.setPen(QPen(QColor(30, 30, 30), 1))
            p.drawRoundedRect(r, 6, 6)
            p.setPen(QColor(0, 0, 0) if lit else QColor(220, 220, 220))
            p.drawText(
                r,
                Qt.AlignmentFlag.AlignCenter,
                f"{state}: {view}\n{gaze}\n{params}",
            )
        p.end()


class TcrPanel(QWidget):
    def __init__(
        self, session: Session, on_change: Callable[[str], None] | None = None, parent=None
    ) -> None:
        super().__init__(parent)
        self.session = session
        self.settings = session.settings
        layout = QVBoxLayout(self)

        self.form = SettingsForm(self.settings, on_change, after_set=self.refresh)
        layout.addWidget(self.form.status)
        box = QGroupBox("Adaptive texture mapping")
        form = QFormLayout(box)
        self.enabled = self.form.add_row(form, "tcr.enabled")
        self.preset = self.form.add_row(form, "tcr.preset")
        terms_row = QGridLayout()
        self.terms: dict[str, QCheckBox] = {}
        for i, term in enumerate("dvgl"):
            # The terms a preset implies: derived, so not one setting each (see _set_term).
            key = f"tcr.use_{term}"
            cb = QCheckBox(setting_label(self.settings, key))
            cb.setToolTip(self.settings.explain(key))
            cb.toggled.connect(lambda v, t=term: self._set_term(t, v))
            self.terms[term] = cb
            terms_row.addWidget(cb, i // 2, i % 2)
        rules = QLabel("Detail follows")
        rules.setToolTip(
            "The rules that lower or raise each object's texture detail;\n"
            "ticking one makes your own set.\n"
            "TCR paper: the terms d, v, g and l."
        )
        form.addRow(rules, terms_row)
        self.mode = self.form.add_row(form, "tcr.mode")
        self.f = self.form.add_row(form, "tcr.f_m")
        # Brightness has one control (Settings tab); the light rule reads it, so show it here.
        self.brightness = QLabel()
        self.brightness.setToolTip(
            "How bright the picture shows the room (its average against\n"
            "18% grey), which the dim-light rule reads; change it with\n"
            "Brightness or the exposure in the Settings tab."
        )
        form.addRow(QLabel("Scene brightness"), self.brightness)
        self.tint = self.form.add_row(form, "tcr.tint")
        layout.addWidget(box)

        box = QGroupBox("Walking or standing")
        form = QFormLayout(box)
        self.move_on = self.form.add_row(form, "tcr.move_on")
        self.move_off = self.form.add_row(form, "tcr.move_off")
        self.window = self.form.add_row(form, "tcr.window_s")
        layout.addWidget(box)

        legend = QGroupBox("Texture level colours")
        legend.setToolTip(
            "The tint each texture level gets when Tint objects by level\n"
            "is on: 0 is the full texture, each level after it half as sharp."
        )
        grid = QGridLayout(legend)
        for level, colour in enumerate(LEVEL_TINTS):
            swatch = QLabel()
            swatch.setFixedSize(18, 14)
            r, g, b = (int(c * 255) for c in colour)
            swatch.setStyleSheet(f"background: rgb({r},{g},{b}); border: 1px solid #444")
            grid.addWidget(swatch, level // 4, (level % 4) * 2)
            text = (
                "0 (full detail)"
                if level == 0
                else (f"{level}+" if level == len(LEVEL_TINTS) - 1 else str(level))
            )
            grid.addWidget(QLabel(text), level // 4, (level % 4) * 2 + 1)
        layout.addWidget(legend)

        self.diagram = StateDiagram()
        layout.addWidget(self.diagram)
        self.phase = QLabel()
        self.readout = QLabel()
        self.readout.setWordWrap(True)
        self.readout.setTextInteractionFlags(Qt.TextInteractionFlag.TextSelectableByMouse)
        self.readout.setToolTip(
            "Why the object under the gaze has its texture level.\n"
            "TCR paper: level j = d + v - g + l, kept within the\n"
            "texture's levels (0 is full detail)."
        )
        layout.addWidget(self.phase)
        layout.addWidget(self.readout)
        layout.addStretch(1)
        self.refresh()
        self.poll()
        self.timer = QTimer(self)
        self.timer.timeout.connect(self.poll)
        self.timer.start(250)

    @property
    def on_change(self) -> Callable[[str], None] | None:
        return self.form.on_change

    @on_change.setter
    def on_change(self, callback: Callable[[str], None] | None) -> None:
        self.form.on_change = callback

    def _set_term(self, term: str, value: bool) -> None:
        t = self.settings.tcr
        if t.preset != "custom":
            # Editing a term of a preset starts a custom set from that preset's terms.
            base = PRESETS[t.preset]
            for name in "dvgl":
                self.settings.set(f"tcr.use_{name}", getattr(base, name))
            self.settings.set("tcr.preset", "custom")
        self.form.set(f"tcr.use_{term}", value)

    def refresh(self) -> None:
        """Show the model's values (after a change here, a preset load, or the CLI)."""
        self.form.refresh()
        terms = terms_from_settings(self.settings.tcr)
        for w in self.terms.values():
            w.blockSignals(True)
        for name, cb in self.terms.items():
            cb.setChecked(getattr(terms, name))
        for w in self.terms.values():
            w.blockSignals(False)

    def poll(self) -> None:
        s = self.session
        self.diagram.set_state(s.state)
        t = self.settings.tcr
        phase = PHASES[phase_name(terms_from_settings(t))] if t.enabled else "off"
        self.phase.setText(f"Rules in use: {phase}")
        self.brightness.setText(
            f"{s.displayed_brightness() * 100:.0f}% (change it in Settings, Picture)"
        )
        reason = s.reason(s.gazed)
        name = s.gazed_object()
        if reason is None or name is None:
            self.readout.setText("Looking at: nothing")
        elif not t.enabled:
            self.readout.setText(f"{name}: full texture detail (adaptive textures off)")
        else:
            self.readout.setText(reason.plain(name))
