"""``vrpreview study governor``: the governor's error table measured, and the governor against
fixed presets at equal frame time.

Two parts, both on the showroom walk and both resumable (each is a :mod:`app.lab.study`
matrix in its own folder):

1. ``errors/``: every knob step of :data:`app.governor_model.KNOBS` alone, over a few frames of the
   walk, each against the full-quality frame. The FLIP of each step (whole frame, fovea and
   periphery) becomes ``governor_errors.json``, the table the governor reads
   (:func:`app.governor.load_error_table`; the one shipped in ``app/`` was made by this
   command). A knob that only acts on top of another (the fovea's size and falloff act only
   under coarse lighting; the texture bias only with TCR) is measured on that base and
   counted from it.
2. The study itself: full quality, a few fixed presets, and for each preset the governor
   asked for that preset's frame rate (``render.target_fps`` = 1000 / its median frame
   time), so each pair compares at about equal mean frame time. ``report.md`` adds the pair
   table (periphery and fovea FLIP), ``pareto.png`` marks the governor's points.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from app.fileio import atomic_write_json, atomic_write_png, atomic_write_text
from app.governor import KNOBS, Knob, step_weight
from app.lab.plots import pareto, pareto_plot
from app.lab.report import markdown
from app.lab.study import FULL, Matrix, run_study, to_markdown

SCENE, PATH = "showroom", "showroom_walkthrough"
#: Every run starts from the window's defaults at fixed settings.
BASE = ("render.target_fps=0",)
#: Fixed presets a user might pick by hand to go faster (name, assignments).
PRESETS: tuple[tuple[str, tuple[str, ...]], ...] = (
    ("preset-scale-77", ("render.scale=0.77",)),
    ("preset-scale-59", ("render.scale=0.59",)),
    ("preset-cps-block8", ("cps.mode=cps", "cps.max_level=3")),
    ("preset-cps16-scale-67", ("cps.mode=cps", "cps.max_level=4", "render.scale=0.67")),
    ("preset-hard-lod4-scale-50", ("render.shadows=hard", "render.lod_bias=4", "render.scale=0.5")),
)
GOVERNOR = "governor"
#: Untimed frames the governor walks before its timed ones: it starts from full quality and
#: settles in a few changes of MIN_FRAMES each; the fixed presets need none. Then the 3
#: warm-up frames of every run. The study compares the settled governor with each preset.
SETTLE_FRAMES = 48
#: The base a knob is measured on, where it acts only on top of another setting.
KNOB_BASE: dict[str, tuple[str, ...]] = {
    "cps.fovea_deg": ("cps.mode=cps", "cps.max_level=4"),
    "cps.deg_per_level": ("cps.mode=cps", "cps.max_level=4"),
    "tcr.level_bias": ("tcr.enabled=true",),
    "render.upscaler": ("render.scale=0.67",),  # the enlarging acts only on a scaled picture
}


#: Steps the full-quality reference cannot measure: it keeps a run's own shadows and
#: reflections off (a user who turned them off compares like with like), so no shadows would
#: be measured against no shadows and cost nothing. Their priors stand
#: (app.governor_model.PRIOR_KNOBS).
UNMEASURED = {("render.shadows", "off"), ("render.reflections", "off")}


def _assign(step: dict[str, Any]) -> tuple[str, ...]:
    def text(v: Any) -> str:
        return str(v).lower() if isinstance(v, bool) else str(v)

    return tuple(f"{k}={text(v)}" for k, v in step.items())


def _base_name(key: str) -> str:
    return "base " + " ".join(KNOB_BASE[key])


def step_name(knob: Knob, step: dict[str, Any]) -> str:
    return f"{knob.key}={step[knob.key]}"


def error_matrix(frames: int = 6, stride: int = 60) -> Matrix:
    """Full quality, the bases of :data:`KNOB_BASE`, and every knob step alone."""
    named: list[tuple[str, tuple[str, ...]]] = [(FULL, BASE)]
    for key, base in KNOB_BASE.items():
        if any(k.key == key for k in KNOBS) and all(n != _base_name(key) for n, _ in named):
            named.append((_base_name(key), (*BASE, *base)))
    for knob in KNOBS:
        base = KNOB_BASE.get(knob.key, ())
        for step in knob.steps:
            named.append((step_name(knob, step), (*BASE, *base, *_assign(step))))
    return Matrix.of(SCENE, PATH, named, frames=frames, stride=stride, compare_every=1)


def _figures(row: dict[str, Any]) -> dict[str, float]:
    def f(key: str) -> float:
        v = row.get(key)
        return float(v) if isinstance(v, (int, float)) and np.isfinite(v) else 0.0

    return {
        "flip": f("flip"),
        "fovea_flip": f("fovea_flip"),
        "periphery_flip": f("periphery_flip"),
        "frame_ms": f("frame_ms"),
    }


def error_table(rows: list[dict[str, Any]], scene: str = SCENE, path: str = PATH) -> dict:
    """The governor's table from :func:`error_matrix`'s rows: per knob key, per step value,
    the figures of the step and its ``weight`` counted from its base
    (:func:`app.governor.step_weight`)."""
    by_name = {r["name"]: r for r in rows}
    full = _figures(by_name[FULL]) if FULL in by_name else None
    knobs: dict[str, list[dict[str, Any]]] = {}
    for knob in KNOBS:
        base_row = by_name.get(_base_name(knob.key)) if knob.key in KNOB_BASE else None
        base = _figures(base_row) if base_row else full
        out = []
        for step in knob.steps:
            row = by_name.get(step_name(knob, step))
            if (knob.key, step[knob.key]) in UNMEASURED:
                break  # this step and those beyond keep their priors (measured_knobs)
            if row is None or base is None:
                continue
            fig = _figures(row)
            out.append(
                {
                    "value": step[knob.key],
                    **{k: round(v, 6) for k, v in fig.items()},
                    "weight": round(max(0.0, step_weight(fig) - step_weight(base)), 6),
                }
            )
        if out:
            knobs[knob.key] = out
    return {"scene": scene, "path": path, "knobs": knobs}


def governor_runs(presets: list[dict[str, Any]]) -> list[tuple[str, tuple[str, ...]]]:
    """For each measured preset row, the governor held at that preset's frame rate."""
    out: list[tuple[str, tuple[str, ...]]] = []
    for row in presets:
        ms = row.get("frame_ms")
        if not isinstance(ms, (int, float)) or not ms > 0:
            continue
        fps = 1000.0 / float(ms)
        out.append((f"{GOVERNOR} @ {row['name']}", (f"render.target_fps={fps:.3f}",)))
    return out


#: A governor run whose mean frame time is further than this from its preset's (a share) is
#: run once more, asked for the rate that would bring it there (:func:`matched_runs`).
MATCH_TOLERANCE = 0.05
MATCHED = "matched"


def matched_runs(rows: list[dict[str, Any]]) -> list[tuple[str, tuple[str, ...]]]:
    """For each preset whose governor ran off its frame time, the governor asked once more for
    the rate scaled by how far off it ran (one secant step towards equal mean frame time).

    The governor aims below the asked time by its frames' spread so that 95 % of frames fit,
    and its steps are discrete: asked for a preset's rate it may run 20 % faster, and the
    error read at the preset's time then rests on a straight line to a much slower run."""
    by_name = {r["name"]: r for r in rows}
    out: list[tuple[str, tuple[str, ...]]] = []
    for name, _sets in PRESETS:
        p, g = by_name.get(name), by_name.get(f"{GOVERNOR} @ {name}")
        if p is None or g is None:
            continue
        times = [p.get("frame_ms"), g.get("frame_ms")]
        if not all(isinstance(v, (int, float)) and np.isfinite(v) and v > 0 for v in times):
            continue
        p_ms, g_ms = (float(v) for v in times)  # type: ignore[arg-type]
        ratio = g_ms / p_ms
        if abs(ratio - 1.0) <= MATCH_TOLERANCE:
            continue
        fps = 1000.0 / p_ms * ratio
        out.append((f"{GOVERNOR} @ {name} {MATCHED}", (f"render.target_fps={fps:.3f}",)))
    return out


def _nearest_governor(rows: list[dict[str, Any]], name: str, ms: float) -> dict[str, Any] | None:
    """The governor run for preset ``name`` (first or matched) whose frame time is nearest
    ``ms``."""
    runs = [
        r
        for r in rows
        if r["name"] in (f"{GOVERNOR} @ {name}", f"{GOVERNOR} @ {name} {MATCHED}")
        and isinstance(r.get("frame_ms"), (int, float))
    ]
    return min(runs, key=lambda r: abs(float(r["frame_ms"]) - ms), default=None)


def governor_curve(rows: list[dict[str, Any]], key: str) -> list[tuple[float, float]]:
    """The governor's (frame ms, ``key``) points, by frame time, ending at full quality (the
    governor with all the time it wants draws it: error 0)."""
    points = []
    for r in rows:
        ms, v = r.get("frame_ms"), r.get(key)
        if r["name"].startswith(GOVERNOR) or r["name"] == FULL:
            value = 0.0 if r["name"] == FULL else v
            if isinstance(ms, (int, float)) and isinstance(value, (int, float)):
                if np.isfinite(ms) and np.isfinite(value):
                    points.append((float(ms), float(value)))
    return sorted(points)


def at_time(curve: list[tuple[float, float]], ms: float) -> float | None:
    """The curve's value at ``ms``, linear between the two points around it; None outside it
    (no extrapolation: the governor was not measured there)."""
    if not curve or not curve[0][0] <= ms <= curve[-1][0]:
        return None
    xs, ys = zip(*curve)
    return float(np.interp(ms, xs, ys))


def pairs(rows: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """Each preset beside the governor held at its frame rate, and the governor's error at
    the preset's own frame time (interpolated along the governor's runs): the fair pair when
    the governor did not run at exactly the preset's time."""
    by_name = {r["name"]: r for r in rows}
    periphery = governor_curve(rows, "periphery_flip")
    fovea = governor_curve(rows, "fovea_flip")
    out = []
    for name, _sets in PRESETS:
        p = by_name.get(name)
        if p is None:
            continue
        ms = float(p["frame_ms"])
        g = _nearest_governor(rows, name, ms)
        if g is None:
            continue
        out.append(
            {
                "preset": name,
                "preset_ms": p["frame_ms"],
                "governor_ms": g["frame_ms"],
                "preset_periphery_flip": p["periphery_flip"],
                "governor_periphery_flip": g["periphery_flip"],
                "preset_fovea_flip": p.get("fovea_flip"),
                "governor_fovea_flip": g.get("fovea_flip"),
                "governor_periphery_flip_at_preset_ms": at_time(periphery, ms),
                "governor_fovea_flip_at_preset_ms": at_time(fovea, ms),
            }
        )
    return out


def _pairs_markdown(table: list[dict[str, Any]]) -> str:
    def num(v: Any, spec: str) -> str:
        if isinstance(v, (int, float)) and np.isfinite(v):
            return format(v, spec)
        return "identical" if v == float("inf") else "-"

    header = (
        "preset",
        "preset ms",
        "governor ms",
        "preset periphery FLIP",
        "governor periphery FLIP",
        "preset fovea FLIP",
        "governor fovea FLIP",
        "governor periphery FLIP at the preset's ms",
        "governor fovea FLIP at the preset's ms",
    )
    body = [
        [
            t["preset"],
            num(t["preset_ms"], ".1f"),
            num(t["governor_ms"], ".1f"),
            num(t["preset_periphery_flip"], ".4f"),
            num(t["governor_periphery_flip"], ".4f"),
            num(t["preset_fovea_flip"], ".4f"),
            num(t["governor_fovea_flip"], ".4f"),
            num(t["governor_periphery_flip_at_preset_ms"], ".4f"),
            num(t["governor_fovea_flip_at_preset_ms"], ".4f"),
        ]
        for t in table
    ]
    return (
        "\n## The governor at each preset's frame rate\n\n"
        "Each fixed preset, and the governor asked for that preset's frame rate "
        "(render.target_fps = 1000 / the preset's median frame time), and where it ran more "
        "than 5 % off that time, once more at the rate scaled by how far off it ran "
        "('matched'); the governor columns show whichever of its runs came nearest the "
        "preset's time. Lower periphery FLIP and fovea FLIP are better. The last two "
        "columns read the governor's error at the preset's own frame time, linear "
        "between the governor's runs around it (and full quality, error 0, at its time); "
        "'-' where no run brackets it.\n\n" + markdown(header, body) + "\n"
    )


def run_governor_study(
    out_dir: str | Path,
    size: str = "1280x720",
    progress: Callable[[int, int, str], None] | None = None,
    errors: Matrix | None = None,
    frames: int = 0,
    stride: int = 10,
    compare_every: int = 3,
) -> list[dict[str, Any]]:
    """Both parts (see the module's text); returns the second part's rows."""
    out = Path(out_dir)
    err_rows = run_study(
        "governor-errors", out / "errors", size, progress, errors or error_matrix()
    )
    atomic_write_json(out / "governor_errors.json", error_table(err_rows))
    common = dict(frames=frames, stride=stride, compare_every=compare_every)
    fixed = [(FULL, BASE), *((n, (*BASE, *s)) for n, s in PRESETS)]
    rows = run_study("governor", out, size, progress, Matrix.of(SCENE, PATH, fixed, **common))
    presets = [r for r in rows if r["name"].startswith("preset-")]
    matrix = Matrix.of(SCENE, PATH, [*fixed, *governor_runs(presets)], **common)
    matrix = replace(
        matrix,
        runs=tuple(
            replace(r, settle=SETTLE_FRAMES) if r.name.startswith(GOVERNOR) else r
            for r in matrix.runs
        ),
    )
    rows = run_study("governor", out, size, progress, matrix)
    matched = matched_runs(rows)
    if matched:
        extra = Matrix.of(SCENE, PATH, matched, **common)
        matrix = replace(
            matrix, runs=matrix.runs + tuple(replace(r, settle=SETTLE_FRAMES) for r in extra.runs)
        )
        rows = run_study("governor", out, size, progress, matrix)
    front = pareto(rows)
    table = pairs(rows)
    atomic_write_json(out / "pairs.json", {"pairs": table})
    atomic_write_text(
        out / "report.md", to_markdown("governor", matrix, rows, front) + _pairs_markdown(table)
    )
    named = tuple(r["name"] for r in rows if r["name"].startswith(GOVERNOR)) + (FULL,)
    atomic_write_png(
        out / "pareto.png",
        pareto_plot(rows, front, f"governor: {SCENE}", named=named, marked=GOVERNOR),
    )
    return rows
