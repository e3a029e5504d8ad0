"""``vrpreview load-bench``: how long a model takes to open and how much memory it needs.

Each file is measured in a fresh child process, so one file's caches and heap do not flatter the
next: the load (parse, repair, spawn, lights, texture pyramids: what the window's load worker
does) in seconds, then the first stereo frame as the window makes it (upload, huge texture sets
streamed in, and draw, with the GL context made beforehand), the peak
memory the load added (the process's peak resident size minus its size just before loading)
and what the scene holds once decoded (geometry arrays plus RGBA8 textures). A synthetic room of
any triangle count (:mod:`app.lab.synthetic`) stands in for the largest files users open.
"""

from __future__ import annotations

import json
import os
import resource
import subprocess
import sys
import time
from pathlib import Path

from app.frame import parse_size


def _rss_mb() -> float:
    with open("/proc/self/statm") as fh:
        pages = int(fh.read().split()[1])
    return pages * os.sysconf("SC_PAGE_SIZE") / 2**20


def _peak_rss_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0  # kB on Linux


def measure(path: str, size: tuple[int, int]) -> dict:
    """Load ``path`` here and render its first frame; the figures as a dict."""
    from app.loaders import load_scene
    from app.session import Session
    from app.settings import Settings
    from render.offscreen import OffscreenHost
    from render.texture_stream import prepare_textures

    settings = Settings()
    settings.render.overlay = False
    host = OffscreenHost(*size, settings)  # the window has its GL context before any load
    before = _rss_mb()
    start = time.perf_counter()
    scene = load_scene(path)
    prepare_textures(scene.textures)  # on the window's load worker too
    load_s = time.perf_counter() - start
    peak_load = _peak_rss_mb() - before
    geometry = sum(
        m.positions.nbytes
        + m.normals.nbytes
        + m.uvs.nbytes
        + m.indices.nbytes
        + (m.colors.nbytes if m.colors is not None else 0)
        for m in scene.meshes
    )
    textures = sum(t.rgba.nbytes for t in scene.textures)
    start = time.perf_counter()
    session = Session(settings)
    session.set_scene(scene)
    host.set_scene(scene, stream_in=True)
    session.tick(0.0)
    host.draw(session.frame_input(*host.eye_size))
    frame_s = time.perf_counter() - start
    host.close()
    decoded = (geometry + textures) / 2**20
    return {
        "file": Path(path).name,
        "triangles": scene.triangle_count,
        "meshes": len(scene.meshes),
        "textures": len(scene.textures),
        "load_s": round(load_s, 3),
        "first_frame_s": round(frame_s, 3),
        "open_s": round(load_s + frame_s, 3),
        "decoded_mb": round(decoded, 1),
        "peak_load_mb": round(peak_load, 1),
        "peak_over_decoded": round(peak_load / decoded, 2) if decoded else None,
        "warnings": len(scene.warnings),
        "spawn": [round(v, 2) for v in scene.spawn.position],
    }


def run(files: list[str], size: str, synthetic: int, work: str) -> list[dict]:
    """Measure each file (and a synthetic room of ``synthetic`` triangles) in a child process."""
    targets = list(files)
    if synthetic:
        from app.lab.synthetic import write_synthetic_room

        room = Path(work) / f"synthetic-{synthetic}.glb"
        if not room.exists():
            write_synthetic_room(room, synthetic)
        targets.append(str(room))
    rows = []
    for target in targets:
        proc = subprocess.run(
            [sys.executable, "-m", "app.lab.load_bench", "--child", target, size],
            capture_output=True,
            text=True,
            check=False,
        )
        lines = [line for line in proc.stdout.splitlines() if line.startswith("{")]
        if proc.returncode != 0 or not lines:
            tail = (proc.stderr.strip().splitlines() or ["no output"])[-1]
            rows.append({"file": Path(target).name, "error": tail})
        else:
            rows.append(json.loads(lines[-1]))
    return rows


def table(rows: list[dict]) -> str:
    head = (
        "| file | triangles | meshes | load s | first frame s | decoded MB | peak MB "
        "| peak / decoded |\n|---|---|---|---|---|---|---|---|"
    )
    out = [head]
    for r in rows:
        if "error" in r:
            out.append(f"| {r['file']} | error: {r['error']} | | | | | | |")
            continue
        out.append(
            f"| {r['file']} | {r['triangles']:,} | {r['meshes']} | {r['load_s']:.2f} "
            f"| {r['first_frame_s']:.2f} | {r['decoded_mb']:.0f} | {r['peak_load_mb']:.0f} "
            f"| {r['peak_over_decoded']} |"
        )
    return "\n".join(out)


if __name__ == "__main__":
    if len(sys.argv) == 4 and sys.argv[1] == "--child":
        print(json.dumps(measure(sys.argv[2], parse_size(sys.argv[3]))))
