"""Settings controls built from the settings model, and the evaluation bar.

Every panel builds its controls one way, with :class:`SettingsForm`: a dotted key's metadata
gives the control (check box for a bool, combo box for choices, an integer spin box for an int
or a whole-number float, a decimal one with the setting's decimals otherwise, in its unit), its
label and its tooltip (plain help, the paper's term and the range, wrapped), so a new setting
appears in the panels, the CLI and presets at once, and no panel shows a key. Every edit goes
through :meth:`SettingsForm.set`, which shows a value the model refuses in the panel's status
line (named by its label) instead of raising in a Qt slot.
Statistics are polled at 4 Hz.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Mapping
from typing import Any

from PyQt6.QtCore import Qt, QTimer
from PyQt6.QtWidgets import (
    QCheckBox,
    QComboBox,
    QDoubleSpinBox,
    QFormLayout,
    QGroupBox,
    QHBoxLayout,
    QLabel,
    QScrollArea,
    QSpinBox,
    QVBoxLayout,
    QWidget,
)

from app.settings import SECTION_TITLES, Settings, SettingsError
from app.settings_fields import format_number, range_text, shown_range, shows_integer, with_unit

log = logging.getLogger(__name__)

_INT_MIN, _INT_MAX = -(2**31), 2**31 - 1  # what a QSpinBox holds


def setting_label(settings: Settings, key: str) -> str:
    """The control's name: the metadata's ``label`` (never the key)."""
    return settings.label(key)


def suffix_for(unit: str) -> str:
    """What a spin box shows after its value: ``" mm"``, ``"°"``, ``"%"``."""
    return with_unit("", unit) if unit else ""


class SettingsForm:
    """Builds the controls for settings keys and is their one way into the model.

    ``on_change(key)`` hears every accepted edit; ``after_set()`` (the panel's refresh, say)
    runs after each edit, accepted or not. ``status`` is the panel's status line: a refused
    value shows there, named by the setting's label, and the controls show the model's value
    again.
    """

    def __init__(
        self,
        settings: Settings,
        on_change: Callable[[str], None] | None = None,
        after_set: Callable[[], None] | None = None,
    ) -> None:
        self.settings = settings
        self.on_change = on_change
        self.after_set = after_set
        self.editors: dict[str, QWidget] = {}
        self.status = QLabel()
        self.status.setWordWrap(True)
        self.status.setStyleSheet("color: #d04040")
        self.status.setTextInteractionFlags(Qt.TextInteractionFlag.TextSelectableByMouse)
        self.status.hide()

    # -- building ------------------------------------------------------------------------------
    def control(
        self, key: str, *, text: str = "", items: Mapping[Any, str] | None = None
    ) -> QWidget:
        """The control for ``key``, from its metadata and current value.

        A bool is a check box (``text`` beside it, else the label); choices are a combo box
        whose entries carry the choice as data and show its ``choice_labels`` text; ``items``
        (value -> text) makes a combo box of other values (an int's levels, say). A number
        shown in whole units (an int, or ``decimals=0``) is a :class:`QSpinBox`, any other a
        :class:`QDoubleSpinBox` with the metadata's ``decimals``; both are limited to the
        key's range, step by its ``step``, show ``scale`` times the value and end in its unit.
        The tooltip is :meth:`Settings.explain`.
        """
        meta = self.settings.describe(key)
        value = self.settings.get(key)
        w: QWidget
        if isinstance(value, bool):
            w = QCheckBox(text or self.settings.label(key))
            w.toggled.connect(lambda v, k=key: self.set(k, v))
        elif meta.get("choices") or items is not None:
            if items is None:
                names = meta.get("choice_labels") or {}
                items = {c: names.get(c, c) for c in meta["choices"]}
            w = QComboBox()
            for data, label in items.items():
                w.addItem(label, data)
            w.currentIndexChanged.connect(lambda i, k=key, c=w: self.set(k, c.itemData(i)))
        elif isinstance(value, str):
            # Free text with suggestions (e.g. units: auto, or a factor): an editable combo box.
            w = QComboBox()
            w.setEditable(True)
            for data, label in (meta.get("choice_labels") or {}).items():
                w.addItem(label, data)
            w.activated.connect(lambda i, k=key, c=w: self.set(k, c.itemData(i) or c.itemText(i)))
            line = w.lineEdit()
            if line is not None:
                line.editingFinished.connect(lambda k=key, c=w: self._set_text(k, c))
        else:
            w = self._spin_box(key, meta, value)
        w.setToolTip(self.settings.explain(key))
        self.editors[key] = w
        w.blockSignals(True)  # showing the model's value is not an edit
        self._show(key, w)
        w.blockSignals(False)
        return w

    def _spin_box(self, key: str, meta: dict[str, Any], value: float) -> QWidget:
        scale = float(meta.get("scale") or 1.0)
        integer = shows_integer(meta, value)
        lo, hi = shown_range(meta, integer)
        step = meta.get("step")
        w: QSpinBox | QDoubleSpinBox
        if integer:
            w = QSpinBox()
            w.setRange(
                int(max(lo if lo is not None else _INT_MIN, _INT_MIN)),
                int(min(hi if hi is not None else _INT_MAX, _INT_MAX)),
            )
            w.setSingleStep(int(step) if step else max(1, round(abs(value * scale) * 0.05)))
            w.setGroupSeparatorShown(True)  # 65,536 photons
        else:
            w = QDoubleSpinBox()
            w.setDecimals(int(meta.get("decimals", 2)))
            w.setRange(lo if lo is not None else -1e9, hi if hi is not None else 1e9)
            w.setSingleStep(float(step) if step else max(0.01, abs(float(value) * scale) * 0.05))
        w.setSuffix(suffix_for(str(meta.get("unit", ""))))
        w.setKeyboardTracking(False)  # one change per finished edit, not per keystroke
        if scale == 1.0 and isinstance(value, int):
            w.valueChanged.connect(lambda v, k=key: self.set(k, v))
        else:
            w.valueChanged.connect(lambda v, k=key, f=scale: self.set(k, v / f))
        return w

    def add_row(self, form: QFormLayout, key: str, *, label: str | None = None, **kw) -> QWidget:
        """:meth:`control` for ``key`` as a row of ``form``, named by its label (or ``label``).

        A check box says its name itself, so its row has no name on the left.
        """
        w = self.control(key, **kw)
        if isinstance(w, QCheckBox) and label is None and not kw.get("text"):
            form.addRow(w)
            return w
        name = QLabel(label or setting_label(self.settings, key))
        name.setToolTip(w.toolTip())
        name.setBuddy(w)
        form.addRow(name, w)
        return w

    # -- model <-> widgets ---------------------------------------------------------------------
    def set(self, key: str, value: object) -> bool:
        """Write ``value`` through :meth:`Settings.set`; False (and the reason, in words, in
        the status line) when the model refuses it."""
        try:
            self.settings.set(key, value)
        except SettingsError as exc:
            log.warning("%s", exc)
            self.show_error(self.refusal(key, value, exc))
            self.refresh()
            if self.after_set:
                self.after_set()
            return False
        self.show_error(None)
        if self.after_set:
            self.after_set()
        if self.on_change:
            self.on_change(key)
        return True

    def refusal(self, key: str, value: object, exc: SettingsError) -> str:
        """Why ``value`` was refused, named by the label, a number in the units shown."""
        meta = self.settings.describe(key)
        label = self.settings.label(key)
        current = self.settings.get(key)
        if isinstance(current, (int, float)) and not isinstance(current, bool):
            try:
                shown = float(value) * float(meta.get("scale") or 1.0)  # type: ignore[arg-type]
            except (TypeError, ValueError):
                return f"{label}: {exc.reason}"
            digits = 0 if shows_integer(meta, current) else int(meta.get("decimals", 2))
            number = with_unit(format_number(shown, max(digits, 2)), str(meta.get("unit", "")))
            return f"{label}: {number} is not possible. {range_text(meta, current)}".strip()
        if meta.get("choices"):
            return f"{label}: that is not one of the choices."
        return f"{label}: {exc.reason}"

    def show_error(self, message: str | None) -> None:
        """Show ``message`` in the status line (None clears it)."""
        self.status.setText(message or "")
        self.status.setVisible(bool(message))

    def refresh(self) -> None:
        """Show the model's values again (after a change elsewhere, or a preset load)."""
        for key, w in self.editors.items():
            w.blockSignals(True)
            try:
                self._show(key, w)
            finally:
                w.blockSignals(False)

    def _set_text(self, key: str, combo: QComboBox) -> None:
        """A typed value: an entry's label means its value; anything else is taken as typed."""
        text = combo.currentText().strip()
        index = combo.findText(text)
        value = combo.itemData(index) if index >= 0 else text
        if value != self.settings.get(key):
            self.set(key, value)

    def _show(self, key: str, w: QWidget) -> None:
        value = self.settings.get(key)
        scale = float(self.settings.describe(key).get("scale") or 1.0)
        if isinstance(w, QCheckBox):
            w.setChecked(bool(value))
        elif isinstance(w, QComboBox) and w.isEditable():
            index = w.findData(value)
            if index >= 0:
                w.setCurrentIndex(index)
            else:
                w.setEditText(str(value))
        elif isinstance(w, QComboBox):
            w.setCurrentIndex(w.findData(value))
        elif isinstance(w, QSpinBox):
            w.setValue(round(value * scale))
        elif isinstance(w, QDoubleSpinBox):
            w.setValue(float(value) * scale)


class SettingsPanel(QScrollArea):
    """One group per settings section, every shown key a row built by :class:`SettingsForm`.

    Sections are titled in words (:data:`app.settings.SECTION_TITLES`); hidden settings
    (command line and presets only) get no row.
    """

    def __init__(
        self,
        settings: Settings,
        sections: tuple[str, ...],
        on_change: Callable[[str], None] | None = None,
        parent=None,
    ) -> None:
        super().__init__(parent)
        self.settings = settings
        self.form = SettingsForm(settings, on_change)
        self.editors = self.form.editors
        self.sections = sections
        body = QWidget()
        layout = QVBoxLayout(body)
        layout.addWidget(self.form.status)
        # Settings with no control here (command line and presets only) say so when changed,
        # so a preset's exposure never brightens the picture behind the user's back.
        self.hidden_note = QLabel()
        self.hidden_note.setWordWrap(True)
        self.hidden_note.setToolTip(
            "Settings that have no control in the panels, changed on the\n"
            "command line or by a loaded preset."
        )
        layout.addWidget(self.hidden_note)
        for section in sections:
            box = QGroupBox(SECTION_TITLES.get(section, section.capitalize()))
            rows = QFormLayout(box)
            for key in settings.shown_keys(section):
                self.form.add_row(rows, key)
            layout.addWidget(box)
        layout.addStretch(1)
        self.setWidget(body)
        self.setWidgetResizable(True)
        self._show_hidden()

    @property
    def on_change(self) -> Callable[[str], None] | None:
        return self.form.on_change

    @on_change.setter
    def on_change(self, callback: Callable[[str], None] | None) -> None:
        self.form.on_change = callback

    @property
    def status(self) -> QLabel:
        return self.form.status

    def refresh(self) -> None:
        """Show the model's values again (after a preset was loaded)."""
        self.form.refresh()
        self._show_hidden()

    def _show_hidden(self) -> None:
        defaults = Settings()
        changed = []
        for key in self.settings.keys():
            meta = self.settings.describe(key)
            value = self.settings.get(key)
            if not meta.get("hidden") or key.split(".", 1)[0] not in self.sections:
                continue
            if value == defaults.get(key):
                continue
            if isinstance(value, (int, float)) and not isinstance(value, bool):
                scale = float(meta.get("scale") or 1.0)
                digits = 0 if shows_integer(meta, value) else int(meta.get("decimals", 2))
                shown = with_unit(format_number(value * scale, digits), str(meta["unit"]))
            else:
                shown = str(value)
            changed.append(f"{self.settings.label(key)} {shown}")
        self.hidden_note.setText(
            f"Also set on the command line or by a preset: {', '.join(changed)}." if changed else ""
        )
        self.hidden_note.setVisible(bool(changed))


class EvaluationBar(QWidget):
    """Mode, viewpoint/gaze state, fps and the gazed object, polled at 4 Hz."""

    STATE_NAMES = {
        0: "standing, eyes wandering",
        1: "walking, eyes wandering",
        2: "standing, gaze fixed",
        3: "walking, gaze fixed",
    }
    TIPS = {
        "phase": "Which rules choose the texture detail (TCR tab).",
        "state": "Walking or standing, eyes wandering or fixed: the TCR paper's\n"
        "four states, drawn in the TCR tab.",
        "fps": "Frames drawn per second.",
        "resident": "Memory the textures take on the graphics card.",
        "gazed": "The object under the cursor, which stands in for your gaze.",
        "scene": "The model shown and its size in triangles.",
        "exposure": "The exposure the picture is shown at, in EV: automatic\n"
        "(adapting like the eye) or fixed, with the Brightness (Settings tab).",
    }

    def __init__(self, poll: Callable[[], dict], parent=None) -> None:
        super().__init__(parent)
        self.poll = poll
        layout = QHBoxLayout(self)
        layout.setContentsMargins(8, 2, 8, 2)
        names = ("phase", "state", "fps", "resident", "gazed", "scene", "exposure")
        self.labels = {name: QLabel() for name in names}
        for name in names:
            self.labels[name].setTextInteractionFlags(Qt.TextInteractionFlag.TextSelectableByMouse)
            self.labels[name].setToolTip(self.TIPS[name])
            layout.addWidget(self.labels[name])
            layout.addStretch(1)
        self.timer = QTimer(self)
        self.timer.timeout.connect(self.refresh)
        self.timer.start(250)

    def refresh(self) -> None:
        info = self.poll()
        state = info.get("state", 0)
        phase = info.get("phase", "")
        self.labels["phase"].setText(
            "Adaptive textures: off" if phase == "TCR off" else f"Texture rules: {phase}"
        )
        self.labels["state"].setText(f"State {state}: {self.STATE_NAMES.get(state, '')}")
        self.labels["resident"].setText(f"textures {info.get('resident_mb', 0.0):.2f} MB")
        self.labels["fps"].setText(f"{info.get('fps', 0.0):.1f} fps")
        self.labels["gazed"].setText(f"Looking at: {info.get('gazed') or '-'}")
        self.labels["scene"].setText(info.get("scene", ""))
        self.labels["scene"].setToolTip(info.get("scene_tip", ""))
        self.labels["exposure"].setText(info.get("exposure", ""))
