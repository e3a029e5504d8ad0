"""The last few seconds of frames, each with its per-pass GPU times: what the frame-time graph
draws (ui/frame_graph.py), kept here so it needs no Qt and can be tested alone.

A frame's time is the wall-clock interval since the frame before it (what the user waits);
its passes are the renderer's GPU times (``Renderer.pass_ms()``). Stacked, the passes come
first in the renderer's order and ``OTHER`` tops them up to the frame time (CPU work, waiting,
the swap), so the top of the stack is the frame time itself.
"""

from __future__ import annotations

import collections
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from app.settings import Settings

OTHER = "other (CPU, waiting)"
DEFAULT_TARGET_FPS = 30.0  # no render.target_fps setting exists: the graph's line is 30 fps


@dataclass(frozen=True)
class Frame:
    """One frame: when it ended (seconds, any monotonic clock), its wall time and passes."""

    t: float
    frame_ms: float
    pass_ms: Mapping[str, float]


@dataclass(frozen=True)
class Stack:
    """The window's frames ready to draw: ``t`` (seconds before ``now``, <= 0), ``names`` the
    layers bottom to top and ``tops[i, j]`` the top of layer ``j`` at frame ``i`` (ms; the last
    column is the frame time)."""

    t: np.ndarray
    names: tuple[str, ...]
    tops: np.ndarray

    @property
    def peak_ms(self) -> float:
        return float(self.tops[:, -1].max()) if len(self.t) else 0.0


class FrameLog:
    """A ring buffer of the last frames (at most ``capacity``); :meth:`stack` keeps those of
    the last ``seconds``."""

    def __init__(self, seconds: float = 5.0, capacity: int = 4096) -> None:
        if seconds <= 0 or capacity < 1:
            raise ValueError("a frame log needs a positive span and capacity")
        self.seconds = seconds
        self.frames: collections.deque[Frame] = collections.deque(maxlen=capacity)
        self._last_t: float | None = None

    def __len__(self) -> int:
        return len(self.frames)

    def record(self, t: float, pass_ms: Mapping[str, float]) -> None:
        """A frame that ended at ``t`` (seconds) with these GPU pass times. The first frame has
        no interval before it: its time is the sum of its passes."""
        passes = {name: max(0.0, float(ms)) for name, ms in pass_ms.items()}
        gpu = sum(passes.values())
        frame_ms = gpu if self._last_t is None else max(0.0, (t - self._last_t) * 1000.0)
        self._last_t = t
        self.add(Frame(t, frame_ms, passes))

    def add(self, frame: Frame) -> None:
        self.frames.append(frame)

    def clear(self) -> None:
        self.frames.clear()
        self._last_t = None

    def recent(self, now: float | None = None) -> list[Frame]:
        """The frames of the last ``seconds`` before ``now`` (default: the newest frame)."""
        if not self.frames:
            return []
        now = self.frames[-1].t if now is None else now
        start = now - self.seconds
        return [f for f in self.frames if start <= f.t <= now]

    def stack(self, now: float | None = None) -> Stack:
        """The recent frames as stacked layers: every pass seen in the window (first-seen
        order, which is the renderer's), then ``OTHER``. A pass a frame did not run adds 0."""
        frames = self.recent(now)
        names: dict[str, None] = {}
        for f in frames:
            names.update(dict.fromkeys(f.pass_ms))
        layers = (*names, OTHER)
        if not frames:
            return Stack(np.zeros(0), layers, np.zeros((0, len(layers))))
        now = frames[-1].t if now is None else now
        ms = np.array([[f.pass_ms.get(n, 0.0) for n in names] for f in frames], np.float64)
        ms = ms.reshape(len(frames), len(names))
        gpu = ms.sum(axis=1)
        total = np.array([f.frame_ms for f in frames], np.float64)
        other = np.maximum(total - gpu, 0.0)  # GPU time longer than the interval: no "other"
        tops = np.cumsum(np.column_stack([ms, other]), axis=1)
        t = np.array([f.t - now for f in frames], np.float64)
        return Stack(t, layers, tops)


def target_fps(settings: Settings, display_hz: float | None = None) -> float:
    """The frame rate the graph's line marks: the governor's target (``render.target_fps``: a
    number, or ``auto`` = the display's refresh), else :data:`DEFAULT_TARGET_FPS` when the
    governor is off (0) or there is no display."""
    from app.governor import target_fps as governed

    value = governed(settings, display_hz)
    return float(value) if value > 0 else DEFAULT_TARGET_FPS


def nice_ceiling(value: float) -> float:
    """The smallest 1, 2, 2.5 or 5 times a power of ten at or above ``value`` (an axis top)."""
    if value <= 0:
        return 1.0
    power = 10.0 ** np.floor(np.log10(value))
    for step in (1.0, 2.0, 2.5, 5.0, 10.0):
        if step * power >= value - 1e-9:
            return float(step * power)
    return float(10.0 * power)


# The passes in words (the legend); a pass not listed shows its own name.
PASS_LABELS = {
    "gbuffer": "geometry (G-buffer)",
    "light_cull": "light culling",
    "shadow_mask": "shadows on screen",
    "cps_levels": "CPS detail levels",
    "photons": "photon gather",
    "lighting": "lighting",
    "cps_lighting": "CPS lighting",
    "cps_filter": "CPS filter",
    "cps_temporal": "CPS temporal filter",
    "cps_mask": "mask",
    "emissive": "emissive",
    "forward": "forward shading",
    "daylight": "sun and sky",
    "sky": "sky background",
    "present": "tone map and present",
    "overlay": "overlay",
    OTHER: OTHER,
}


def pass_label(name: str) -> str:
    return PASS_LABELS.get(name, name.replace("_", " "))


# A pass keeps its colour in the live graph and the lab's plots, whichever others run; none is
# the red of the target line.
PASS_COLOURS = {
    "gbuffer": "#1f77b4",
    "light_cull": "#17becf",
    "shadow_mask": "#393b79",
    "cps_levels": "#bcbd22",
    "photons": "#9467bd",
    "lighting": "#ff7f0e",
    "cps_lighting": "#ffbb78",
    "cps_filter": "#e377c2",
    "cps_temporal": "#8c564b",
    "cps_mask": "#5a5a8c",
    "emissive": "#ffd700",
    "forward": "#2ca02c",
    "daylight": "#87ceeb",
    "sky": "#4682b4",
    "present": "#98df8a",
    "overlay": "#aec7e8",
    OTHER: "#c8c8c8",
}
_SPARE_COLOURS = ("#60a0a0", "#a0783c", "#783ca0")


def pass_colour(name: str) -> str:
    """The pass's colour as ``#rrggbb`` (a pass not listed: one of a few spare colours)."""
    return PASS_COLOURS.get(name) or _SPARE_COLOURS[sum(map(ord, name)) % len(_SPARE_COLOURS)]
