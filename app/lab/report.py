"""Benchmark JSON files side by side: one markdown table row per run.

``vrpreview report out/bench-tcr/*.json`` is how the paper-style tables in the notes are made:
every figure comes from a file a user can re-create with the command stored in it.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

COLUMNS = (
    "run",
    "frames",
    "fps",
    "frame ms",
    "p95 ms",
    "resident MB",
    "PSNR dB",
    "SSIM",
    "FLIP",
    "gazed PSNR dB",
    "gazed SSIM",
)


def _num(value: object, fmt: str) -> str:
    if not isinstance(value, (int, float)) or math.isnan(value):
        return "-"
    if math.isinf(value):
        return "identical" if value > 0 else "-inf"
    return format(value, fmt)


def row(name: str, result: dict) -> list[str]:
    err = result.get("error_vs_full_quality") or {}
    frame, gazed = err.get("frame", {}), err.get("gazed_object", {})
    return [
        name,
        str(result.get("frames", "-")),
        _num(result.get("fps_median"), ".1f"),
        _num(result.get("frame_ms", {}).get("median"), ".1f"),
        _num(result.get("frame_ms", {}).get("p95"), ".1f"),
        _num(result.get("texture_resident_bytes", math.nan) / 1e6, ".2f"),
        _num(frame.get("psnr_db"), ".1f"),
        _num(frame.get("ssim"), ".4f"),
        _num(frame.get("flip"), ".4f"),
        _num(gazed.get("psnr_db"), ".1f"),
        _num(gazed.get("ssim"), ".4f"),
    ]


CPS_COLUMNS = (
    "run",
    "frames",
    "fps",
    "frame ms",
    "p95 ms",
    "samples / frame",
    "PSNR dB",
    "fovea max diff",
    "periphery PSNR dB",
    "periphery SSIM",
    "periphery FLIP",
)


def cps_row(name: str, result: dict) -> list[str]:
    err = result.get("error_vs_full_quality") or {}
    frame, periphery = err.get("frame", {}), err.get("periphery", {})
    fovea_max = err.get("fovea_max_abs_diff")
    return [
        name,
        str(result.get("frames", "-")),
        _num(result.get("fps_median"), ".2f"),
        _num(result.get("frame_ms", {}).get("median"), ".1f"),
        _num(result.get("frame_ms", {}).get("p95"), ".1f"),
        str(result.get("shaded_samples", "-")),
        _num(frame.get("psnr_db"), ".1f"),
        "-" if fovea_max is None else str(fovea_max),
        _num(periphery.get("psnr_db"), ".1f"),
        _num(periphery.get("ssim"), ".4f"),
        _num(periphery.get("flip"), ".4f"),
    ]


def group_rows(result: dict, key: str) -> list[list[str]]:
    """Median fps per value of a per-frame grouping (by_state, by_gazed_level, ...)."""
    return [
        [value, str(g["frames"]), _num(g["fps_median"], ".1f"), _num(g["frame_ms_median"], ".1f")]
        for value, g in result.get(key, {}).items()
    ]


def markdown(header: list[str] | tuple[str, ...], rows: list[list[str]]) -> str:
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(r) + " |" for r in rows]
    return "\n".join(lines)


def report(paths: list[str | Path], groups: tuple[str, ...] = ()) -> str:
    """The runs as one table, then for each run its per-group fps for every key in ``groups``."""
    results = []
    for p in paths:
        try:
            results.append((Path(p).stem, json.loads(Path(p).read_text(encoding="utf-8"))))
        except (OSError, ValueError) as exc:
            raise ValueError(f"{p}: not a benchmark JSON file ({exc})") from exc
    if any(r.get("settings", {}).get("cps", {}).get("mode", "none") != "none" for _, r in results):
        parts = [markdown(CPS_COLUMNS, [cps_row(name, r) for name, r in results])]
    else:
        parts = [markdown(COLUMNS, [row(name, r) for name, r in results])]
    for key in groups:
        for name, r in results:
            if r.get(key):
                parts.append(
                    f"\n{name}, {key}:\n"
                    + markdown(
                        (key.removeprefix("by_"), "frames", "fps", "frame ms"), group_rows(r, key)
                    )
                )
    return "\n".join(parts)
