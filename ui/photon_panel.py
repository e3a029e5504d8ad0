"""Photon-mapping panel: the ``photons.*`` settings and live figures.

The controls are generated from the settings model like every other section (count, radius,
gather variant, k, stereo reuse, tolerance, seed, the reuse overlay). Below them, polled at 4 Hz
from a ``stats()`` callable: whether the scene gets indirect light and why, the tracing
progress, photons stored, gather time per eye and the share of right-eye pixels reused.
"""

from __future__ import annotations

from collections.abc import Callable

from PyQt6.QtCore import QTimer
from PyQt6.QtWidgets import QFormLayout, QGroupBox, QLabel, QProgressBar, QVBoxLayout, QWidget

from app.settings import Settings
from ui.panels import SettingsPanel

#: The live figures: (key, title, tooltip).
FIELDS = (
    ("status", "Indirect light", "Whether this scene gets bounced light now, and why."),
    ("stored", "Photons stored", "Photons that landed on surfaces and are kept."),
    ("trace", "Traced in", "How long tracing the photons took (in the background)."),
    (
        "gather",
        "Collecting (both eyes)",
        "Time per frame spent collecting photons, per eye.\nPhoton paper: the gather.",
    ),
    (
        "reuse",
        "Right eye reused",
        "Share of right-eye pixels taken from the left eye.\n"
        "Photon paper: stereo reuse, section 3.3.",
    ),
    (
        "grid",
        "Search grid",
        "The grid the photons are sorted into for the search.\nPhoton paper: hash grid.",
    ),
)


class PhotonPanel(QWidget):
    def __init__(
        self,
        settings: Settings,
        stats: Callable[[], dict],
        on_change: Callable[[str], None] | None = None,
        parent=None,
    ) -> None:
        super().__init__(parent)
        self.stats = stats
        layout = QVBoxLayout(self)
        layout.setContentsMargins(0, 0, 0, 0)
        self.controls = SettingsPanel(settings, ("photons",), on_change)
        layout.addWidget(self.controls, 1)
        box = QGroupBox("Live")
        form = QFormLayout(box)
        self.progress = QProgressBar()
        self.progress.setRange(0, 100)
        self.progress.setFormat("Tracing photons %p%")
        self.progress.setToolTip("Photons are traced in the background; the view keeps going.")
        self.progress.hide()
        form.addRow(self.progress)
        self.labels: dict[str, QLabel] = {}
        for key, title, tip in FIELDS:
            self.labels[key] = QLabel("-")
            self.labels[key].setWordWrap(True)
            self.labels[key].setToolTip(tip)
            name = QLabel(title)
            name.setToolTip(tip)
            form.addRow(name, self.labels[key])
        layout.addWidget(box)
        self.timer = QTimer(self)
        self.timer.timeout.connect(self._tick)
        self.timer.start(250)

    @property
    def on_change(self) -> Callable[[str], None] | None:
        return self.controls.on_change

    def refresh(self) -> None:
        self.controls.refresh()

    def _tick(self) -> None:
        # Only while the tab shows: the reuse share reads the right eye's target back.
        if self.isVisible():
            self.refresh_stats()

    def refresh_stats(self) -> None:
        info = self.stats()
        tracing = info.get("tracing")
        self.progress.setVisible(tracing is not None)
        if tracing is not None:
            self.progress.setValue(int(round(100 * tracing)))
        self.labels["status"].setText(info.get("status", "-"))
        stored = info.get("photons")
        self.labels["stored"].setText("-" if stored is None else f"{stored:,}")
        ms = info.get("trace_ms")
        self.labels["trace"].setText("-" if not ms else f"{ms / 1000:.1f} s")
        gather, eye_ms = info.get("gather_ms"), info.get("eye_ms")
        text = "-" if gather is None else f"{gather:.1f} ms"
        if eye_ms:
            text += f" (left {eye_ms[0]:.1f}, right {eye_ms[1]:.1f})"
        self.labels["gather"].setText(text)
        share = info.get("reuse_share")
        self.labels["reuse"].setText("-" if share is None else f"{100 * share:.1f}% of pixels")
        self.labels["grid"].setText(info.get("grid", "-"))
