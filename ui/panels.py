"""Panels built from the settings model, and the evaluation bar.

Widgets are generated from the dataclass tree (type, range, choices, help) so a new setting
appears in the panel, the CLI and presets at once. Statistics are polled at 4 Hz.
"""

from __future__ import annotations

from collections.abc import Callable

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
    QVBoxLayout,
    QWidget,
)

from app.settings import Settings


class SettingsPanel(QScrollArea):
    """One group per settings section; every edit goes through ``Settings.set``."""

    def __init__(
        self,
        settings: Settings,
        sections: tuple[str, ...],
        on_change: Callable[[str], None] | None = None,
        parent=None,
    ) -> None:
        super().__init__(parent)
        self.settings = settings
        self.on_change = on_change
        self.editors: dict[str, QWidget] = {}
        body = QWidget()
        layout = QVBoxLayout(body)
        for section in sections:
            box = QGroupBox(section.capitalize())
            form = QFormLayout(box)
            for key in settings.keys():
                if key.split(".")[0] == section:
                    editor = self._editor(key)
                    self.editors[key] = editor
                    label = QLabel(key.split(".", 1)[1].replace("_", " "))
                    label.setToolTip(settings.describe(key).get("help", ""))
                    editor.setToolTip(label.toolTip())
                    form.addRow(label, editor)
            layout.addWidget(box)
        layout.addStretch(1)
        self.setWidget(body)
        self.setWidgetResizable(True)

    def _editor(self, key: str) -> QWidget:
        meta = self.settings.describe(key)
        value = self.settings.get(key)
        if isinstance(value, bool):
            w = QCheckBox()
            w.setChecked(value)
            w.toggled.connect(lambda v, k=key: self._set(k, v))
            return w
        if meta.get("choices"):
            w = QComboBox()
            w.addItems(list(meta["choices"]))
            w.setCurrentText(str(value))
            w.currentTextChanged.connect(lambda v, k=key: self._set(k, v))
            return w
        w = QDoubleSpinBox()
        w.setDecimals(3)
        w.setRange(
            meta.get("lo") if meta.get("lo") is not None else -1e9,
            meta.get("hi") if meta.get("hi") is not None else 1e9,
        )
        w.setSingleStep(max(0.01, abs(float(value)) * 0.05))
        w.setValue(float(value))
        w.setKeyboardTracking(False)
        w.valueChanged.connect(lambda v, k=key: self._set(k, v))
        return w

    def _set(self, key: str, value: object) -> None:
        self.settings.set(key, value)
        if self.on_change:
            self.on_change(key)

    def refresh(self) -> None:
        """Show the model's values again (after a preset was loaded)."""
        for key, w in self.editors.items():
            value = self.settings.get(key)
            w.blockSignals(True)
            if isinstance(w, QCheckBox):
                w.setChecked(bool(value))
            elif isinstance(w, QComboBox):
                w.setCurrentText(str(value))
            elif isinstance(w, QDoubleSpinBox):
                w.setValue(float(value))
            w.blockSignals(False)


class EvaluationBar(QWidget):
    """Mode, viewpoint/gaze state, fps and the gazed object, polled at 4 Hz."""

    STATE_NAMES = {
        0: "viewpoint still, gaze moving",
        1: "viewpoint moving, gaze moving",
        2: "viewpoint still, gaze fixed",
        3: "viewpoint moving, gaze fixed",
    }

    def __init__(self, poll: Callable[[], dict], parent=None) -> None:
        super().__init__(parent)
        self.poll = poll
        layout = QHBoxLayout(self)
        layout.setContentsMargins(8, 2, 8, 2)
        names = ("phase", "state", "fps", "resident", "gazed", "scene")
        self.labels = {name: QLabel() for name in names}
        for name in names:
            self.labels[name].setTextInteractionFlags(Qt.TextInteractionFlag.TextSelectableByMouse)
            layout.addWidget(self.labels[name])
            layout.addStretch(1)
        self.timer = QTimer(self)
        self.timer.timeout.connect(self.refresh)
        self.timer.start(250)

    def refresh(self) -> None:
        info = self.poll()
        state = info.get("state", 0)
        self.labels["phase"].setText(f"phase: {info.get('phase', '')}")
        self.labels["state"].setText(f"state {state}: {self.STATE_NAMES.get(state, '')}")
        self.labels["resident"].setText(f"textures {info.get('resident_mb', 0.0):.2f} MB")
        self.labels["fps"].setText(f"{info.get('fps', 0.0):.1f} fps")
        self.labels["gazed"].setText(f"gaze on: {info.get('gazed') or '-'}")
        self.labels["scene"].setText(info.get("scene", ""))
