"""The lab's typed results: a benchmark run and its error figures, one spelling per metric
(``psnr_db``, ``ssim``, ``flip``, ``frame_ms``), written as JSON by :func:`write_json`.

The JSON layout is the documented one of ``vrpreview bench`` (``frames``, ``fps_median``,
``frame_ms`` {median, p95, mean}, ``passes``, ``error_vs_full_quality``, ...); readers of
files (:mod:`app.lab.report`, the photon tables, a resumed study) read those keys.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from app.fileio import atomic_write_json
from app.quality import ErrorFigures
from app.stats import summarize


@dataclass(frozen=True)
class FrameTimes:
    """Median, p95 and mean of per-frame (or per-pass) times in milliseconds."""

    median: float = 0.0
    p95: float = 0.0
    mean: float = 0.0
    p99: float = 0.0

    @classmethod
    def of(cls, ms: list[float]) -> FrameTimes:
        p99 = float(np.percentile(np.asarray(ms, np.float64), 99)) if ms else 0.0
        return cls(**summarize(ms), p99=p99 if math.isfinite(p99) else 0.0)

    @property
    def fps(self) -> float:
        """Frames per second at the median frame time (0 when there is none)."""
        return 1000.0 / self.median if self.median > 0 else 0.0


@dataclass(frozen=True)
class FrameBudget:
    """Frame times against the governor's target (``frame_budget`` in the JSON): the share
    of frames over the budget by more than 10%, and what the governor chose."""

    target_fps: float
    budget_ms: float
    median: float
    p95: float
    p99: float
    over_budget_share: float
    governor: dict

    @classmethod
    def of(cls, ms: list[float], target_fps: float, governor: dict) -> FrameBudget:
        budget = 1000.0 / target_fps if target_fps > 0 else 0.0
        times = FrameTimes.of(ms)
        over = sum(m > 1.1 * budget for m in ms) / len(ms) if ms and budget > 0 else 0.0
        return cls(target_fps, budget, times.median, times.p95, times.p99, over, governor)


@dataclass(frozen=True)
class PassTimes:
    median_ms: float
    p95_ms: float


@dataclass(frozen=True)
class GroupTimes:
    """Median frame time of the frames sharing one value (a state, a level, a distance)."""

    frames: int
    frame_ms_median: float
    fps_median: float


@dataclass(frozen=True)
class MeanErrors:
    """Error figures over the compared frames: mean PSNR over the frames that differ
    (identical frames have infinite PSNR), mean SSIM and FLIP."""

    frames: int
    identical_frames: int = 0
    psnr_db: float = math.inf
    ssim: float = math.nan
    flip: float = math.nan

    @classmethod
    def of(cls, rows: list[ErrorFigures]) -> MeanErrors:
        if not rows:
            return cls(0)
        finite = [r.psnr_db for r in rows if math.isfinite(r.psnr_db)]
        return cls(
            frames=len(rows),
            identical_frames=len(rows) - len(finite),
            psnr_db=float(np.mean(finite)) if finite else math.inf,
            ssim=float(np.mean([r.ssim for r in rows])),
            flip=float(np.nanmean([r.flip for r in rows])),
        )

    def to_dict(self) -> dict:
        return asdict(self) if self.frames else {"frames": 0}


REFERENCE_NOTE = (
    "same frame at full quality (TCR off, full-rate lighting, no mask, "
    "converged photon map), display values; fovea/periphery: pixels at "
    "CPS level 0 / above 0 (without CPS: by angle from the gaze alone)"
)


@dataclass
class ErrorVsFullQuality:
    """The error of a run against full quality (``error_vs_full_quality`` in the JSON)."""

    pixels_per_degree: float
    frame: MeanErrors
    gazed_object: MeanErrors
    fovea: MeanErrors | None = None  # None: no compared frame had foveal pixels
    periphery: MeanErrors | None = None
    fovea_max_abs_diff: int | None = None
    by_state: dict[str, dict[str, MeanErrors]] = field(default_factory=dict)
    reference: str = REFERENCE_NOTE

    def to_dict(self) -> dict:
        out: dict = {
            "reference": self.reference,
            "pixels_per_degree": self.pixels_per_degree,
            "frame": self.frame.to_dict(),
            "gazed_object": self.gazed_object.to_dict(),
        }
        for name in ("fovea", "periphery"):
            region = getattr(self, name)
            if region is not None:
                out[name] = region.to_dict()
        out["fovea_max_abs_diff"] = self.fovea_max_abs_diff
        out["by_state"] = {
            state: {k: v.to_dict() for k, v in figures.items()}
            for state, figures in self.by_state.items()
        }
        return out


@dataclass
class BenchResult:
    """One ``vrpreview bench`` run. ``per_frame`` holds one plain record per timed frame
    (its error figures included, as ``ErrorFigures.to_dict``)."""

    scene: dict
    scene_load_s: float  # building or reading the scene (the showroom: its textures)
    path: str
    size: dict
    device: str
    frames: int
    warmup_frames: int
    stride: int
    time_step_s: float
    frame_ms: FrameTimes
    passes: dict[str, PassTimes]
    texture_resident_bytes: int
    texture_resident_bytes_max: int
    shaded_samples: int
    by_state: dict[str, GroupTimes]
    by_gazed_level: dict[str, GroupTimes]
    by_gazed_distance_m: dict[str, GroupTimes]
    settings: dict
    photons: dict | None
    errors: list
    per_frame: list[dict]
    error_vs_full_quality: ErrorVsFullQuality | None = None
    command: str | None = None  # the command that makes the run again (experiments)
    shadows: dict | None = None  # the shadow maps: GPU memory, maps drawn (render.shadows)
    # The geometry drawn: ``triangles_drawn``, ``draw_calls`` and ``draw_ranges`` (index
    # ranges, a multi-draw's commands each counted) per eye (the geometry pass's, median over
    # frames, after culling and levels of detail), ``draw_calls_frame`` (every pass's draws of
    # meshes in a frame, shadow maps included), ``meshes`` and ``merged_groups`` (the
    # material groups the static meshes were merged into, render.gpu_scene.GpuGroup),
    # ``gpu_bytes`` (the vertex, index, sky and object-index buffers on the GPU, each mesh's
    # geometry held once) and ``upload_s`` (building the GpuScene: the upload).
    geometry: dict | None = None
    frame_budget: FrameBudget | None = None  # against render.target_fps (None: fixed)
    refine: dict | None = (
        None  # showroom_stop: refinement after the stop (bench.refine_after_still)
    )

    @property
    def fps_median(self) -> float:
        return self.frame_ms.fps

    def to_dict(self) -> dict:
        """The documented JSON layout."""
        out: dict = {
            "scene": self.scene,
            "scene_load_s": round(self.scene_load_s, 4),
            "path": self.path,
            "size": self.size,
            "device": self.device,
            "frames": self.frames,
            "warmup_frames": self.warmup_frames,
            "stride": self.stride,
            "time_step_s": self.time_step_s,
            "fps_median": self.fps_median,
            "frame_ms": asdict(self.frame_ms),
            "passes": {k: asdict(v) for k, v in self.passes.items()},
            "texture_resident_bytes": self.texture_resident_bytes,
            "texture_resident_bytes_max": self.texture_resident_bytes_max,
            "shaded_samples": self.shaded_samples,
            "by_state": _groups(self.by_state),
            "by_gazed_level": _groups(self.by_gazed_level),
            "by_gazed_distance_m": _groups(self.by_gazed_distance_m),
            "settings": self.settings,
            "photons": self.photons,
            "errors": self.errors,
            "per_frame": self.per_frame,
        }
        if self.error_vs_full_quality is not None:
            out["error_vs_full_quality"] = self.error_vs_full_quality.to_dict()
        if self.refine is not None:
            out["refine"] = self.refine
        if self.command is not None:
            out["command"] = self.command
        if self.shadows is not None:
            out["shadows"] = self.shadows
        if self.geometry is not None:
            out["geometry"] = self.geometry
        if self.frame_budget is not None:
            out["frame_budget"] = asdict(self.frame_budget)
        return out


def _groups(groups: dict[str, GroupTimes]) -> dict[str, dict]:
    return {k: asdict(v) for k, v in groups.items()}


def write_json(path: str | Path, result: BenchResult) -> None:
    """Write a run as JSON, atomically (the one writer of benchmark files)."""
    atomic_write_json(path, result.to_dict())
