"""``vrpreview survey analyse DIR``: report.md, ssq.png and quality.png for a study folder.

As in the CPS paper (sections 4-5): SSQ scores after each exposure against the baseline
(paired t-test, 95% confidence intervals: Fig. 7) and the quality items per condition (Fig. 8,
p-values). Added: the SSQ change (post minus baseline) per condition, paired tests between
conditions (t-test and Wilcoxon signed-rank; Friedman for more than two conditions) with effect
sizes, order effects, and frame times against sickness. Conditions are unblinded here.
"""

from __future__ import annotations

import io
import itertools
import math
import os
import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from scipy import stats

from app.fileio import atomic_write_bytes, atomic_write_text
from app.stats import summarize
from app.survey.plan import BASELINE
from app.survey.questionnaires import SCORE_KEYS, questionnaire
from app.survey.store import Record, export_csv, read_study

LABELS = {
    "nausea": "Nausea",
    "oculomotor": "Oculomotor",
    "disorientation": "Disorientation",
    "total": "Total",
}


@dataclass
class Describe:
    n: int
    mean: float
    median: float
    sd: float
    ci_lo: float
    ci_hi: float


@dataclass
class Paired:
    """A paired comparison of a against b over the participants who have both."""

    a: str
    b: str
    n: int
    mean_diff: float  # a - b
    t: float
    p_t: float
    dz: float  # Cohen's d for paired data: mean difference / SD of differences
    w: float
    p_w: float
    r_rb: float  # matched-pairs rank-biserial correlation


@dataclass
class AnalysisResult:
    folder: Path
    report: Path
    files: list[Path] = field(default_factory=list)
    participants: int = 0
    complete: int = 0

    def summary(self) -> str:
        names = ", ".join(p.name for p in self.files)
        return (
            f"{self.participants} participants ({self.complete} complete); wrote "
            f"{self.report.name}, {names} in {self.folder}/"
        )


def describe(values: list[float]) -> Describe:
    a = np.asarray(values, np.float64)
    n = len(a)
    if n == 0:
        return Describe(0, *(math.nan,) * 5)
    mean, median = float(a.mean()), float(np.median(a))
    sd = float(a.std(ddof=1)) if n > 1 else math.nan
    if n > 1 and sd > 0:
        half = float(stats.t.ppf(0.975, n - 1)) * sd / math.sqrt(n)
        lo, hi = mean - half, mean + half
    elif n > 1:  # all the same: the interval is the value
        lo = hi = mean
    else:
        lo = hi = math.nan
    return Describe(n, mean, median, sd, lo, hi)


def paired(a_name: str, b_name: str, a: list[float], b: list[float]) -> Paired:
    x, y = np.asarray(a, np.float64), np.asarray(b, np.float64)
    d = x - y
    n = len(d)
    nan = math.nan
    t = p_t = dz = w = p_w = r_rb = nan
    with warnings.catch_warnings(), np.errstate(all="ignore"):
        warnings.simplefilter("ignore")
        if n >= 2:
            sd = float(d.std(ddof=1))
            if sd > 0:
                res = stats.ttest_rel(x, y)
                t, p_t = float(res.statistic), float(res.pvalue)
                dz = float(d.mean()) / sd
            elif d.mean() == 0:
                t, p_t, dz = 0.0, 1.0, 0.0  # identical in every pair
        nz = d[d != 0]
        if len(nz) >= 1:
            try:
                res = stats.wilcoxon(x, y)
                w, p_w = float(res.statistic), float(res.pvalue)
            except ValueError:
                pass
            ranks = stats.rankdata(np.abs(nz))
            plus, minus = ranks[nz > 0].sum(), ranks[nz < 0].sum()
            r_rb = float((plus - minus) / (plus + minus))
        elif n >= 1:
            w, p_w, r_rb = 0.0, 1.0, 0.0
    return Paired(a_name, b_name, n, float(d.mean()) if n else nan, t, p_t, dz, w, p_w, r_rb)


def friedman(columns: list[list[float]]) -> tuple[float, float, float, int]:
    """Friedman chi-square, p and Kendall's W over complete cases (columns = conditions)."""
    n, k = len(columns[0]) if columns else 0, len(columns)
    if k < 3 or n < 2:
        return math.nan, math.nan, math.nan, n
    with warnings.catch_warnings(), np.errstate(all="ignore"):
        warnings.simplefilter("ignore")
        try:
            chi2, p = stats.friedmanchisquare(*columns)
        except ValueError:
            return math.nan, math.nan, math.nan, n
    return float(chi2), float(p), float(chi2) / (n * (k - 1)), n


def f(x: float, digits: int = 2) -> str:
    return "–" if x is None or not math.isfinite(x) else f"{x:.{digits}f}"


def fp(p: float) -> str:
    if p is None or not math.isfinite(p):
        return "–"
    return "<0.001" if p < 0.001 else f"{p:.3f}"


def table(header: list[str], rows: list[list[str]]) -> str:
    out = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    out += ["| " + " | ".join(r) + " |" for r in rows]
    return "\n".join(out)


def _change(r: Record, c: str, key: str) -> float | None:
    if BASELINE in r.ssq and c in r.ssq:
        return r.ssq[c][key] - r.ssq[BASELINE][key]
    return None


def _complete_cases(records: list[Record], conds: Sequence[Any], value) -> list[list[float]]:
    rows = []
    for r in records:
        vals = [value(r, c) for c in conds]
        if all(v is not None for v in vals):
            rows.append(vals)
    return [list(col) for col in zip(*rows)] if rows else [[] for _ in conds]


def analyse(folder: str | os.PathLike[str]) -> AnalysisResult:
    folder = Path(folder)
    study, records = read_study(folder)
    p = study.protocol
    conds = [c.name for c in p.conditions]
    codes = {c.name: c.code for c in p.conditions}
    q_items = questionnaire("quality").items
    has_ssq = "ssq" in p.after_exposure
    has_quality = "quality" in p.after_exposure
    complete = [r for r in records if r.status == "complete"]
    result = AnalysisResult(folder, folder / "report.md")
    result.participants, result.complete = len(records), len(complete)
    result.files += export_csv(folder)

    md = [f"# Study report: {p.name}", ""]
    md.append(
        f"{len(records)} participants ({len(complete)} complete, "
        f"{sum(r.status == 'withdrawn' for r in records)} withdrawn, "
        f"{sum(r.status == 'in progress' for r in records)} unfinished). Scene {p.scene}, "
        f"path {p.path or 'the scene default'}, exposure {p.exposure_s:g} s, rest {p.rest_s:g} s."
    )
    md.append("")
    described = []
    for c in conds:
        shown = ", ".join(f"{k}={v}" for k, v in p.condition(c).settings.items()) or "defaults"
        described.append(f"{codes[c]} = {c} ({shown})")
    md.append(
        "Conditions (unblinded): "
        + ", ".join(described)
        + ". Every participant's data is used wherever it exists; paired tests use the "
        "participants with both values. 95% CI: t-interval of the mean."
    )
    md.append("")
    orders: dict[str, list[str]] = {}
    for r in records:
        orders.setdefault(" → ".join(codes.get(c, "?") for c in r.order), []).append(r.pid)
    md.append("Orders: " + "; ".join(f"{o}: {', '.join(v)}" for o, v in sorted(orders.items())))
    md.append("")

    if has_ssq:
        md += ["## SSQ after each condition (paper Fig. 7)", ""]
        rows = []
        for key in SCORE_KEYS:
            base = describe([r.ssq[BASELINE][key] for r in records if BASELINE in r.ssq])
            rows.append(
                [
                    LABELS[key],
                    "baseline",
                    str(base.n),
                    f(base.mean),
                    f(base.median),
                    f"[{f(base.ci_lo)}, {f(base.ci_hi)}]",
                    "",
                    "",
                    "",
                    "",
                ]
            )
            for c in conds:
                post = describe([r.ssq[c][key] for r in records if c in r.ssq])
                ch = [v for r in records if (v := _change(r, c, key)) is not None]
                d = describe(ch)
                pairs = [
                    (r.ssq[c][key], r.ssq[BASELINE][key])
                    for r in records
                    if c in r.ssq and BASELINE in r.ssq
                ]
                pt = paired(c, BASELINE, [a for a, _ in pairs], [b for _, b in pairs])
                rows.append(
                    [
                        LABELS[key],
                        f"{codes[c]} {c}",
                        str(post.n),
                        f(post.mean),
                        f(post.median),
                        f"[{f(post.ci_lo)}, {f(post.ci_hi)}]",
                        f(d.mean),
                        f(d.median),
                        f"[{f(d.ci_lo)}, {f(d.ci_hi)}]",
                        fp(pt.p_t),
                    ]
                )
        md.append(
            table(
                [
                    "score",
                    "when",
                    "n",
                    "mean",
                    "median",
                    "95% CI",
                    "change mean",
                    "change median",
                    "change 95% CI",
                    "p (paired t, post vs baseline)",
                ],
                rows,
            )
        )
        md.append("")

    if has_quality:
        md += ["## Quality items per condition (paper Fig. 8; 1-5)", ""]
        rows = []
        for item in q_items:
            for c in conds:
                d = describe([r.quality[c][item.id] for r in records if c in r.quality])
                rows.append(
                    [
                        item.id,
                        f"{codes[c]} {c}",
                        str(d.n),
                        f(d.mean),
                        f(d.median),
                        f(d.sd),
                        f"[{f(d.ci_lo)}, {f(d.ci_hi)}]",
                    ]
                )
        md.append(table(["item", "condition", "n", "mean", "median", "SD", "95% CI"], rows))
        md.append("")

    measures: list[tuple[str, object]] = []
    if has_ssq:
        measures += [
            (f"SSQ {LABELS[k]} change", lambda r, c, k=k: _change(r, c, k)) for k in SCORE_KEYS
        ]
    if has_quality:
        measures += [
            (f"quality: {i.id}", lambda r, c, i=i.id: r.quality.get(c, {}).get(i)) for i in q_items
        ]
    pair_p: dict[tuple[str, str, str], float] = {}
    if len(conds) >= 2 and measures:
        md += ["## Paired comparisons between conditions", ""]
        md.append(
            "Difference = first minus second condition. dz = mean difference / SD of the "
            "differences; r = matched-pairs rank-biserial correlation (Wilcoxon)."
        )
        md.append("")
        rows = []
        for name, value in measures:
            for a, b in itertools.combinations(conds, 2):
                cols = _complete_cases(records, [a, b], value)
                pr = paired(a, b, cols[0], cols[1])
                pair_p[(name, a, b)] = pr.p_t
                rows.append(
                    [
                        name,
                        f"{a} − {b}",
                        str(pr.n),
                        f(pr.mean_diff),
                        f(pr.t),
                        fp(pr.p_t),
                        f(pr.dz),
                        f(pr.w, 1),
                        fp(pr.p_w),
                        f(pr.r_rb),
                    ]
                )
        md.append(
            table(
                [
                    "measure",
                    "conditions",
                    "n",
                    "mean diff",
                    "t",
                    "p (t)",
                    "dz",
                    "W",
                    "p (Wilcoxon)",
                    "r",
                ],
                rows,
            )
        )
        md.append("")
        if len(conds) > 2:
            md += ["### Friedman test over all conditions", ""]
            rows = []
            for name, value in measures:
                chi2, pv, kw, n = friedman(_complete_cases(records, conds, value))
                rows.append([name, str(n), f(chi2), fp(pv), f(kw)])
            md.append(table(["measure", "n", "chi²", "p", "Kendall's W"], rows))
            md.append("")

    if has_ssq and len(conds) >= 2:
        md += ["## Order effects", ""]
        md.append("SSQ Total change by run (whatever the condition) and by condition and run.")
        md.append("")
        by_pos = [
            [_change(r, r.order[pos], "total") if pos < len(r.order) else None for r in records]
            for pos in range(len(conds))
        ]
        rows = []
        for pos, vals in enumerate(by_pos):
            d = describe([v for v in vals if v is not None])
            rows.append([f"run {pos + 1}", str(d.n), f(d.mean), f"[{f(d.ci_lo)}, {f(d.ci_hi)}]"])
        md.append(table(["run", "n", "mean change", "95% CI"], rows))
        md.append("")
        both = [(a, b) for a, b in zip(by_pos[0], by_pos[1]) if a is not None and b is not None]
        pr = paired("run 1", "run 2", [a for a, _ in both], [b for _, b in both])
        line = (
            f"Run 1 against run 2 (paired t): n {pr.n}, mean diff {f(pr.mean_diff)}, "
            f"p {fp(pr.p_t)}; Wilcoxon p {fp(pr.p_w)}."
        )
        if len(conds) > 2:
            cols = _complete_cases(
                records,
                list(range(len(conds))),
                lambda r, pos: _change(r, r.order[pos], "total") if pos < len(r.order) else None,
            )
            chi2, pv, kw, n = friedman(cols)
            line += f" Friedman over runs: n {n}, chi² {f(chi2)}, p {fp(pv)}."
        md.append(line)
        md.append("")
        rows = []
        for c in conds:
            cells = []
            for pos in range(len(conds)):
                at_pos = [
                    v
                    for r in records
                    if r.position.get(c) == pos and (v := _change(r, c, "total")) is not None
                ]
                d = describe(at_pos)
                cells.append(f"{f(d.mean)} (n {d.n})")
            rows.append([f"{codes[c]} {c}", *cells])
        md.append(table(["condition", *[f"as run {i + 1}" for i in range(len(conds))]], rows))
        md.append("")

    md += ["## Exposures and frame times", ""]
    rows = []
    points: list[tuple[float, float]] = []
    for c in conds:
        xs = [r.exposures[c] for r in records if c in r.exposures]
        medians = [summarize(x.frame_ms)["median"] for x in xs if x.frame_ms]
        fm = describe(medians)
        fps = 1000.0 / fm.median if fm.n and fm.median > 0 else math.nan
        stopped = sum(x.stopped for x in xs)
        rows.append(
            [
                f"{codes[c]} {c}",
                str(len(xs)),
                str(stopped),
                f(fm.median),
                f(fps, 1),
                f(describe([x.duration_s for x in xs]).mean, 1),
            ]
        )
        for r in records:
            x = r.exposures.get(c)
            change = _change(r, c, "total") if has_ssq else None
            if x is not None and x.frame_ms and change is not None:
                points.append((summarize(x.frame_ms)["median"], change))
    md.append(
        table(
            [
                "condition",
                "exposures",
                "stopped (unwell)",
                "median frame ms",
                "fps",
                "mean duration s",
            ],
            rows,
        )
    )
    md.append("")
    if len(points) >= 3 and len({p_[0] for p_ in points}) > 1 and len({p_[1] for p_ in points}) > 1:
        rho, pv = stats.spearmanr([a for a, _ in points], [b for _, b in points])
        md.append(
            f"SSQ Total change against the exposure's median frame time: Spearman rho "
            f"{f(float(rho))}, p {fp(float(pv))} ({len(points)} exposures)."
        )
    else:
        md.append("Too few or constant values to relate SSQ change to frame time.")
    md.append("")

    plots = []
    if has_ssq:
        plots.append(_plot_ssq(folder / "ssq.png", records, conds, codes))
    if has_quality:
        plots.append(_plot_quality(folder / "quality.png", records, conds, codes, pair_p))
    if plots:
        md += ["## Plots", ""]
        md += [f"![{pl.stem}]({pl.name})" for pl in plots]
        md.append("")
    result.files += plots
    atomic_write_text(result.report, "\n".join(md))
    return result


def _save(fig, path: Path) -> Path:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110)
    return atomic_write_bytes(path, buf.getvalue())


def _bar_group(
    ax, groups: list[str], series: list[tuple[str, list[Describe]]], err: str, first_colour: int = 0
):
    width = 0.8 / max(1, len(series))
    x = np.arange(len(groups))
    for i, (label, ds) in enumerate(series):
        means = [d.mean if math.isfinite(d.mean) else 0.0 for d in ds]
        if err == "ci":
            lo = [d.mean - d.ci_lo if math.isfinite(d.ci_lo) else 0.0 for d in ds]
            hi = [d.ci_hi - d.mean if math.isfinite(d.ci_hi) else 0.0 for d in ds]
            yerr: list[list[float]] | list[float] = [lo, hi]
        else:
            yerr = [d.sd if math.isfinite(d.sd) else 0.0 for d in ds]
        ax.bar(
            x + (i - (len(series) - 1) / 2) * width,
            means,
            width,
            yerr=yerr,
            capsize=3,
            label=label,
            color=f"C{first_colour + i}",  # a condition keeps its colour in every panel
        )
    ax.set_xticks(x, groups)
    ax.legend(fontsize=8)
    return x, width


def _plot_ssq(path: Path, records: list[Record], conds: list[str], codes: dict) -> Path:
    from matplotlib.figure import Figure

    fig = Figure(figsize=(11, 4.2), layout="constrained")
    left, right = fig.subplots(1, 2)
    groups = [LABELS[k] for k in SCORE_KEYS]
    series = [
        (
            "baseline",
            [
                describe([r.ssq[BASELINE][k] for r in records if BASELINE in r.ssq])
                for k in SCORE_KEYS
            ],
        )
    ]
    series += [
        (
            f"{codes[c]} {c}",
            [describe([r.ssq[c][k] for r in records if c in r.ssq]) for k in SCORE_KEYS],
        )
        for c in conds
    ]
    _bar_group(left, groups, series, "ci")
    left.set_title("SSQ before and after each condition (mean, 95% CI)")
    left.set_ylabel("score")
    change = [
        (
            f"{codes[c]} {c}",
            [
                describe([v for r in records if (v := _change(r, c, k)) is not None])
                for k in SCORE_KEYS
            ],
        )
        for c in conds
    ]
    _bar_group(right, groups, change, "ci", first_colour=1)
    right.axhline(0, color="black", linewidth=0.8)
    right.set_title("SSQ change, post minus baseline (mean, 95% CI)")
    return _save(fig, path)


def _plot_quality(
    path: Path, records: list[Record], conds: list[str], codes: dict, pair_p: dict
) -> Path:
    from matplotlib.figure import Figure

    items = questionnaire("quality").items
    fig = Figure(figsize=(9, 4.2), layout="constrained")
    ax = fig.subplots()
    series = [
        (
            f"{codes[c]} {c}",
            [describe([r.quality[c][i.id] for r in records if c in r.quality]) for i in items],
        )
        for c in conds
    ]
    x, width = _bar_group(ax, [i.id.replace("_", " ") for i in items], series, "sd", 1)
    ax.set_ylim(0, 6.2)
    ax.set_ylabel("rating (1-5)")
    ax.set_title(
        "Quality items (mean, SD)" + (f"; p: paired t against {conds[0]}" if len(conds) > 1 else "")
    )
    for j, item in enumerate(items):
        labels = [fp(pair_p.get((f"quality: {item.id}", conds[0], c), math.nan)) for c in conds[1:]]
        if labels:
            ax.text(x[j], 5.7, "p " + ", ".join(labels), ha="center", fontsize=8)
    return _save(fig, path)
