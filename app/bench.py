"""Headless runs: one frame to PNG, the benchmark (JSON), and the no-display demo.

Every run steps the recorded path by a fixed time step, so frame N is the same image on every
run and machine; only the timings vary.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from app import scenes
from app.fileio import atomic_write_json, atomic_write_png
from app.overlay_text import text_image
from app.paths import FIXED_DT, CameraPath
from app.session import Session
from app.settings import Settings
from app.stats import overlay_lines, summarize

log = logging.getLogger(__name__)
Progress = Callable[[int, int], None]


def parse_size(text: str) -> tuple[int, int]:
    """'1280x720' -> (1280, 720): the whole side-by-side view."""
    try:
        w, h = (int(v) for v in text.lower().split("x"))
    except ValueError as exc:
        raise ValueError(f"size must look like 1280x720, got '{text}'") from exc
    if not (2 <= w <= 16384 and 1 <= h <= 16384):
        raise ValueError(f"size {w}x{h} is outside 2x1 .. 16384x16384")
    return w, h


def _open(scene_name: str, size: tuple[int, int], settings: Settings,
          path: CameraPath | None = None):
    from render.offscreen import OffscreenHost  # GL only when a run really renders

    scene = scenes.resolve(scene_name)
    session = Session(settings)
    session.set_scene(scene, path)
    host = OffscreenHost(*size, settings)
    host.set_scene(scene)
    return scene, session, host


def render_frame(scene_name: str, out: str | Path, size: tuple[int, int], frame: int,
                 settings: Settings, path: CameraPath | None = None) -> np.ndarray:
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


def bench(scene_name: str, size: tuple[int, int], frames: int, settings: Settings,
          warmup: int = 5, path: CameraPath | None = None,
          progress: Progress | None = None) -> dict:
    """Replay the path; per-frame wall time and per-pass GPU time. frames=0: the whole path."""
    scene, session, host = _open(scene_name, size, settings, path)
    assert session.path is not None
    total = frames if frames > 0 else session.path.frame_count()
    frame_ms: list[float] = []
    pass_ms: dict[str, list[float]] = {}
    samples: list[int] = []
    try:
        host.set_text_image(None)
        for i in range(-warmup, total):
            session.apply_path_frame(max(i, 0) % session.path.frame_count())
            frame = session.frame_input(*host.eye_size)
            t0 = time.perf_counter()
            host.render_only(frame)
            dt = (time.perf_counter() - t0) * 1000.0
            if i < 0:
                continue
            frame_ms.append(dt)
            for name, ms in host.renderer.pass_ms().items():
                pass_ms.setdefault(name, []).append(ms)
            samples.append(host.renderer.shaded_samples())
            if progress:
                progress(i + 1, total)
        errors = host.renderer.errors
        device = host.ctx.info.get("GL_RENDERER", "")
        resident = host.renderer.texture_resident_bytes()
    finally:
        host.close()
    ft = summarize(frame_ms)
    return {
        "scene": {"name": scene.name, "source": scene.source, "triangles": scene.triangle_count,
                  "lights": len(scene.lights), "textures": len(scene.textures)},
        "size": {"width": size[0], "height": size[1], "eye": [size[0] // 2, size[1]]},
        "device": device,
        "frames": len(frame_ms),
        "warmup_frames": warmup,
        "time_step_s": FIXED_DT,
        "fps_median": 1000.0 / ft["median"] if ft["median"] > 0 else 0.0,
        "frame_ms": ft,
        "passes": {k: {"median_ms": summarize(v)["median"], "p95_ms": summarize(v)["p95"]}
                   for k, v in pass_ms.items()},
        "texture_resident_bytes": resident,
        "shaded_samples": int(np.median(samples)) if samples else 0,
        "settings": settings.to_dict(),
        "errors": errors,
    }


def demo(scene_name: str, out_dir: str | Path, size: tuple[int, int], settings: Settings,
         every_s: float = 1.0, progress: Progress | None = None) -> dict:
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
                host.set_text_image(text_image(overlay_lines(
                    fps, host.renderer.pass_ms(), settings, frame.gaze_fixed)))
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
    summary = {"scene": scene.name, "frames": total, "screenshots": shots,
               "fps_median": 1000.0 / ft["median"] if ft["median"] else 0.0, "frame_ms": ft,
               "settings": settings.to_dict()}
    atomic_write_json(out_dir / "summary.json", summary)
    return summary
