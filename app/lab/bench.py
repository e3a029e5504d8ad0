"""Headless runs: one frame to PNG, the benchmark (JSON), and the no-display demo.

Every run steps the recorded path by a fixed time step, so frame N is the same image on every
run and machine; only the timings vary.
"""

from __future__ import annotations

import logging
import math
import sys
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from app import metrics, scenes
from app.fileio import atomic_write_json, atomic_write_png
from app.overlay_text import text_image
from app.paths import FIXED_DT, CameraPath
from app.quality import full_quality, measure, stereo_fovea
from app.session import Session
from app.settings import Settings
from app.stats import overlay_lines, summarize

log = logging.getLogger(__name__)
Progress = Callable[[int, int], None]
_last_fraction = -1.0


def parse_size(text: str) -> tuple[int, int]:
    """'1280x720' -> (1280, 720): the whole side-by-side view."""
    try:
        w, h = (int(v) for v in text.lower().split("x"))
    except ValueError as exc:
        raise ValueError(f"size must look like 1280x720, got '{text}'") from exc
    if not (2 <= w <= 16384 and 1 <= h <= 16384):
        raise ValueError(f"size {w}x{h} is outside 2x1 .. 16384x16384")
    return w, h


def _open(
    scene_name: str, size: tuple[int, int], settings: Settings, path: CameraPath | None = None
):
    from render.offscreen import OffscreenHost  # GL only when a run really renders

    scene = scenes.resolve(scene_name)
    session = Session(settings)
    session.set_scene(scene, path)
    host = OffscreenHost(*size, settings, trace_progress=print_trace_progress)
    host.renderer.photons.measure = True  # per-eye gather time (waits for the GPU per eye)
    host.set_scene(scene)
    return scene, session, host


def print_trace_progress(fraction: float) -> None:
    """A text progress bar for photon tracing on stderr."""
    global _last_fraction
    if fraction == _last_fraction:
        return
    _last_fraction = fraction
    filled = int(round(30 * min(max(fraction, 0.0), 1.0)))
    end = "\n" if fraction >= 1.0 else ""
    print(
        f"\rtracing photons [{'#' * filled}{'.' * (30 - filled)}] {100 * fraction:3.0f}%",
        end=end,
        file=sys.stderr,
        flush=True,
    )


def render_frame(
    scene_name: str,
    out: str | Path,
    size: tuple[int, int],
    frame: int,
    settings: Settings,
    path: CameraPath | None = None,
) -> np.ndarray:
    """Render frame ``frame`` of the scene's path and save it as a PNG (both eyes)."""
    _scene, session, host = _open(scene_name, size, settings, path)
    try:
        session.apply_path_frame(frame)
        host.set_text_image(None)
        img = host.draw(session.frame_input(*host.eye_size))
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
) -> dict:
    """Replay the path; per-frame wall time and per-pass GPU time. frames=0: the whole path.

    ``stride`` K > 1 times every K-th frame of the path only (the session still steps through
    the frames in between, so motion states are as when played): the whole of a long walk in
    fewer rendered frames.

    With ``compare_every`` K > 0, every K-th frame is also rendered at full quality (TCR off) by
    a second host and the error of this setting against it is measured (display values): for
    the whole frame and for the gazed object alone.
    """
    scene, session, host = _open(scene_name, size, settings, path)
    assert session.path is not None
    stride = max(1, int(stride))
    total = frames if frames > 0 else -(-session.path.frame_count() // stride)
    reference = None
    if compare_every > 0:
        from render.offscreen import OffscreenHost

        ref_settings = full_quality(settings)
        reference = OffscreenHost(*size, ref_settings)
        _share_converged(reference, scene_name, scene)
        reference.set_scene(scene)
        reference.set_text_image(None)
    ppd = metrics.pixels_per_degree(
        size[0] // 2, session.camera.horizontal_fov_deg(size[0] // 2, size[1])
    )
    frame_ms: list[float] = []
    pass_ms: dict[str, list[float]] = {}
    samples: list[int] = []
    resident: list[int] = []
    per_frame: list[dict] = []
    errors_whole: list[dict] = []
    errors_gazed: list[dict] = []
    errors_regions: dict[str, list[dict]] = {}
    fovea_max: list[int] = []
    photon_frames: list[dict] = []
    try:
        host.set_text_image(None)
        for i in range(-warmup, total):
            session.apply_path_frame(max(i, 0) * stride % session.path.frame_count())
            frame = session.frame_input(*host.eye_size)
            t0 = time.perf_counter()
            host.render_only(frame)
            dt = (time.perf_counter() - t0) * 1000.0
            if i < 0:
                continue
            frame_ms.append(dt)
            for name, ms in host.renderer.pass_ms().items():
                pass_ms.setdefault(name, []).append(ms)
            samples.append(host.shaded_samples())
            if host.renderer.photons.active:
                with host.ctx:
                    photon_frames.append(host.renderer.photon_stats())
            resident.append(host.renderer.texture_resident_bytes())
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
            }
            if reference is not None and i % compare_every == 0:
                test_img = host.read_pixels()  # the timed frame itself
                ref_img = reference.draw(frame)
                regions = (
                    {"gazed": np.hstack(reference.object_ids(frame)) == gazed}
                    if gazed is not None
                    else {}
                )
                err = measure(ref_img, test_img, stereo_fovea(settings.cps, frame), ppd, regions)
                record["error"] = err["frame"]
                errors_whole.append({**err["frame"], "state": session.state})
                for region in ("fovea", "periphery"):
                    if err[region]:
                        record[f"error_{region}"] = err[region]
                        errors_regions.setdefault(region, []).append(err[region])
                if err["fovea_max_abs_diff"] is not None:
                    fovea_max.append(err["fovea_max_abs_diff"])
                if err.get("gazed"):
                    record["error_gazed"] = err["gazed"]
                    errors_gazed.append({**err["gazed"], "state": session.state})
            per_frame.append(record)
            if progress:
                progress(i + 1, total)
        errors = host.renderer.errors
        device = host.ctx.info.get("GL_RENDERER", "")
        trace_ms = host.photon_cache.trace_ms
    finally:
        host.close()
        if reference is not None:
            reference.close()
    ft = summarize(frame_ms)
    result = {
        "scene": {
            "name": scene.name,
            "source": scene.source,
            "triangles": scene.triangle_count,
            "lights": len(scene.lights),
            "textures": len(scene.textures),
        },
        "path": session.path.scene or scene.name,
        "size": {"width": size[0], "height": size[1], "eye": [size[0] // 2, size[1]]},
        "device": device,
        "frames": len(frame_ms),
        "warmup_frames": warmup,
        "stride": stride,
        "time_step_s": FIXED_DT,
        "fps_median": 1000.0 / ft["median"] if ft["median"] > 0 else 0.0,
        "frame_ms": ft,
        "passes": {
            k: {"median_ms": summarize(v)["median"], "p95_ms": summarize(v)["p95"]}
            for k, v in pass_ms.items()
        },
        "texture_resident_bytes": int(np.median(resident)) if resident else 0,
        "texture_resident_bytes_max": max(resident, default=0),
        "shaded_samples": int(np.median(samples)) if samples else 0,
        "by_state": _group(per_frame, "state"),
        "by_gazed_level": _group(per_frame, "gazed_level"),
        "by_gazed_distance_m": _group(
            [r for r in per_frame if r["gazed_distance_m"] is not None],
            "gazed_distance_m",
            max_groups=40,
        ),
        "settings": settings.to_dict(),
        "photons": _photon_summary(photon_frames, trace_ms),
        "errors": errors,
        "per_frame": per_frame,
    }
    if reference is not None:
        result["error_vs_full_quality"] = {
            "reference": "same frame at full quality (TCR off, full-rate lighting, no mask, "
            "converged photon map), display values; fovea/periphery: pixels at "
            "CPS level 0 / above 0 (without CPS: by angle from the gaze alone)",
            "pixels_per_degree": ppd,
            "frame": _mean_errors(errors_whole),
            "gazed_object": _mean_errors(errors_gazed),
            **{region: _mean_errors(rows) for region, rows in errors_regions.items()},
            "fovea_max_abs_diff": max(fovea_max) if fovea_max else None,
            "by_state": {
                str(s): {
                    "frame": _mean_errors([e for e in errors_whole if e["state"] == s]),
                    "gazed_object": _mean_errors([e for e in errors_gazed if e["state"] == s]),
                }
                for s in sorted({e["state"] for e in errors_whole})
            },
        }
    return result


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


_converged: dict[tuple, tuple] = {}  # (scene, count, seed, bounces) -> (scene, PhotonMap)


def _share_converged(host, scene_name: str, scene) -> None:
    """Trace the converged photon map once per process and scene (4M paths take a while), and
    hand it to each reference host."""
    from app.indirect import map_key, trace, wanted

    s = host.settings.photons
    if not wanted(s, scene):
        return
    memo = (scene_name, s.photons, s.seed, s.max_bounces)
    if memo not in _converged:
        _converged.clear()  # one at a time: a 4M map is 128 MB
        _converged[memo] = trace(s, scene, print_trace_progress)
    host.photon_cache.store(map_key(s, scene), scene, _converged[memo])


def _group(records: list[dict], key: str, max_groups: int = 0) -> dict[str, dict]:
    """Median frame time per value of ``key``; {} when there are more than ``max_groups``
    values (0: no limit), e.g. distances along a continuous walk."""
    out: dict[str, dict] = {}
    values = {r[key] for r in records}
    if max_groups and len(values) > max_groups:
        return out
    for value in sorted(values, key=lambda v: (isinstance(v, str), v)):
        ms = [r["ms"] for r in records if r[key] == value]
        med = summarize(ms)["median"]
        out[str(value)] = {
            "frames": len(ms),
            "frame_ms_median": med,
            "fps_median": 1000.0 / med if med > 0 else 0.0,
        }
    return out


def _mean_errors(rows: list[dict]) -> dict:
    """Mean PSNR over frames that differ (identical frames have infinite PSNR), SSIM, FLIP."""
    if not rows:
        return {"frames": 0}
    finite = [r["psnr"] for r in rows if math.isfinite(r["psnr"])]
    return {
        "frames": len(rows),
        "identical_frames": len(rows) - len(finite),
        "psnr_db": float(np.mean(finite)) if finite else math.inf,
        "ssim": float(np.mean([r["ssim"] for r in rows])),
        "flip": float(np.nanmean([r["flip"] for r in rows])),
    }


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
    scene, session, host = _open(scene_name, size, settings)
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
