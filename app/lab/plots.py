"""The lab's plots, drawn with matplotlib (Agg: no display needed) and returned as HxWx3
arrays for :func:`app.fileio.atomic_write_png`: the speed/accuracy plot with its Pareto front
(the study, the experiments) and frame time per run stacked per render pass (the experiments).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from app.frame_log import OTHER, pass_colour, pass_label

PLOT_RUN = "#2a5ac8"  # blue: a run
PLOT_FRONT = "#dc1e1e"  # red: the Pareto front
PLOT_MARKED = "#1e9e3c"  # green: the governor's runs
TARGET_MS = 1000.0 / 30.0  # the 30 fps line (no target frame rate setting exists)


def pareto(rows: list[dict], cost: str = "frame_ms", error: str = "flip") -> list[str]:
    """Names of the rows no other row beats on both frame time and error (lower is better)."""
    ok = [r for r in rows if finite(r.get(cost)) and finite(r.get(error))]
    front = []
    for r in ok:
        dominated = any(
            o[cost] <= r[cost]
            and o[error] <= r[error]
            and (o[cost] < r[cost] or o[error] < r[error])
            for o in ok
        )
        if not dominated:
            front.append(r["name"])
    return sorted(front, key=lambda n: next(r[cost] for r in ok if r["name"] == n))


def finite(v: object) -> bool:
    return isinstance(v, (int, float)) and math.isfinite(v)


@dataclass(frozen=True)
class PlotData:
    """What the study's plot shows: every run with both figures (name, frame ms, FLIP), the
    Pareto front's points fastest first, and the front as a step line (x, y): from each point
    along to the next one's frame time, then down to its error, so everything above and to
    the right of the line is beaten by a run on it."""

    points: tuple[tuple[str, float, float], ...]
    front: tuple[tuple[str, float, float], ...]
    step_x: tuple[float, ...]
    step_y: tuple[float, ...]


def plot_data(rows: list[dict], front: list[str]) -> PlotData:
    pts = tuple(
        (r["name"], float(r["frame_ms"]), float(r["flip"]))
        for r in rows
        if finite(r.get("frame_ms")) and finite(r.get("flip"))
    )
    by_name = {p[0]: p for p in pts}
    on = tuple(by_name[n] for n in front if n in by_name)
    xs: list[float] = []
    ys: list[float] = []
    for i, (_name, x, y) in enumerate(on):
        xs.append(x)
        ys.append(y)
        if i + 1 < len(on):
            xs.append(on[i + 1][1])  # along at this error to the next run's frame time
            ys.append(y)
    return PlotData(pts, on, tuple(xs), tuple(ys))


def pareto_plot(
    rows: list[dict],
    front: list[str],
    title: str,
    size: tuple[int, int] = (900, 600),
    named: tuple[str, ...] = (),
    marked: str | None = None,
) -> np.ndarray:
    """Frame time (x) against FLIP (y): every run a dot, the Pareto front a red step line
    through its runs, which are named (and the runs in ``named``). Runs whose name starts
    with ``marked`` (the governor's) are drawn as green diamonds over the rest. An HxWx3
    array."""
    fig = _figure(size)
    _pareto_axes(fig.subplots(), rows, front, title, named, marked)
    return figure_array(fig)


def _pareto_axes(
    ax: Any, rows: list[dict], front: list[str], title: str, named, marked: str | None = None
) -> None:
    data = plot_data(rows, front)
    ax.set_title(f"{title}: frame time against error (FLIP)")
    ax.set_xlabel("frame time, median (ms)")
    ax.set_ylabel("FLIP error against full quality (0 = identical)")
    ax.grid(True, color="#dddddd", linewidth=0.8)
    ax.set_axisbelow(True)
    others = [p for p in data.points if p not in data.front]
    if others:
        ax.scatter(
            [p[1] for p in others],
            [p[2] for p in others],
            s=30,
            color=PLOT_RUN,
            label="run (not on the front)",
            zorder=3,
        )
    if data.front:
        ax.plot(
            data.step_x,
            data.step_y,
            color=PLOT_FRONT,
            linewidth=1.8,
            label="Pareto front: no run is both faster and more accurate",
            zorder=2,
        )
        ax.scatter(
            [p[1] for p in data.front],
            [p[2] for p in data.front],
            s=42,
            color=PLOT_FRONT,
            label="run on the front",
            zorder=4,
        )
    special = [p for p in data.points if marked and p[0].startswith(marked)]
    if special:
        ax.scatter(
            [p[1] for p in special],
            [p[2] for p in special],
            s=70,
            marker="D",
            color=PLOT_MARKED,
            label=f"{marked}: holds a frame rate",
            zorder=5,
        )
    for name, x, y in data.points:
        on = any(name == p[0] for p in data.front)
        if on or name in named:
            ax.annotate(
                name,
                (x, y),
                xytext=(5, 4),
                textcoords="offset points",
                fontsize=8,
                color=PLOT_FRONT if on else PLOT_RUN,
            )
    target = TARGET_MS
    ax.axvline(target, color="#888888", linestyle="--", linewidth=1, label="33.3 ms: 30 fps")
    if data.points:
        ax.set_xlim(0, max(max(p[1] for p in data.points) * 1.15, target * 1.1))
        ax.set_ylim(0, max(max(p[2] for p in data.points) * 1.15, 1e-3))
        ax.legend(loc="best", fontsize=9)
    else:
        ax.set_xlim(0, target * 1.1)
        ax.text(0.5, 0.5, "no run with both figures", ha="center", transform=ax.transAxes)


@dataclass(frozen=True)
class RunTimes:
    """One benchmark run as the experiments' plot shows it: median and p95 frame time, the
    median GPU time per pass (ms) and the FLIP error against full quality (None: not
    compared)."""

    name: str
    frame_ms: float
    p95_ms: float
    pass_ms: dict[str, float]
    flip: float | None = None

    @classmethod
    def of(cls, name: str, result: Any) -> RunTimes:
        """From an :class:`app.lab.results.BenchResult`."""
        err = result.error_vs_full_quality
        flip = err.frame.flip if err is not None and err.frame.frames else None
        passes = {n: p.median_ms for n, p in result.passes.items()}
        return cls(name, result.frame_ms.median, result.frame_ms.p95, passes, flip)

    def layers(self) -> list[tuple[str, float]]:
        """The bar's parts, bottom to top: the passes, then the rest of the frame."""
        parts = [(n, ms) for n, ms in self.pass_ms.items() if ms > 0]
        rest = self.frame_ms - sum(ms for _, ms in parts)
        return [*parts, (OTHER, max(rest, 0.0))]


def run_times_plot(runs: list[RunTimes], title: str, width: int = 1100) -> np.ndarray:
    """Frame time per run as a horizontal bar stacked per render pass (median GPU time per
    pass, grey: the rest of the frame) with the p95 as a black tick and the 30 fps line; with a
    second panel of frame time against FLIP and its Pareto front when runs were compared."""
    compared = [
        {"name": r.name, "frame_ms": r.frame_ms, "flip": r.flip}
        for r in runs
        if finite(r.flip) and finite(r.frame_ms)
    ]
    height = int(max(420, 90 + 24 * len(runs)))
    fig = _figure((width + (700 if compared else 0), height))
    if compared:
        bars, scatter = fig.subplots(1, 2, width_ratios=(width, 700))
        _pareto_axes(scatter, compared, pareto(compared), "compared runs", ())
    else:
        bars = fig.subplots()
    _bars_axes(bars, runs, title)
    return figure_array(fig)


def _bars_axes(ax: Any, runs: list[RunTimes], title: str) -> None:
    ax.set_title(f"{title}: frame time per run")
    ax.set_xlabel("frame time, median (ms); black tick: 95th percentile")
    ax.grid(True, axis="x", color="#dddddd", linewidth=0.8)
    ax.set_axisbelow(True)
    y = np.arange(len(runs))[::-1]  # the first run at the top
    seen: dict[str, None] = {}
    for yi, run in zip(y, runs):
        left = 0.0
        for name, ms in run.layers():
            ax.barh(
                yi,
                ms,
                left=left,
                height=0.7,
                color=pass_colour(name),
                label=None if name in seen else pass_label(name),
            )
            seen[name] = None
            left += ms
        ax.plot([run.p95_ms, run.p95_ms], [yi - 0.35, yi + 0.35], color="black", linewidth=1.5)
    ax.set_yticks(y, [r.name for r in runs], fontsize=8)
    ax.axvline(TARGET_MS, color="#dc1e1e", linestyle="--", linewidth=1.2, label="33.3 ms: 30 fps")
    top = max([TARGET_MS * 1.1, *(r.p95_ms * 1.05 for r in runs)])
    ax.set_xlim(0, top)
    if runs:
        ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8)
    else:
        ax.text(0.5, 0.5, "no runs", ha="center", transform=ax.transAxes)


def _figure(size: tuple[int, int]) -> Any:
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    dpi = 100
    fig = Figure(figsize=(size[0] / dpi, size[1] / dpi), dpi=dpi, layout="constrained")
    FigureCanvasAgg(fig)
    return fig


def figure_array(fig: Any) -> np.ndarray:
    """The figure drawn, as an HxWx3 uint8 array."""
    fig.canvas.draw()
    return np.asarray(fig.canvas.buffer_rgba())[..., :3].copy()
