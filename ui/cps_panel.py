"""Coarse pixel shading panel: mitigation mode, detail levels, edge rays, pipeline, temporal
filter, the detail visualisation with its legend, and live statistics.

Built on the settings model (controls from :class:`ui.panels.SettingsForm`, every edit through
``Settings.set``, keys ``cps.*``, a refused value shown in the panel);
the live part (share of pixels per level, lighting samples, edge-ray caps and distances) is
polled from a ``stats()`` callable at 4 Hz, so the renderer never pushes into Qt.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable, Sequence
from typing import Any

from PyQt6.QtCore import QRectF, Qt, QTimer
from PyQt6.QtGui import QColor, QPainter, QPen
from PyQt6.QtWidgets import (
    QComboBox,
    QFormLayout,
    QGridLayout,
    QGroupBox,
    QLabel,
    QVBoxLayout,
    QWidget,
)

from app.cps import MAX_LEVEL
from app.settings import Settings
from render.passes import CPS_LEVEL_COLOURS
from ui.panels import SettingsForm, setting_label

log = logging.getLogger(__name__)

LEVELS = MAX_LEVEL + 1  # s = 0..MAX_LEVEL: blocks of 1x1 .. 32x32 pixels
#: The mitigation control: (cps.mode, lighting stage or None for "as it is"), label.
MITIGATIONS = (
    (("none", "fragment"), "None, graphics pipeline (the baseline)"),
    (("none", "compute"), "None, compute shader"),
    (("black-mask", None), "Black mask (darkened edges)"),
    (("blur-mask", None), "Blur mask (blurred edges)"),
    (("cps", "fragment"), "Coarse pixel shading, graphics pipeline"),
    (("cps", "compute"), "Coarse pixel shading, compute (the paper's)"),
)
MITIGATION_TIP = (
    "How the edges of the view are calmed against VR sickness: not at\n"
    "all, darkened, blurred, or lit more coarsely where surfaces are\n"
    "near. The first and last two also choose where the lighting\n"
    "runs. Deferred rendering method only.\n"
    "CPS paper: the comparisons of Table 1."
)
#: Where the lighting runs: CPS follows the deferred lighting stage.
PIPELINE_KEY = "render.lighting"
SIDES = ("left", "right", "bottom")
EYES = ("left eye", "right eye")
NONE = "-"  # shown for a statistic the renderer did not report


def block_label(level: int) -> str:
    n = 1 << level
    return f"{n}×{n}"


def _qcolor(rgb: Sequence[float]) -> QColor:
    r, g, b = (max(0, min(255, round(c * 255))) for c in rgb)
    return QColor(r, g, b)


class LevelShareBar(QWidget):
    """A horizontal bar split into the share of pixels at each detail level, in legend colours."""

    def __init__(self, parent=None) -> None:
        super().__init__(parent)
        self.shares: list[float] | None = None
        self.setMinimumSize(200, 18)
        self.setMaximumHeight(22)

    def set_shares(self, shares: list[float] | None) -> None:
        if shares != self.shares:
            self.shares = shares
            self.update()

    def paintEvent(self, event) -> None:
        p = QPainter(self)
        r = QRectF(0.5, 0.5, self.width() - 1.0, self.height() - 1.0)
        p.fillRect(r, QColor(60, 60, 66))
        if self.shares:
            total = sum(self.shares) or 1.0
            x = r.left()
            for level, share in enumerate(self.shares):
                w = r.width() * share / total
                if w > 0:
                    p.fillRect(QRectF(x, r.top(), w, r.height()), _qcolor(CPS_LEVEL_COLOURS[level]))
                x += w
        p.setPen(QPen(QColor(30, 30, 30), 1))
        p.drawRect(r)
        p.end()


class CpsPanel(QWidget):
    """Every ``cps.*`` setting as a control, the level legend, and the live CPS statistics.

    The pipeline control edits ``cps.pipeline`` where the model has it, else ``render.lighting``
    (the deferred lighting stage that CPS runs in); ``controls`` maps each key to its widget.

        ``stats()`` returns a dict in which any key may be missing: ``level_share`` (6 fractions),
        ``shaded_samples`` and ``full_samples`` (lighting evaluations last frame, and what full rate
        would have cost), ``edge_caps`` and ``edge_distances`` ([[left, right, bottom]] per eye, the
        level cap and the hit distance in metres, inf for no hit).
    """

    def __init__(
        self,
        settings: Settings,
        stats: Callable[[], dict],
        on_change: Callable[[str], None] | None = None,
        parent=None,
    ) -> None:
        super().__init__(parent)
        self.settings = settings
        self.stats = stats
        self.form = SettingsForm(settings, on_change, after_set=self.refresh)
        self._stats_failed = False
        layout = QVBoxLayout(self)
        layout.addWidget(self.form.status)
        add = self.form.add_row

        box = QGroupBox("Mitigation")
        form = QFormLayout(box)
        self.pipeline_key = PIPELINE_KEY
        # The paper's five modes on one control (plus CPS in either pipeline): each entry sets
        # cps.mode and, where it matters, the lighting stage (render.lighting).
        self.mode = QComboBox()
        for data, text in MITIGATIONS:
            self.mode.addItem(text, data)
        self.mode.setToolTip(MITIGATION_TIP)
        self.mode.currentIndexChanged.connect(self._set_mitigation)
        name = QLabel(setting_label(settings, "cps.mode"))
        name.setToolTip(MITIGATION_TIP)
        form.addRow(name, self.mode)
        layout.addWidget(box)
        self.controls: dict[str, QWidget] = {"cps.mode": self.mode}

        box = QGroupBox("Detail levels")
        form = QFormLayout(box)
        levels = {s: block_label(s) for s in range(LEVELS)}
        self.max_level = add(form, "cps.max_level", items=levels)
        self.fovea = add(form, "cps.fovea_deg")
        self.falloff = add(form, "cps.deg_per_level")
        layout.addWidget(box)

        box = QGroupBox("Near surfaces at the edges")
        form = QFormLayout(box)
        self.near = add(form, "cps.near_m")
        self.far = add(form, "cps.far_m")
        self.rays = add(form, "cps.rays_per_side")
        layout.addWidget(box)

        box = QGroupBox("Coarse shading")
        form = QFormLayout(box)
        self.pipeline = add(form, self.pipeline_key)
        self.dispatch = add(form, "cps.dispatch")
        self.filter = add(form, "cps.filter")
        layout.addWidget(box)

        box = QGroupBox("Smoothing over time")
        form = QFormLayout(box)
        self.temporal = add(form, "cps.temporal")
        self.reproject = add(form, "cps.reproject")
        self.history = add(form, "cps.history_weight")
        layout.addWidget(box)

        box = QGroupBox("Detail colours")
        grid = QGridLayout(box)
        self.visualize = self.form.control("cps.visualize")
        grid.addWidget(self.visualize, 0, 0, 1, 6)
        for level, colour in enumerate(CPS_LEVEL_COLOURS[:LEVELS]):
            swatch = QLabel()
            swatch.setFixedSize(18, 14)
            r, g, b = (round(c * 255) for c in colour)
            swatch.setStyleSheet(f"background: rgb({r},{g},{b}); border: 1px solid #444")
            swatch.setToolTip(f"Blocks of {block_label(level)} pixels share one lighting result")
            row, col = 1 + level // 3, (level % 3) * 2
            grid.addWidget(swatch, row, col)
            text = f"{block_label(level)} (unpainted)" if level == 0 else block_label(level)
            grid.addWidget(QLabel(text), row, col + 1)
        layout.addWidget(box)

        box = QGroupBox("Live")
        live = QGridLayout(box)
        live.addWidget(QLabel("Share of pixels per block size"), 0, 0, 1, 4)
        self.share_bar = LevelShareBar()
        live.addWidget(self.share_bar, 1, 0, 1, 4)
        self.share_label = QLabel(NONE)
        live.addWidget(self.share_label, 2, 0, 1, 4)
        live.addWidget(QLabel("Lighting computed"), 3, 0)
        self.samples_label = QLabel(NONE)
        live.addWidget(self.samples_label, 3, 1, 1, 3)
        live.addWidget(QLabel("Edges: coarsest block allowed / nearest surface"), 4, 0, 1, 4)
        for col, side in enumerate(SIDES, start=1):
            live.addWidget(QLabel(side), 5, col)
        self.edge_labels: list[list[QLabel]] = []
        for row, eye in enumerate(EYES, start=6):
            live.addWidget(QLabel(eye), row, 0)
            cells = []
            for col in range(1, len(SIDES) + 1):
                cell = QLabel(NONE)
                cell.setToolTip(
                    "The coarsest block this side of the eye may use, and how far\n"
                    "away the nearest surface along its edge is (none: open space)."
                )
                live.addWidget(cell, row, col)
                cells.append(cell)
            self.edge_labels.append(cells)
        for label in (self.share_label, self.samples_label):
            label.setTextInteractionFlags(Qt.TextInteractionFlag.TextSelectableByMouse)
        layout.addWidget(box)
        layout.addStretch(1)
        self.controls.update(self.form.editors)

        self.refresh()
        self.poll()
        self.timer = QTimer(self)
        self.timer.timeout.connect(self.poll)
        self.timer.start(250)

    # -- model <-> widgets ---------------------------------------------------------------------

    @property
    def on_change(self) -> Callable[[str], None] | None:
        return self.form.on_change

    @on_change.setter
    def on_change(self, callback: Callable[[str], None] | None) -> None:
        self.form.on_change = callback

    def _set_mitigation(self, index: int) -> None:
        mode, lighting = self.mode.itemData(index)
        if lighting is not None and self.settings.get(self.pipeline_key) != lighting:
            if not self.form.set(self.pipeline_key, lighting):
                return
        self.form.set("cps.mode", mode)

    def _mitigation_index(self) -> int:
        mode, lighting = self.settings.cps.mode, self.settings.get(self.pipeline_key)
        for i, (m, stage) in enumerate(data for data, _ in MITIGATIONS):
            if m == mode and stage in (None, lighting):
                return i
        return -1

    def refresh(self) -> None:
        """Show the model's values (after a change here, a preset load, or the CLI)."""
        c = self.settings.cps
        self.form.refresh()
        self.mode.blockSignals(True)
        self.mode.setCurrentIndex(self._mitigation_index())
        self.mode.blockSignals(False)
        # Controls that mean nothing in the current configuration are greyed out, not hidden.
        self.dispatch.setEnabled(self.settings.get(self.pipeline_key) == "compute")
        self.reproject.setEnabled(c.temporal)
        self.history.setEnabled(c.temporal)

    def poll(self) -> None:
        """Read the live statistics (called by the 4 Hz timer)."""
        try:
            data = self.stats() or {}
            if not isinstance(data, dict):
                raise TypeError(f"stats() returned {type(data).__name__}, not a dict")
        except Exception as exc:  # noqa: BLE001 - a failing source must not break the UI
            if not self._stats_failed:
                log.warning("CPS statistics unavailable: %s", exc)
                self._stats_failed = True
            data = {}
        shares = _shares(data.get("level_share"))
        self.share_bar.set_shares(shares)
        if shares is None:
            self.share_label.setText(NONE)
        else:
            parts = [f"{block_label(s)}\u00a0{100 * v:.0f}%" for s, v in enumerate(shares)]
            self.share_label.setText("   ".join(parts[:3]) + "\n" + "   ".join(parts[3:]))
        self.samples_label.setText(
            _samples_text(data.get("shaded_samples"), data.get("full_samples"))
        )
        caps, dists = data.get("edge_caps"), data.get("edge_distances")
        for eye, cells in enumerate(self.edge_labels):
            for side, cell in enumerate(cells):
                cell.setText(_edge_text(_item(caps, eye, side), _item(dists, eye, side)))


# -- formatting (any statistic may be missing or malformed: then it shows "-") -----------------


def _number(value: Any) -> float | None:
    if isinstance(value, bool):
        return None
    try:
        out = float(value)
    except (TypeError, ValueError):
        return None
    return None if math.isnan(out) else out


def _shares(value: Any) -> list[float] | None:
    try:
        shares = [_number(v) for v in value]
    except TypeError:
        return None
    if len(shares) != LEVELS or any(v is None or v < 0 or math.isinf(v) for v in shares):
        return None
    return [float(v) for v in shares]  # type: ignore[arg-type]


def _samples_text(shaded: Any, full: Any) -> str:
    s, f = _number(shaded), _number(full)
    if s is None or math.isinf(s):
        return NONE
    text = f"{int(s):,}"
    if f is not None and math.isfinite(f) and f > 0:
        text += f" of {int(f):,} ({100 * s / f:.1f}%)"
    return text


def _item(grid: Any, eye: int, side: int) -> Any:
    try:
        return grid[eye][side]
    except (TypeError, IndexError, KeyError):
        return None


def _edge_text(cap: Any, dist: Any) -> str:
    c, d = _number(cap), _number(dist)
    if c is None and d is None:
        return NONE
    cap_text = NONE if c is None or not 0 <= c < LEVELS else block_label(int(c))
    if d is None:
        dist_text = NONE
    elif math.isinf(d):
        dist_text = "none"
    else:
        dist_text = f"{d:.2f} m"
    return f"{cap_text} / {dist_text}"
