"""The papers' experiments as lists of benchmark runs (``vrpreview experiments tcr|cps``).

Each run is one ``vrpreview bench`` with its settings; every result is written as its own
JSON file (the command that makes it again is stored in it) and the tables are printed at the
end through :mod:`app.lab.report`. Runs go one after another: timings of runs that overlap on a
2-core machine mean nothing.
"""

from __future__ import annotations

import json
import logging
from pathlib import Path

from app.fileio import atomic_write_png
from app.lab.bench import CliBar, TraceProgress
from app.lab.photon_bench import table_runs, tables, write_peer
from app.lab.plots import RunTimes, run_times_plot
from app.lab.reference import ConvergedPhotons
from app.lab.report import report
from app.lab.results import write_json
from app.lab.runs import Run, bench_run

log = logging.getLogger(__name__)


def tcr_runs() -> list[Run]:
    """TCR paper: the cube against distance, orbiting (state 1), gaze held (states 2 and 3), and
    the showroom walkthrough; each with TCR off, ergonomics and psychology."""
    presets = (
        ("off", ("tcr.enabled=false",)),
        ("ergonomics", ("tcr.enabled=true", "tcr.preset=ergonomics")),
        ("psychology", ("tcr.enabled=true", "tcr.preset=psychology")),
    )
    runs = []
    for path in ("tcr_cube_distance", "tcr_cube_orbit", "tcr_cube_gaze", "showroom_walkthrough"):
        scene = "showroom" if path == "showroom_walkthrough" else "tcr-cube"
        every = 20 if scene == "showroom" else 30
        for name, sets in presets:
            runs.append(
                Run(
                    f"{path}-{name}",
                    scene,
                    path,
                    sets,
                    compare_every=every,
                    groups=("by_state", "by_gazed_level"),
                )
            )
    return runs


def cps_runs() -> list[Run]:
    """CPS paper on the corridor walk with 100 lights, 2x640x720: Table 1 (the mitigation
    modes), Table 2 (multi-level against single dispatch per maximum block) and the image
    error of the filters and the temporal filter against full-rate lighting."""
    walk = ("corridor", "corridor_walk")
    table1 = (
        ("none-fragment", ("cps.mode=none", "render.lighting=fragment")),
        ("none-compute", ("cps.mode=none", "render.lighting=compute")),
        ("black-mask", ("cps.mode=black-mask", "render.lighting=fragment")),
        ("blur-mask", ("cps.mode=blur-mask", "render.lighting=fragment")),
        ("cps-compute", ("cps.mode=cps", "render.lighting=compute")),
        ("cps-fragment", ("cps.mode=cps", "render.lighting=fragment")),
    )
    # As in the paper every light is evaluated at every pixel (light culling off); then the
    # baseline and CPS once more with tiled light culling, which this app adds.
    paper = ("render.light_culling=false",)
    runs = [
        Run(f"t1-{name}", *walk, (*sets, *paper), frames=0, stride=12, compare_every=4)
        for name, sets in table1
    ]
    runs += [
        Run(
            f"t1c-{name}",
            *walk,
            (*sets, "render.light_culling=true"),
            frames=0,
            stride=12,
            compare_every=4,
        )
        for name, sets in table1
        if name in ("none-fragment", "cps-fragment")
    ]
    for level in range(1, 6):
        for dispatch in ("multi", "single"):
            runs.append(
                Run(
                    f"t2-block{1 << level:02d}-{dispatch}",
                    *walk,
                    (
                        "cps.mode=cps",
                        "render.lighting=compute",
                        f"cps.dispatch={dispatch}",
                        f"cps.max_level={level}",
                        *paper,
                    ),
                    frames=0,
                    stride=12,
                )
            )
    filters = (
        ("raw", ("cps.filter=none",)),
        ("bilinear", ("cps.filter=bilinear",)),
        ("hierarchical", ("cps.filter=hierarchical",)),
        ("hierarchical-temporal", ("cps.filter=hierarchical", "cps.temporal=true")),
        (
            "hierarchical-temporal-noreproject",
            ("cps.filter=hierarchical", "cps.temporal=true", "cps.reproject=false"),
        ),
    )
    for name, sets in filters:
        runs.append(
            Run(
                f"err-{name}",
                *walk,
                ("cps.mode=cps", "render.lighting=fragment", *sets),
                frames=120,
                compare_every=10,
            )
        )
    # The temporal filter when frames are 0.1 s apart (10 fps, about what this machine shows):
    # the history lags 25 cm of walking, which reprojection has to undo.
    for name, sets in filters[3:]:
        runs.append(
            Run(
                f"err10fps-{name}",
                *walk,
                ("cps.mode=cps", "render.lighting=fragment", *sets),
                frames=60,
                stride=6,
                compare_every=5,
            )
        )
    return runs


def photon_runs() -> list[Run]:
    """The photon-mapping paper's Tables 1, 2, 4 and 5 on the showroom walkthrough: 3 frames
    spread over the walk (every 200th), both eyes at 640x720 (see app.lab.photon_bench)."""
    return table_runs()


EXPERIMENTS = {"tcr": tcr_runs, "cps": cps_runs, "photons": photon_runs}


def run_all(which: str, out_dir: str | Path, only: str | None = None) -> str:
    """Run every benchmark of an experiment (names containing ``only``, if given) into
    ``out_dir``, with their frame times plotted in ``frame_times.png``; returns the tables."""
    out = Path(out_dir)
    runs = [r for r in EXPERIMENTS[which]() if not only or only in r.name]
    files: list[str | Path] = []
    times: list[RunTimes] = []
    converged = ConvergedPhotons(TraceProgress())  # traced once for all the runs that compare
    with CliBar(f"experiments {which}", "run", mininterval=0.0) as bar:
        for index, run in enumerate(runs):
            bar.count(index, len(runs), run.name)
            log.info("%s: %s", run.name, run.command())
            result = bench_run(run, converged)
            target = out / f"{run.name}.json"
            write_json(target, result)
            files.append(target)
            times.append(RunTimes.of(run.name, result))
            log.info("%s: %.2f fps, %.1f ms", run.name, result.fps_median, result.frame_ms.median)
    picture = out / "frame_times.png"
    atomic_write_png(picture, run_times_plot(times, f"experiments {which}"))
    text = _tables(which, out, only, runs, files)
    return text + f"\n\nFrame time per run (and error against time) plotted in {picture}\n"


def _tables(
    which: str, out: Path, only: str | None, runs: list[Run], files: list[str | Path]
) -> str:
    if which == "photons":
        # Every run in the folder, so a table can be completed by later --only runs.
        results = {
            f.stem: json.loads(f.read_text(encoding="utf-8"))
            for f in sorted(out.glob("*.json"))
            if f.stem != "peer"
        }
        text = tables(results)
        if not only or "peer" in only:
            log.info("peer comparison with scipy cKDTree")
            text += "\n\n" + write_peer(out)
        return text
    groups = sorted({g for r in runs for g in r.groups})
    return report(files, tuple(groups))
