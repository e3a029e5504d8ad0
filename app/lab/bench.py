"""Headless runs: one frame to PNG, the benchmark (JSON), and the no-display demo.

Every run steps the recorded path by a fixed time step, so frame N is the same image on every
run and machine; only the timings vary.
"""

from __future__ import annotations

import contextlib
import logging
import sys
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any, TextIO, TypeVar

import numpy as np

from app import metrics, scenes
from app.fileio import atomic_write_json, atomic_write_png
from app.governor import Governor, target_fps
from app.lab.reference import BenchReference, ConvergedPhotons
from app.lab.results import (
    BenchResult,
    ErrorVsFullQuality,
    FrameBudget,
    FrameTimes,
    GroupTimes,
    MeanErrors,
    PassTimes,
)
from app.loaders import LoadOptions
from app.overlay_text import text_image
from app.paths import FIXED_DT, SHOWROOM_STOP, SHOWROOM_STOP_AT_S, CameraPath
from app.progress import Progress as LoadProgress
from app.quality import FrameErrors
from app.session import Session
from app.settings import Settings
from app.stats import overlay_lines, summarize

log = logging.getLogger(__name__)
Progress = Callable[[int, int], None]


def _open(
    scene_name: str, size: tuple[int, int], settings: Settings, path: CameraPath | None = None
):
    from render.offscreen import OffscreenHost  # GL only when a run really renders

    start = time.perf_counter()
    with cli_load_progress(scene_name) as progress:
        scene = scenes.resolve(scene_name, LoadOptions.from_settings(settings.scene), progress)
    load_s = time.perf_counter() - start
    session = Session(settings)
    session.set_scene(scene, path)
    host = OffscreenHost(*size, settings, trace_progress=TraceProgress())
    host.renderer.photons.measure = True  # per-eye gather time (waits for the GPU per eye)
    host.set_scene(scene)
    return scene, session, host, load_s


@contextlib.contextmanager
def cli_load_progress(name: str) -> Iterator[LoadProgress]:
    """A tqdm bar on stderr for loading ``name`` (shown only on a terminal: logs stay clean)."""
    from tqdm import tqdm

    with tqdm(
        total=100, desc=f"loading {Path(name).name}", unit="%", disable=None, leave=False
    ) as bar:

        def report(fraction: float, text: str) -> None:
            bar.set_postfix_str(text, refresh=False)
            bar.update(round(100 * fraction) - bar.n)

        yield LoadProgress(report)


_Bar = TypeVar("_Bar", bound="CliBar")


class CliBar:
    """A tqdm bar with an ETA on stderr, shown only when stderr is a terminal (logs and tests
    stay clean). Made on the first report, closed by the last one or on leaving ``with``."""

    def __init__(
        self, desc: str, unit: str, file: TextIO | None = None, mininterval: float = 0.1
    ) -> None:
        self.desc = desc
        self.unit = unit
        self.file = file
        self.mininterval = mininterval  # seconds between redraws (0: every report)
        self.bar_format: str | None = None  # tqdm's own unless a subclass says otherwise
        self.bar: Any = None

    def count(self, done: int, total: int, text: str = "") -> None:
        """``done`` of ``total`` finished; ``text`` names what is running."""
        from tqdm import tqdm

        if self.bar is None or self.bar.total != total:
            self.close()
            self.bar = tqdm(
                total=total,
                desc=self.desc,
                unit=self.unit,
                file=self.file or sys.stderr,
                disable=None,  # None: off unless the stream is a terminal
                dynamic_ncols=True,
                mininterval=self.mininterval,
                bar_format=self.bar_format,
            )
        if text:
            self.bar.set_postfix_str(text, refresh=False)
        self.bar.update(max(0, min(done, total)) - self.bar.n)
        if done >= total:
            self.close()

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()
            self.bar = None

    def finish(self) -> None:
        """Everything done: the bar shows its total, then closes."""
        if self.bar is not None:
            self.count(self.bar.total, self.bar.total)

    def __enter__(self: _Bar) -> _Bar:
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        if exc_type is None:
            self.finish()
        self.close()


class FrameProgress(CliBar):
    """``progress(done, total)`` of a benchmark or walkthrough, as a bar of frames."""

    def __init__(self, desc: str, file: TextIO | None = None, mininterval: float = 0.1) -> None:
        super().__init__(desc, "frame", file, mininterval)

    def __call__(self, done: int, total: int) -> None:
        self.count(done, total)


class TraceProgress(CliBar):
    """Photon tracing's ``progress(fraction)`` as a bar of percent."""

    def __init__(self, file: TextIO | None = None, mininterval: float = 0.1) -> None:
        super().__init__("tracing photons", "%", file, mininterval)
        self.bar_format = "{desc}: {percentage:3.0f}%|{bar}| [{elapsed}<{remaining}]"
        self.last = -1

    def __call__(self, fraction: float) -> None:
        percent = round(100 * min(max(fraction, 0.0), 1.0))
        if percent != self.last:  # a trace reports 1.0 once more when it is done
            self.last = percent
            self.count(percent, 100)


def render_frame(
    scene_name: str,
    out: str | Path,
    size: tuple[int, int],
    frame: int,
    settings: Settings,
    path: CameraPath | None = None,
) -> np.ndarray:
    """Render frame ``frame`` of the scene's path and save it as a PNG (both eyes)."""
    _scene, session, host, _load_s = _open(scene_name, size, settings, path)
    try:
        session.apply_path_frame(frame)
        host.set_text_image(None)
        fi = session.frame_input(*host.eye_size)
        if settings.render.exposure_mode == "auto":  # a first frame meters the room: the
            host.draw(fi)  # picture is shown at its EV from the second (a sunlit room was white)
        img = host.draw(fi)
    finally:
        host.close()
    atomic_write_png(out, img)
    return img


def bench(
    scene_name: str,
    size: tuple[int, int],
    frames: int,
    settings: Settings,
    warmup: int = 5,
    path: CameraPath | None = None,
    progress: Progress | None = None,
    compare_every: int = 0,
    stride: int = 1,
    converged: ConvergedPhotons | None = None,
    settle: int = 0,
) -> BenchResult:
    """Replay the path; per-frame wall time and per-pass GPU time. frames=0: the whole path.

    ``warmup`` frames are drawn first, untimed, on the path's first frame (shaders compile);
    before them ``settle`` frames walk the path's last ones, untimed (the governor settles
    on its knobs: the governor study compares it settled). ``stride`` K > 1 times every
    K-th frame of the path only (the session still steps through the frames in between, so
    motion states are as when played): the whole of a long walk in fewer rendered frames.

    With ``compare_every`` K > 0, every K-th frame is also rendered at full quality (TCR off;
    :class:`app.lab.reference.BenchReference`, its converged photon map from ``converged``,
    shared by the runs of an experiment or a study) and the error of this setting against it
    is measured (display values): for the whole frame and for the gazed object alone.
    """
    scene, session, host, load_s = _open(scene_name, size, settings, path)
    assert session.path is not None
    if settings.sky.enabled and host.renderer.gpu_scene is not None:
        with host.ctx:  # daylight: the sky visibility baked before timing, not during it
            host.renderer.daylight.wait_for_visibility(host.renderer.gpu_scene)
    stride = max(1, int(stride))
    total = frames if frames > 0 else -(-session.path.frame_count() // stride)
    reference = None
    if compare_every > 0:
        converged = converged or ConvergedPhotons(TraceProgress())
        reference = BenchReference(host, scene_name, scene, converged)
    ppd = metrics.pixels_per_degree(
        size[0] // 2, session.camera.horizontal_fov_deg(size[0] // 2, size[1])
    )
    frame_ms: list[float] = []
    pass_ms: dict[str, list[float]] = {}
    samples: list[int] = []
    resident: list[int] = []
    per_frame: list[dict] = []
    compared: list[tuple[int, FrameErrors]] = []  # (state, figures) per compared frame
    photon_frames: list[dict] = []
    drawn: list[list[int]] = []  # triangles drawn per eye, per frame
    calls: list[list[int]] = []  # the geometry pass's draw calls per eye, per frame
    ranges: list[list[int]] = []  # the index ranges those calls drew per eye, per frame
    frame_calls: list[int] = []  # draw calls for meshes per frame, every pass
    try:
        host.set_text_image(None)
        # The settling frames walk the path's last frames (standing still, the picture
        # would refine and the governor hold full quality instead of settling), the warm-up
        # frames stand on the first.
        for i in range(-settle - warmup, total):
            at = i + warmup if i < -warmup else max(i, 0)
            session.apply_path_frame(at * stride % session.path.frame_count())
            frame = session.frame_input(*host.eye_size)
            calls_before = host.renderer.frame_draw_calls()
            t0 = time.perf_counter()
            host.render_only(frame)
            dt = (time.perf_counter() - t0) * 1000.0
            if i < 0:
                host.warm_variants(frame)  # before any timed frame, not one a frame
                continue
            frame_ms.append(dt)
            for name, ms in host.renderer.pass_ms().items():
                pass_ms.setdefault(name, []).append(ms)
            samples.append(host.shaded_samples())
            if host.renderer.photons.active:
                with host.ctx:
                    photon_frames.append(host.renderer.photon_stats())
            resident.append(host.renderer.texture_resident_bytes())
            drawn.append(host.renderer.triangles_drawn())
            calls.append(host.renderer.draw_calls())
            ranges.append(host.renderer.draw_ranges())
            frame_calls.append(host.renderer.frame_draw_calls() - calls_before)
            gazed = session.gazed
            distance = (
                float(session.tcr.distances[gazed])
                if gazed is not None
                and session.tcr is not None
                and len(session.tcr.distances) > gazed
                else None
            )
            record = {
                "path_frame": max(i, 0) * stride % session.path.frame_count(),
                "gazed_distance_m": None if distance is None else round(distance, 2),
                "frame": i,
                "ms": dt,
                "state": session.state,
                "gazed": session.gazed_object(),
                "gazed_level": (
                    session.levels[gazed]
                    if (settings.tcr.enabled and session.levels and gazed is not None)
                    else 0
                ),
                "resident_bytes": resident[-1],
                # Each pass's time: where a slow frame spent it.
                "passes_ms": {k: round(v, 2) for k, v in host.renderer.pass_ms().items()},
            }
            if reference is not None and i % compare_every == 0:
                test_img = host.read_pixels()  # the timed frame itself
                err = reference.measure(settings, frame, test_img, ppd, gazed)
                host.renderer.governor.skip_next()  # the reference slows the next frame
                compared.append((session.state, err))
                if err.frame is not None:
                    record["error"] = err.frame.to_dict()
                for region in ("fovea", "periphery", "gazed"):
                    figures = err.region(region)
                    if figures is not None:
                        record[f"error_{region}"] = figures.to_dict()
            _record_governor(record, host.renderer.governor)
            per_frame.append(record)
            if progress:
                progress(i + 1, total)
        refine = (
            refine_after_still(host, session, settings, ppd)
            if getattr(session.path, "name", "") == SHOWROOM_STOP
            else None
        )
        errors = host.renderer.errors
        budget = _frame_budget(frame_ms, settings, host.renderer.governor)
        shadows = host.renderer.shadows.stats()  # shadow_memory_bytes: the maps' GPU memory
        gpu_scene = host.renderer.gpu_scene
        merged_groups = len(gpu_scene.groups) if gpu_scene is not None else 0
        gpu_bytes = gpu_scene.geometry_bytes if gpu_scene is not None else 0
        upload_s = gpu_scene.upload_s if gpu_scene is not None else 0.0
        device = host.ctx.info.get("GL_RENDERER", "")
        trace_ms = host.photon_cache.trace_ms
    finally:
        if reference is not None:
            reference.close()
        host.close()
    return BenchResult(
        scene={
            "name": scene.name,
            "source": scene.source,
            "triangles": scene.triangle_count,
            "lights": len(scene.lights),
            "textures": len(scene.textures),
        },
        scene_load_s=load_s,
        path=session.path.scene or scene.name,
        size={"width": size[0], "height": size[1], "eye": [size[0] // 2, size[1]]},
        device=device,
        frames=len(frame_ms),
        warmup_frames=warmup,
        stride=stride,
        time_step_s=FIXED_DT,
        frame_ms=FrameTimes.of(frame_ms),
        passes={
            k: PassTimes(FrameTimes.of(v).median, FrameTimes.of(v).p95) for k, v in pass_ms.items()
        },
        texture_resident_bytes=int(np.median(resident)) if resident else 0,
        texture_resident_bytes_max=max(resident, default=0),
        shaded_samples=int(np.median(samples)) if samples else 0,
        by_state=_group(per_frame, "state"),
        by_gazed_level=_group(per_frame, "gazed_level"),
        by_gazed_distance_m=_group(
            [r for r in per_frame if r["gazed_distance_m"] is not None],
            "gazed_distance_m",
            max_groups=40,
        ),
        settings=settings.to_dict(),
        photons=_photon_summary(photon_frames, trace_ms),
        errors=errors,
        per_frame=per_frame,
        error_vs_full_quality=(_error_summary(compared, ppd) if reference is not None else None),
        shadows=shadows,
        geometry={
            "triangles_drawn": [int(np.median(col)) for col in zip(*drawn)] if drawn else [],
            "draw_calls": [int(np.median(col)) for col in zip(*calls)] if calls else [],
            "draw_ranges": [int(np.median(col)) for col in zip(*ranges)] if ranges else [],
            "draw_calls_frame": int(np.median(frame_calls)) if frame_calls else 0,
            "meshes": len(scene.meshes),
            "merged_groups": merged_groups,
            "gpu_bytes": gpu_bytes,  # vertex + index buffers (render.gpu_scene.geometry_bytes)
            "upload_s": round(upload_s, 3),  # GpuScene: geometry, maps, first texture levels
        },
        frame_budget=budget,
        refine=refine,
    )


def _record_governor(record: dict, governor: Governor) -> None:
    """The knobs the governor chose for the next frame (only while it holds a rate)."""
    if governor.budget_ms > 0:
        record["knobs"] = dict(governor.overrides)


def _frame_budget(ms: list[float], settings: Settings, governor: Governor) -> FrameBudget | None:
    """Frame times against render.target_fps (headless: "auto" is fixed settings, None)."""
    fps = target_fps(settings, None)
    if fps <= 0:
        return None
    return FrameBudget.of(ms, fps, governor.summary())


REFINE_MARKS_S = (0.5, 1.0, 2.0, 5.0)
REFINE_REFERENCE_SAMPLES = 256


def refine_after_still(
    host, session: Session, settings: Settings, ppd: float, stop_s: float = SHOWROOM_STOP_AT_S
) -> dict:
    """The refinement after the path stops (``showroom_stop``): FLIP of the displayed frame
    at 0.5, 1, 2 and 5 s of path time after the stop against the converged full-quality
    frame (the same pose, accumulated over REFINE_REFERENCE_SAMPLES jittered samples at full
    quality with the current photon map), and the wall-clock seconds those frames took."""
    r = settings.render
    target, mode = r.refine_samples, r.refine
    # Headless, "auto" does not refine: this path measures the refinement, so it is on here
    # (an explicit "off" stays off: the picture without refinement, for comparison).
    r.refine = "off" if mode == "off" else "on"
    try:
        return _refine_after_still(host, session, settings, ppd, stop_s)
    finally:
        r.refine_samples, r.refine = target, mode


def _refine_after_still(
    host, session: Session, settings: Settings, ppd: float, stop_s: float
) -> dict:
    from app.refine import needed

    assert session.path is not None
    stop = round(stop_s / FIXED_DT)
    marks = {round((stop_s + m) / FIXED_DT): m for m in REFINE_MARKS_S}
    last = min(max(marks), session.path.frame_count() - 1)
    session.apply_path_frame(max(0, stop - 1))  # walking into the stop (not timed)
    host.render_only(session.frame_input(*host.eye_size))
    shown: dict[float, np.ndarray] = {}
    wall: dict[float, float] = {}
    elapsed = 0.0
    for n in range(stop, last + 1):
        session.apply_path_frame(n)
        frame = session.frame_input(*host.eye_size)
        t0 = time.perf_counter()
        host.render_only(frame)
        elapsed += time.perf_counter() - t0
        if n in marks:
            shown[marks[n]] = host.read_pixels()
            wall[marks[n]] = elapsed
    r = settings.render
    target, was_on = r.refine_samples, r.refine
    r.refine, r.refine_samples = "on", REFINE_REFERENCE_SAMPLES
    session.refinement.reset()
    session.tick(0.0)
    for _ in range(needed(REFINE_REFERENCE_SAMPLES) + 2):
        host.render_only(session.frame_input(*host.eye_size))
    reference = host.read_pixels()
    return {
        "flip_after_still_s": {
            f"{m:g}": metrics.flip(reference, img, ppd) for m, img in shown.items()
        },
        "wall_s_after_still_s": {f"{m:g}": s for m, s in wall.items()},
        "reference_samples": REFINE_REFERENCE_SAMPLES,
        "refine_samples": target,
        "refine_on": was_on == "on",
    }


def _error_summary(compared: list[tuple[int, FrameErrors]], ppd: float) -> ErrorVsFullQuality:
    """Means over the compared frames: whole, gazed object, fovea and periphery, per state."""

    def means(region: str, state: int | None = None) -> MeanErrors:
        rows = [e.region(region) for s, e in compared if state is None or s == state]
        return MeanErrors.of([r for r in rows if r is not None])

    fovea_max = [e.fovea_max_abs_diff for _s, e in compared if e.fovea_max_abs_diff is not None]
    return ErrorVsFullQuality(
        pixels_per_degree=ppd,
        frame=means("frame"),
        gazed_object=means("gazed"),
        fovea=means("fovea") if any(e.fovea for _s, e in compared) else None,
        periphery=means("periphery") if any(e.periphery for _s, e in compared) else None,
        fovea_max_abs_diff=max(fovea_max) if fovea_max else None,
        by_state={
            str(s): {"frame": means("frame", s), "gazed_object": means("gazed", s)}
            for s in sorted({s for s, e in compared if e.frame is not None})
        },
    )


def _photon_summary(frames: list[dict], trace_ms: float) -> dict | None:
    """Medians of the photon pass over the timed frames (None: no indirect light)."""
    if not frames:
        return None
    eye_ms = np.array([f.get("eye_ms", [0.0, 0.0]) for f in frames], float)
    shares = [f["reuse_share"] for f in frames if "reuse_share" in f]
    return {
        "stored": frames[0].get("photons", 0),
        "trace_ms": trace_ms,
        "grid": frames[0].get("grid"),
        "error": frames[0].get("error"),
        # Wall-clock per eye where measured: moderngl's timer query is 32-bit (wraps at
        # 4.29 s, which a 512^2 photon gather on llvmpipe can pass).
        "gather_ms": float(np.median(eye_ms.sum(axis=1)))
        if eye_ms.any()
        else float(np.median([f.get("gather_ms", 0.0) for f in frames])),
        "left_eye_ms": float(np.median(eye_ms[:, 0])),
        "right_eye_ms": float(np.median(eye_ms[:, 1])),
        "reuse_share": float(np.median(shares)) if shares else None,
    }


def _group(records: list[dict], key: str, max_groups: int = 0) -> dict[str, GroupTimes]:
    """Median frame time per value of ``key``; {} when there are more than ``max_groups``
    values (0: no limit), e.g. distances along a continuous walk."""
    out: dict[str, GroupTimes] = {}
    values = {r[key] for r in records}
    if max_groups and len(values) > max_groups:
        return out
    for value in sorted(values, key=lambda v: (isinstance(v, str), v)):
        ms = FrameTimes.of([r["ms"] for r in records if r[key] == value])
        out[str(value)] = GroupTimes(
            len([r for r in records if r[key] == value]), ms.median, ms.fps
        )
    return out


def demo(
    scene_name: str,
    out_dir: str | Path,
    size: tuple[int, int],
    settings: Settings,
    every_s: float = 1.0,
    progress: Progress | None = None,
) -> dict:
    """The no-display fallback: walk the default path, save stereo screenshots and a summary."""
    out_dir = Path(out_dir)
    scene, session, host, _load_s = _open(scene_name, size, settings)
    assert session.path is not None
    total = session.path.frame_count()
    every = max(1, round(every_s / FIXED_DT))
    frame_ms: list[float] = []
    shots: list[str] = []
    try:
        fps = 0.0
        for i in range(total):
            session.apply_path_frame(i)
            frame = session.frame_input(*host.eye_size)
            if i % every == 0 or i == total - 1:
                host.set_text_image(
                    text_image(
                        overlay_lines(fps, host.renderer.pass_ms(), settings, frame.gaze_fixed)
                    )
                )
                img = host.draw(frame)
                name = f"frame_{i:04d}.png"
                atomic_write_png(out_dir / name, img)
                shots.append(name)
            else:
                t0 = time.perf_counter()
                host.render_only(frame)
                frame_ms.append((time.perf_counter() - t0) * 1000.0)
                fps = 1000.0 / frame_ms[-1]
            if progress:
                progress(i + 1, total)
    finally:
        host.close()
    ft = summarize(frame_ms)
    summary = {
        "scene": scene.name,
        "frames": total,
        "screenshots": shots,
        "fps_median": 1000.0 / ft["median"] if ft["median"] else 0.0,
        "frame_ms": ft,
        "settings": settings.to_dict(),
    }
    atomic_write_json(out_dir / "summary.json", summary)
    return summary
