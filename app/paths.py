"""Recorded camera + gaze paths (JSON), played back at a fixed time step.

Format: ``{"vrpreview_path": 1, "scene": NAME, "keys": [{"t", "position", "yaw_deg",
"pitch_deg", "gaze", "gaze_fixed"}, ...]}``. Between keys everything is linear;
``gaze_fixed`` holds the earlier key's value. Gaze is the normalised cursor position inside each
eye's viewport, (0, 0) top-left.
"""

from __future__ import annotations

import bisect
import json
import math
import os
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path

import numpy as np

from app.fileio import atomic_write_json

FIXED_DT = 1.0 / 60.0  # headless runs step time by this, so frame N is always the same image


class PathError(ValueError):
    pass


@dataclass
class PathKey:
    t: float
    position: tuple[float, float, float]
    yaw_deg: float = 0.0
    pitch_deg: float = 0.0
    gaze: tuple[float, float] = (0.5, 0.5)
    gaze_fixed: bool = False


@dataclass
class CameraPath:
    keys: list[PathKey]
    scene: str = ""
    _times: list[float] = field(default_factory=list, repr=False)
    name: str = ""  # a built-in path's name ("" for a file)

    def __post_init__(self) -> None:
        if not self.keys:
            raise PathError("a path needs at least one key")
        self.keys.sort(key=lambda k: k.t)
        self._times = [k.t for k in self.keys]

    @property
    def duration(self) -> float:
        return self.keys[-1].t - self.keys[0].t

    def frame_count(self, dt: float = FIXED_DT) -> int:
        return int(math.floor(self.duration / dt + 1e-9)) + 1

    def sample(self, t: float) -> PathKey:
        t = float(t) if math.isfinite(t) else self.keys[0].t
        t = min(max(t, self.keys[0].t), self.keys[-1].t)
        i = bisect.bisect_right(self._times, t) - 1
        a = self.keys[max(i, 0)]
        if i >= len(self.keys) - 1:
            return a
        b = self.keys[i + 1]
        span = b.t - a.t
        w = 0.0 if span <= 0 else (t - a.t) / span

        def lerp(x: float, y: float) -> float:
            return x + (y - x) * w

        return PathKey(
            t,
            tuple(lerp(x, y) for x, y in zip(a.position, b.position)),  # type: ignore[arg-type]
            lerp(a.yaw_deg, b.yaw_deg),
            lerp(a.pitch_deg, b.pitch_deg),
            (lerp(a.gaze[0], b.gaze[0]), lerp(a.gaze[1], b.gaze[1])),
            a.gaze_fixed,
        )

    def at_frame(self, n: int, dt: float = FIXED_DT) -> PathKey:
        return self.sample(self.keys[0].t + max(0, int(n)) * dt)

    def to_dict(self) -> dict:
        return {
            "vrpreview_path": 1,
            "scene": self.scene,
            "keys": [
                {
                    "t": k.t,
                    "position": list(k.position),
                    "yaw_deg": k.yaw_deg,
                    "pitch_deg": k.pitch_deg,
                    "gaze": list(k.gaze),
                    "gaze_fixed": k.gaze_fixed,
                }
                for k in self.keys
            ],
        }

    def save(self, path: str | os.PathLike[str]) -> None:
        atomic_write_json(path, self.to_dict())

    @classmethod
    def from_dict(cls, doc: dict, origin: str = "path") -> CameraPath:
        if not isinstance(doc, dict) or doc.get("vrpreview_path") != 1:
            raise PathError(f"{origin}: not a vrpreview path (missing 'vrpreview_path': 1)")
        keys = []
        for i, k in enumerate(doc.get("keys") or []):
            try:
                pos = [float(v) for v in k["position"]]
                gaze = [float(v) for v in k.get("gaze", (0.5, 0.5))]
                t = float(k["t"])
                yaw_deg = float(k.get("yaw_deg", 0.0))
                pitch_deg = float(k.get("pitch_deg", 0.0))
                gaze_fixed = bool(k.get("gaze_fixed", False))
            except (KeyError, TypeError, ValueError) as exc:
                raise PathError(f"{origin}: key {i} is malformed ({exc})") from exc
            values = [t, *pos, yaw_deg, pitch_deg, *gaze]
            if len(pos) != 3 or len(gaze) != 2 or not np.isfinite(values).all():
                raise PathError(f"{origin}: key {i} has a missing or non-finite value")
            key = PathKey(
                t, (pos[0], pos[1], pos[2]), yaw_deg, pitch_deg, (gaze[0], gaze[1]), gaze_fixed
            )
            keys.append(key)
        if not keys:
            raise PathError(f"{origin}: the path has no keys")
        return cls(keys, str(doc.get("scene", "")))

    @classmethod
    def load(cls, path: str | os.PathLike[str]) -> CameraPath:
        try:
            doc = json.loads(Path(path).read_text(encoding="utf-8"))
        except (OSError, json.JSONDecodeError) as exc:
            raise PathError(f"cannot read path {path}: {exc}") from exc
        return cls.from_dict(doc, str(path))


def builtin_path(name: str) -> CameraPath:
    """A path shipped in assets/paths (e.g. 'showroom_walkthrough')."""
    ref = resources.files("assets").joinpath("paths").joinpath(f"{name}.json")
    try:
        doc = json.loads(ref.read_text(encoding="utf-8"))
    except (OSError, FileNotFoundError, json.JSONDecodeError) as exc:
        raise PathError(f"built-in path '{name}' is missing or broken: {exc}") from exc
    return CameraPath.from_dict(doc, name)


def still_path(
    position, yaw_deg: float, pitch_deg: float, seconds: float = 2.0, scene: str = ""
) -> CameraPath:
    """A path that stands still at one viewpoint, gaze at the centre (for loaded files)."""
    x, y, z = (float(v) for v in position)
    keys = [PathKey(t, (x, y, z), yaw_deg, pitch_deg) for t in (0.0, seconds)]
    return CameraPath(keys, scene)


# The refinement benchmark's path (issue 15): walk 2 s through the showroom, then stand still
# 5 s; ``app.lab.bench`` measures how fast the picture refines after the stop.
SHOWROOM_STOP = "showroom_stop"
SHOWROOM_STOP_AT_S = 2.0


def showroom_stop() -> CameraPath:
    """Walk 2 s (the showroom walkthrough's first steps), then stand 5 s, gaze resting."""
    keys = [
        PathKey(0.0, (3.0, 1.6, 2.3), 20.0, -4.0, (0.45, 0.42)),
        PathKey(1.0, (2.0, 1.6, 1.75), 14.0, -3.0, (0.62, 0.46)),
        PathKey(SHOWROOM_STOP_AT_S, (0.75, 1.6, 1.05), 5.0, 0.0, (0.5, 0.5)),
        PathKey(SHOWROOM_STOP_AT_S + 5.0, (0.75, 1.6, 1.05), 5.0, 0.0, (0.5, 0.5)),
    ]
    path = CameraPath(keys, "showroom")
    path.name = SHOWROOM_STOP
    return path
