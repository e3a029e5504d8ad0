"""Quality panel: the live frame against full quality, on a key (F9).

Full quality is :func:`app.quality.full_quality` (finest textures, full-rate lighting, no
mask, photons gathered per eye): the same reference the benchmark and the study use. The
figures are PSNR, SSIM and FLIP on display values for the frame, the fovea (around the gaze)
and the periphery; the FLIP error map is shown over the view as a heat map.

The heat map belongs to the view it measured: the view drops it as soon as the camera, the gaze
or a setting changes (:meth:`heat_cleared`), and F8 (:meth:`toggle_heat`) shows or hides it from
anywhere, measuring first when there is nothing to show.
"""

from __future__ import annotations

import math
from collections.abc import Callable

from PyQt6.QtWidgets import (
    QCheckBox,
    QGridLayout,
    QGroupBox,
    QLabel,
    QPushButton,
    QVBoxLayout,
    QWidget,
)

REGIONS = ("frame", "fovea", "periphery")
METRICS = (("psnr_db", "PSNR (dB)"), ("ssim", "SSIM"), ("flip", "FLIP"))
#: What the table's rows and columns show, in words.
REGION_TITLES = {
    "frame": "Whole view",
    "fovea": "Around the gaze",
    "periphery": "Edges of the view",
}
TIPS = {
    "psnr_db": "Peak signal-to-noise ratio: higher is closer to full\n"
    "quality; above 40 dB differences are hard to see.",
    "ssim": "Structural similarity: 1 means the same structure as full\n"
    "quality, lower means visibly changed detail.",
    "flip": "FLIP: how different the two pictures look to a person\n"
    "flipping between them; 0 is no visible difference.",
    "frame": "Both eyes' whole picture.",
    "fovea": "The area around where you look, which must not change.",
    "periphery": "Everything outside the area around the gaze.",
}


class QualityPanel(QWidget):
    def __init__(
        self, measure: Callable[[], dict], show_heat: Callable[[object], None], parent=None
    ) -> None:
        super().__init__(parent)
        self._measure = measure
        self._show_heat = show_heat
        self.report: dict = {}
        layout = QVBoxLayout(self)
        self.button = QPushButton("Measure this frame against full quality (F9)")
        self.button.setToolTip(
            "Draws this frame again at full quality and shows how far\nthe live picture is from it."
        )
        self.button.clicked.connect(self.measure)
        layout.addWidget(self.button)
        box = QGroupBox("Error against full quality (display values)")
        grid = QGridLayout(box)
        for col, (key, title) in enumerate(METRICS, start=1):
            header = QLabel(title)
            header.setToolTip(TIPS[key])
            grid.addWidget(header, 0, col)
        self.cells: dict[tuple[str, str], QLabel] = {}
        for row, region in enumerate(REGIONS, start=1):
            name = QLabel(REGION_TITLES[region])
            name.setToolTip(TIPS[region])
            grid.addWidget(name, row, 0)
            for col, (key, _title) in enumerate(METRICS, start=1):
                self.cells[region, key] = QLabel("-")
                grid.addWidget(self.cells[region, key], row, col)
        self.fovea_diff = QLabel("-")
        grid.addWidget(
            QLabel("Around the gaze, largest pixel difference"), len(REGIONS) + 1, 0, 1, 2
        )
        grid.addWidget(self.fovea_diff, len(REGIONS) + 1, 2, 1, 2)
        layout.addWidget(box)
        self.heat = QCheckBox(
            "Show the FLIP heat map over the view (F8; dark: no error; "
            "purple, orange, pale yellow: FLIP 0.25 and above)"
        )
        self.heat.setToolTip(
            "Colours the view by how visible the error is at each pixel.\n"
            "Available after a measurement."
        )
        self.heat.setEnabled(False)
        self.heat.toggled.connect(self._toggle_heat)
        layout.addWidget(self.heat)
        self.state = QLabel("Not measured yet.")
        self.state.setWordWrap(True)
        layout.addWidget(self.state)
        note = QLabel(
            "Full quality: finest texture levels, full-rate lighting without a mask, "
            "the photon map gathered for each eye. The heat map shows the measured view "
            "only: it goes away when you move, look elsewhere or change a setting "
            "(F8 measures again and shows it)."
        )
        note.setWordWrap(True)
        layout.addWidget(note)
        layout.addStretch(1)

    def measure(self) -> dict:
        self.report = self._measure() or {}
        for region in REGIONS:
            r = self.report.get(region) or {}
            for key, _title in METRICS:
                self.cells[region, key].setText(_format(key, r.get(key)))
        diff = self.report.get("fovea_max_abs_diff")
        self.fovea_diff.setText("-" if diff is None else f"{diff} of 255")
        has_heat = self.report.get("heat") is not None
        self.heat.setEnabled(has_heat)
        self.heat.blockSignals(True)
        self.heat.setChecked(has_heat)
        self.heat.blockSignals(False)
        self.state.setText("Measured: this view." if self.report else "Nothing to measure.")
        return self.report

    def toggle_heat(self) -> dict:
        """F8: hide the heat map if shown, show it again if the view is still the measured one,
        else measure now (which shows it)."""
        if self.report.get("heat") is not None and self.heat.isEnabled():
            self.heat.setChecked(not self.heat.isChecked())
            return self.report
        return self.measure()

    def heat_cleared(self) -> None:
        """The view changed under the heat map (it dropped it): the map is gone for good; the
        figures stay, marked as those of an earlier view."""
        if self.report.get("heat") is not None:
            self.report = {**self.report, "heat": None}
        self.heat.blockSignals(True)
        self.heat.setChecked(False)
        self.heat.blockSignals(False)
        self.heat.setEnabled(False)
        if self.report:
            self.state.setText(
                "The figures are from an earlier view (you moved, looked elsewhere or changed "
                "a setting); press F9 or F8 to measure this one."
            )

    def _toggle_heat(self, on: bool) -> None:
        self._show_heat(self.report.get("heat") if on else None)


def _format(key: str, value: object) -> str:
    if not isinstance(value, (int, float)) or math.isnan(value):
        return "-"
    if math.isinf(value):
        return "identical"
    return f"{value:.1f}" if key == "psnr_db" else f"{value:.4f}"
