"""The speed/accuracy study (``vrpreview study``): a matrix of settings benchmarked on one path,
each against the full-quality frame, written as results.json, results.csv, report.md and a
frame-time-against-error plot with the Pareto front marked.

Resumable: results.json is rewritten after every run, and a run already in it is not run again,
so an interrupted study picks up where it stopped. Errors are computed on display values (what
the user sees) by :func:`app.lab.bench.bench`.
"""

from __future__ import annotations

import csv
import io
import itertools
import json
import math
from collections.abc import Callable
from dataclasses import asdict, dataclass, fields, replace
from pathlib import Path
from typing import TextIO

import numpy as np

from app.fileio import atomic_write_json, atomic_write_png, atomic_write_text
from app.lab.bench import CliBar, TraceProgress, bench
from app.lab.plots import finite, pareto, pareto_plot
from app.lab.reference import ConvergedPhotons
from app.lab.report import markdown
from app.lab.results import BenchResult
from app.lab.runs import Run, bench_run, named_runs

FULL = "full-quality"


@dataclass(frozen=True)
class Matrix:
    """A study's runs, all on one scene and path; the first is the reference (``FULL``)."""

    scene: str
    path: str
    runs: tuple[Run, ...]

    @classmethod
    def of(
        cls,
        scene: str,
        path: str,
        named: list[tuple[str, tuple[str, ...]]],
        frames: int = 0,
        stride: int = 24,
        compare_every: int = 3,
    ) -> Matrix:
        """From (name, --set assignments) pairs sharing the frames, stride and comparison."""
        common = dict(frames=frames, stride=stride, compare_every=compare_every, warmup=3)
        return cls(scene, path, named_runs(scene, path, named, **common))

    @property
    def stride(self) -> int:
        return self.runs[0].stride if self.runs else 1

    @property
    def compare_every(self) -> int:
        return self.runs[0].compare_every if self.runs else 0


def _cps_matrix() -> Matrix:
    runs: list[tuple[str, tuple[str, ...]]] = [(FULL, ("cps.mode=none",))]
    runs += [("black-mask", ("cps.mode=black-mask",)), ("blur-mask", ("cps.mode=blur-mask",))]
    for level, filt, temporal in itertools.product(
        (2, 3, 4, 5), ("none", "hierarchical"), (False, True)
    ):
        name = f"cps-block{1 << level}-{filt}" + ("-temporal" if temporal else "")
        runs.append(
            (
                name,
                (
                    "cps.mode=cps",
                    f"cps.max_level={level}",
                    f"cps.filter={filt}",
                    f"cps.temporal={str(temporal).lower()}",
                ),
            )
        )
    return Matrix.of("corridor", "corridor_walk", runs)


def _tcr_matrix() -> Matrix:
    runs: list[tuple[str, tuple[str, ...]]] = [(FULL, ("tcr.enabled=false",))]
    for preset, mode in itertools.product(("ergonomics", "psychology"), ("clamp", "paper")):
        runs.append(
            (
                f"tcr-{preset}-{mode}",
                ("tcr.enabled=true", f"tcr.preset={preset}", f"tcr.mode={mode}"),
            )
        )
    return Matrix.of("showroom", "showroom_walkthrough", runs, stride=10, compare_every=3)


def _photon_matrix() -> Matrix:
    """Photons emitted x gather radius (and the gather at block rate under CPS), each against
    the converged photon map (app.quality.full_quality): the speed/accuracy curve of the
    indirect light."""
    from app.lab.photon_bench import COUNTS, radius_m

    base = ("photons.enabled=on", "photons.indirect=gather", "photons.stereo_reuse=true")
    runs: list[tuple[str, tuple[str, ...]]] = [
        (
            FULL,
            (
                *base,
                "photons.photons=4194304",
                "photons.radius_m=0.1",
                "photons.stereo_reuse=false",
            ),
        )
    ]
    for (label, count), rho in itertools.product(COUNTS.items(), (0.05, 0.1, 0.2)):
        runs.append(
            (
                f"photons-{label.replace('^', 'p')}-r{radius_m(rho):g}",
                (*base, f"photons.photons={count}", f"photons.radius_m={radius_m(rho)}"),
            )
        )
    runs.append(
        (
            "photons-256p2-r0.2-cps",
            (*base, "photons.photons=65536", "photons.radius_m=0.2", "cps.mode=cps"),
        )
    )
    return Matrix.of("showroom", "showroom_walkthrough", runs, stride=150, compare_every=1)


MATRICES: dict[str, Callable[[], Matrix]] = {
    "cps": _cps_matrix,
    "tcr": _tcr_matrix,
    "photons": _photon_matrix,
}


@dataclass
class StudyRow:
    """One run of a study (a row of results.json / .csv); errors are None where the run
    compared no frame (or the region was empty)."""

    name: str
    settings: str
    frames: int
    fps: float
    frame_ms: float
    p95_ms: float
    speedup: float | None
    psnr_db: float | None
    ssim: float | None
    flip: float | None
    fovea_psnr_db: float | None
    fovea_flip: float | None
    fovea_max_diff: int | None
    periphery_psnr_db: float | None
    periphery_ssim: float | None
    periphery_flip: float | None
    resident_mb: float
    shaded_samples: int

    @classmethod
    def of(cls, run: Run, result: BenchResult) -> StudyRow:
        err = result.error_vs_full_quality
        frame = err.frame if err and err.frame.frames else None
        fovea = err.fovea if err and err.fovea and err.fovea.frames else None
        periphery = err.periphery if err and err.periphery and err.periphery.frames else None
        return cls(
            name=run.name,
            settings=" ".join(run.sets),
            frames=result.frames,
            fps=result.fps_median,
            frame_ms=result.frame_ms.median,
            p95_ms=result.frame_ms.p95,
            speedup=None,
            psnr_db=frame.psnr_db if frame else None,
            ssim=frame.ssim if frame else None,
            flip=frame.flip if frame else None,
            fovea_psnr_db=fovea.psnr_db if fovea else None,
            fovea_flip=fovea.flip if fovea else None,
            fovea_max_diff=err.fovea_max_abs_diff if err else None,
            periphery_psnr_db=periphery.psnr_db if periphery else None,
            periphery_ssim=periphery.ssim if periphery else None,
            periphery_flip=periphery.flip if periphery else None,
            resident_mb=result.texture_resident_bytes / 1e6,
            shaded_samples=result.shaded_samples,
        )


FIELDS = tuple(f.name for f in fields(StudyRow))


def run_study(
    which: str,
    out_dir: str | Path,
    size: str = "1280x720",
    progress: Callable[[int, int, str], None] | None = None,
    matrix: Matrix | None = None,
) -> list[dict]:
    """Run (or resume) a study; ``matrix`` overrides the built-in one named ``which``."""
    matrix = matrix or MATRICES[which]()
    out = Path(out_dir)
    results_file = out / "results.json"
    header = {"study": which, "scene": matrix.scene, "path": matrix.path, "size": size}
    rows: list[dict] = []
    if results_file.exists():
        try:
            rows = json.loads(results_file.read_text(encoding="utf-8")).get("rows", [])
        except (OSError, ValueError):
            rows = []  # unreadable: start again rather than trust half a file
    done = {r["name"] for r in rows}
    converged = ConvergedPhotons(TraceProgress())  # traced once for the whole matrix
    for index, run in enumerate(matrix.runs, start=1):
        if progress:
            progress(index, len(matrix.runs), run.name)
        if run.name in done:
            continue
        result = bench_run(replace(run, size=size), converged, runner=bench)
        rows.append(asdict(StudyRow.of(run, result)))
        atomic_write_json(results_file, header | {"rows": rows})
    full = next((r for r in rows if r["name"] == FULL), None)
    for r in rows:
        r["speedup"] = full["frame_ms"] / r["frame_ms"] if full and r["frame_ms"] else None
    front = pareto(rows)
    atomic_write_json(
        results_file,
        header | {"rows": rows, "pareto": front},
    )
    atomic_write_text(out / "results.csv", to_csv(rows))
    atomic_write_text(out / "report.md", to_markdown(which, matrix, rows, front))
    atomic_write_png(out / "pareto.png", plot(rows, front, f"{which}: {matrix.scene}"))
    return rows


def to_csv(rows: list[dict]) -> str:
    buf = io.StringIO()
    w = csv.DictWriter(buf, FIELDS, lineterminator="\n")
    w.writeheader()
    for r in rows:
        w.writerow({k: r.get(k) for k in FIELDS})
    return buf.getvalue()


def _fmt(v: object, spec: str) -> str:
    if not finite(v):
        return "identical" if v == math.inf else "-"
    return format(v, spec)


def to_markdown(which: str, matrix: Matrix, rows: list[dict], front: list[str]) -> str:
    header = (
        "run",
        "fps",
        "frame ms",
        "speed-up",
        "PSNR dB",
        "SSIM",
        "FLIP",
        "fovea max diff",
        "periphery PSNR dB",
        "periphery FLIP",
        "samples",
    )
    table = [
        [
            r["name"] + (" *" if r["name"] in front else ""),
            _fmt(r["fps"], ".2f"),
            _fmt(r["frame_ms"], ".1f"),
            _fmt(r["speedup"], ".2f"),
            _fmt(r["psnr_db"], ".1f"),
            _fmt(r["ssim"], ".4f"),
            _fmt(r["flip"], ".4f"),
            "-" if r["fovea_max_diff"] is None else str(r["fovea_max_diff"]),
            _fmt(r["periphery_psnr_db"], ".1f"),
            _fmt(r["periphery_flip"], ".4f"),
            str(r["shaded_samples"]),
        ]
        for r in rows
    ]
    return (
        f"# Study `{which}`: {matrix.scene}, path {matrix.path}\n\n"
        f"One frame in {matrix.stride} of the path, one in {matrix.compare_every} of those "
        "compared with the same frame at full quality (finest textures, full-rate "
        "lighting, no mask; indirect light from a converged photon map: 4M paths at "
        "r = 10 cm, each eye gathered); errors on display values. Fovea: pixels CPS keeps "
        "at full rate (without CPS: the same angle around the gaze); periphery: the rest. "
        "`*`: on the Pareto front of frame time against FLIP.\n\n"
        + markdown(header, table)
        + "\n\nPareto front (fastest first): "
        + ", ".join(front)
        + "\n"
    )


def plot(rows: list[dict], front: list[str], title: str, size=(900, 600)) -> np.ndarray:
    """Frame time (x) against FLIP (y): every run a dot, the Pareto front a red step line
    through its runs, named (with full quality and the masks); the other runs' names are in
    report.md. An HxWx3 array."""
    return pareto_plot(rows, front, title, size, named=(FULL, "black-mask", "blur-mask"))


class RunProgress(CliBar):
    """:func:`run_study`'s ``progress(index, total, name)`` (before each run, from 1) as a bar
    of runs with the running one's name; leaving ``with`` shows them all done."""

    def __init__(self, file: TextIO | None = None) -> None:
        super().__init__("study", "run", file, mininterval=0.0)  # a run takes minutes

    def __call__(self, index: int, total: int, name: str) -> None:
        self.count(index - 1, total, name)
