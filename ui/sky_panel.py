"""The "Sun and sky" tab: daylight on or off, a time-of-day slider, the site, and where the sun
stands, in words.

Every ``sky.*`` setting has its one control here (``editors``), built by
:class:`ui.panels.SettingsForm` from its metadata; the time of day is a slider in ten-minute
steps that moves the sun while it is dragged.
"""

from __future__ import annotations

import logging
from collections.abc import Callable

from PyQt6.QtCore import Qt
from PyQt6.QtWidgets import (
    QFormLayout,
    QGroupBox,
    QHBoxLayout,
    QLabel,
    QScrollArea,
    QSlider,
    QVBoxLayout,
    QWidget,
)

from app.settings import SECTION_TITLES, Settings
from app.sky import sun_position
from ui.panels import SettingsForm

log = logging.getLogger(__name__)

STEP_MIN = 10
COMPASS = (
    "north",
    "north-east",
    "east",
    "south-east",
    "south",
    "south-west",
    "west",
    "north-west",
)


def compass_name(azimuth_deg: float) -> str:
    """The compass point nearest an azimuth (degrees clockwise from north)."""
    return COMPASS[int(((azimuth_deg % 360.0) + 22.5) // 45.0) % 8]


def sun_words(settings: Settings) -> str:
    """Where the sun stands, as a designer says it: "Sun 35° above the horizon, south-east"."""
    try:
        pos = sun_position(settings.sky)
    except (ValueError, OverflowError) as exc:  # a date astral cannot place
        return f"The sun cannot be placed for this date and time ({exc})."
    side = compass_name(pos.azimuth_deg)
    if pos.elevation_deg < 0.0:
        return f"Sun {abs(pos.elevation_deg):.0f}° below the horizon, {side}: night, no sunlight"
    return f"Sun {pos.elevation_deg:.0f}° above the horizon, {side}"


def minutes_of(clock: str) -> int:
    hours, minutes = (int(p) for p in clock.split(":"))
    return hours * 60 + minutes


class SkyPanel(QScrollArea):
    """Daylight settings with a time slider and the sun's place in words."""

    def __init__(
        self, settings: Settings, on_change: Callable[[str], None] | None = None, parent=None
    ) -> None:
        super().__init__(parent)
        self.settings = settings
        self.form = SettingsForm(settings, on_change, after_set=self._show_sun)
        self.editors = self.form.editors
        body = QWidget()
        layout = QVBoxLayout(body)
        layout.addWidget(self.form.status)
        box = QGroupBox(SECTION_TITLES.get("sky", "Sun and sky"))
        rows = QFormLayout(box)
        for key in settings.shown_keys("sky"):
            if key == "sky.time":
                self._add_time_row(rows)
            else:
                self.form.add_row(rows, key)
        self.sun = QLabel()
        self.sun.setWordWrap(True)
        self.sun.setToolTip("Where the sun stands for this date, time and place.")
        rows.addRow(self.sun)
        layout.addWidget(box)
        layout.addStretch(1)
        self.setWidget(body)
        self.setWidgetResizable(True)
        self.refresh()

    def _add_time_row(self, rows: QFormLayout) -> None:
        slider = QSlider(Qt.Orientation.Horizontal)
        slider.setRange(0, 24 * 60 // STEP_MIN - 1)  # 00:00 to 23:50
        slider.setSingleStep(1)
        slider.setPageStep(6)  # an hour
        slider.setToolTip(self.settings.explain("sky.time"))
        slider.valueChanged.connect(self._time_moved)  # live while dragging
        self.time_text = QLabel()
        self.time_text.setMinimumWidth(44)
        self.time_text.setToolTip(slider.toolTip())
        self.time_slider = slider
        self.editors["sky.time"] = slider
        row = QWidget()
        line = QHBoxLayout(row)
        line.setContentsMargins(0, 0, 0, 0)
        line.addWidget(slider, 1)
        line.addWidget(self.time_text)
        name = QLabel(self.settings.label("sky.time"))
        name.setToolTip(slider.toolTip())
        name.setBuddy(slider)
        rows.addRow(name, row)

    def _time_moved(self, step: int) -> None:
        minutes = int(step) * STEP_MIN
        clock = f"{minutes // 60:02d}:{minutes % 60:02d}"
        self.time_text.setText(clock)
        if clock != self.settings.sky.time:
            self.form.set("sky.time", clock)

    def _show_sun(self) -> None:
        self.sun.setText(sun_words(self.settings))

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
        self.form.refresh()  # the slider is not a form control: it is set here
        clock = self.settings.sky.time
        self.time_slider.blockSignals(True)
        self.time_slider.setValue(round(minutes_of(clock) / STEP_MIN))
        self.time_slider.blockSignals(False)
        self.time_text.setText(clock)
        self._show_sun()
