"""One named benchmark run: the unit of the experiments, the study and the photon tables.

A :class:`Run` is one ``vrpreview bench`` with its settings; :meth:`Run.command` is the command
line that makes it again (stored in its JSON file), :func:`bench_run` runs it.
"""

from __future__ import annotations

import shlex
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field

from app.frame import parse_size
from app.lab.bench import bench
from app.lab.reference import ConvergedPhotons
from app.lab.results import BenchResult
from app.scenes import resolve_path
from app.settings import Settings


@dataclass(frozen=True)
class Run:
    name: str
    scene: str
    path: str
    sets: tuple[str, ...]  # --set assignments
    frames: int = 0
    stride: int = 1
    compare_every: int = 0
    size: str = "1280x720"
    groups: tuple[str, ...] = field(default=())  # per-frame groupings the report lists
    warmup: int = 5
    settle: int = 0  # untimed frames walked first (app.lab.bench.bench)

    def settings(self) -> Settings:
        settings = Settings()
        settings.apply(list(self.sets))
        return settings

    def command(self) -> str:
        parts = [
            "vrpreview",
            "bench",
            "--scene",
            self.scene,
            "--path",
            self.path,
            "--size",
            self.size,
            "--frames",
            str(self.frames),
            "--warmup",
            str(self.warmup),
        ]
        if self.settle > 0:
            parts += ["--settle", str(self.settle)]
        if self.stride > 1:
            parts += ["--stride", str(self.stride)]
        if self.compare_every:
            parts += ["--compare-every", str(self.compare_every)]
        for s in self.sets:
            parts += ["--set", s]
        return shlex.join(parts)


def named_runs(
    scene: str, path: str, named: Iterable[tuple[str, tuple[str, ...]]], **common: object
) -> tuple[Run, ...]:
    """Runs on one scene and path from (name, --set assignments) pairs, sharing ``common``
    fields (frames, stride, compare_every, ...)."""
    return tuple(Run(name, scene, path, tuple(sets), **common) for name, sets in named)  # type: ignore[arg-type]


def bench_run(
    run: Run,
    converged: ConvergedPhotons | None = None,
    runner: Callable[..., BenchResult] = bench,
) -> BenchResult:
    """Run ``run`` (through ``runner``, :func:`app.lab.bench.bench` unless given); the
    converged photon map of the reference comes from ``converged`` (shared by a set of runs)."""
    result = runner(
        run.scene,
        parse_size(run.size),
        run.frames,
        run.settings(),
        run.warmup,
        resolve_path(run.path),
        None,
        run.compare_every,
        run.stride,
        converged,
        run.settle,
    )
    result.command = run.command()
    return result
