"""Frame statistics shared by the window and the headless host: fps and the overlay text."""

from __future__ import annotations

import collections
import math
import time

import numpy as np

from app.settings import Settings


class FrameTimer:
    """Rolling frame times (wall clock) over the last ``window`` frames."""

    def __init__(self, window: int = 60) -> None:
        self.times: collections.deque[float] = collections.deque(maxlen=window)
        self._last: float | None = None

    def tick(self, now: float | None = None) -> None:
        now = time.perf_counter() if now is None else now
        if self._last is not None:
            self.times.append(now - self._last)
        self._last = now

    @property
    def fps(self) -> float:
        if not self.times:
            return 0.0
        mean = sum(self.times) / len(self.times)
        return 1.0 / mean if mean > 0 else 0.0


def overlay_lines(
    fps: float, pass_ms: dict[str, float], settings: Settings, gaze_fixed: bool
) -> list[str]:
    r = settings.render
    path = f"deferred ({r.lighting})" if r.path == "deferred" else "forward"
    passes = "  ".join(f"{k} {v:.1f}" for k, v in pass_ms.items() if v > 0.05)
    return [
        f"{fps:5.1f} fps   {path}   gaze {'fixed' if gaze_fixed else 'moving'}",
        f"GPU ms: {passes}",
    ]


def summarize(values: list[float]) -> dict[str, float]:
    """Median, p95 and mean of a list (all 0 for an empty list)."""
    if not values:
        return {"median": 0.0, "p95": 0.0, "mean": 0.0}
    a = np.asarray(values, np.float64)
    out = {
        "median": float(np.median(a)),
        "p95": float(np.percentile(a, 95)),
        "mean": float(a.mean()),
    }
    return {k: (v if math.isfinite(v) else 0.0) for k, v in out.items()}
