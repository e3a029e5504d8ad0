"""All user-adjustable settings as one typed tree of dataclasses, addressed by dotted keys.

The panels, the CLI (``--set key=value``), saved presets and the benchmark all go through
:func:`Settings.set` / :func:`Settings.get`, so a key means the same thing everywhere and every
value is validated in one place.
"""

from __future__ import annotations

import copy
import dataclasses
import json
import math
import os
from dataclasses import dataclass, field
from typing import Any

from app.fileio import atomic_write_json


class SettingsError(ValueError):
    """A key that does not exist, or a value that does not fit its key."""


def _opt(
    default: Any,
    help: str,
    *,
    lo: float | None = None,
    hi: float | None = None,
    choices: tuple[str, ...] | None = None,
    label: str | None = None,
    choice_labels: dict[str, str] | None = None,
    check: Any = None,
) -> Any:
    """A setting's default and what the panels, the CLI and validation know about it.

    ``help`` is the CLI's comment and the panels' tooltip; ``lo``/``hi`` bound a number and
    ``choices`` a string (both are enforced by :meth:`Settings.set`); ``label`` names the
    control in a panel (default: the key's last part) and ``choice_labels`` a choice's entry;
    ``check`` normalises a value or raises ``ValueError`` with the reason.
    """
    meta: dict[str, object] = {"help": help, "lo": lo, "hi": hi, "choices": choices}
    if check is not None:
        meta["check"] = check
    if label is not None:
        meta["label"] = label
    if choice_labels is not None:
        meta["choice_labels"] = dict(choice_labels)
    return field(default=default, metadata=meta)


@dataclass
class StereoSettings:
    ipd_mm: float = _opt(64.0, "interpupillary distance (mm)", lo=0.0, hi=100.0)
    fov_deg: float = _opt(95.0, "vertical field of view per eye (degrees)", lo=30.0, hi=130.0)
    near_m: float = _opt(0.05, "near clipping plane (m)", lo=1e-4, hi=10.0)
    far_m: float = _opt(200.0, "far clipping plane (m)", lo=1.0, hi=1e5)
    convergence_m: float = _opt(2.0, "distance where the eyes' images coincide (m)", lo=0.1, hi=1e4)


@dataclass
class RenderSettings:
    path: str = _opt("deferred", "rendering path", choices=("deferred", "forward"))
    lighting: str = _opt(
        "compute",
        "deferred lighting stage",
        choices=("compute", "fragment"),
        label="lighting stage",
        choice_labels={
            "fragment": "Fragment (graphics pipeline)",
            "compute": "Compute (the paper's)",
        },
    )
    exposure: float = _opt(1.0, "exposure before tone mapping", lo=0.0, hi=64.0)
    brightness: float = _opt(
        1.0, "dimmer: scales every light and the ambient (1 = as authored)", lo=0.0, hi=16.0
    )
    ambient: float = _opt(0.06, "constant ambient light", lo=0.0, hi=4.0)
    overlay: bool = _opt(True, "draw the fps overlay in the view")
    light_culling: bool = _opt(
        True,
        "deferred, scenes with more than 8 lights: per 16x16 "
        "tile, evaluate only the lights whose range reaches it",
    )
    # Off by default: llvmpipe's anisotropic filter turns magnified texels into round blobs.
    anisotropy: float = _opt(1.0, "anisotropic texture filtering (1 = off)", lo=1.0, hi=16.0)


@dataclass
class NavigationSettings:
    walk_speed_mps: float = _opt(1.4, "walking speed (m/s)", lo=0.0, hi=50.0)
    turn_deg_per_px: float = _opt(0.15, "mouse-drag look sensitivity (deg/pixel)", lo=0.0, hi=5.0)
    eye_height_m: float = _opt(1.6, "eye height above the floor (m)", lo=0.1, hi=3.0)
    radius_m: float = _opt(0.25, "body radius for collision (m)", lo=0.0, hi=2.0)
    collision: bool = _opt(True, "stop at walls")
    fly: bool = _opt(
        False, "fly freely instead of walking on the floor (no floor following; collision optional)"
    )


@dataclass
class GazeSettings:
    dwell: bool = _opt(False, "a cursor held still also fixes the gaze")
    dwell_deg: float = _opt(
        1.5, "dwell: largest cursor motion still counted as still (deg)", lo=0.0, hi=30.0
    )
    dwell_s: float = _opt(0.4, "dwell: how long the cursor must stay still (s)", lo=0.0, hi=10.0)


@dataclass
class TcrSettings:
    """Adaptive texture mapping (TCR paper): which terms choose each object's pyramid level."""

    enabled: bool = _opt(False, "adapt texture levels per object (off: full quality)", label="TCR")
    preset: str = _opt(
        "ergonomics",
        "term set: psychology (d,g,l), ergonomics (d,v,l) or custom",
        choices=("psychology", "ergonomics", "custom"),
        label="preset",
    )
    use_d: bool = _opt(True, "custom: distance term d")
    use_v: bool = _opt(True, "custom: viewpoint-motion term v (+1 while moving)")
    use_g: bool = _opt(False, "custom: gaze term g (-1 on the gazed object while fixed)")
    use_l: bool = _opt(True, "custom: brightness term l (+1 per halving)")
    mode: str = _opt(
        "clamp",
        "paper: sample exactly level j; clamp: mipmapping, finest level j",
        choices=("paper", "clamp"),
        label="sampling",
        choice_labels={"paper": "paper (exactly level j)", "clamp": "clamp (mipmapping)"},
    )
    f_m: float = _opt(
        1.0,
        "eye-to-screen distance f in j = floor(log2((d+f)/f)) (m)",
        lo=1e-6,
        hi=100.0,
        label="eye-screen f (m)",
    )
    move_on: float = _opt(0.15, "viewpoint counts as moving above this speed", lo=0.0, hi=100.0)
    move_off: float = _opt(0.05, "... and as still again below this speed", lo=0.0, hi=100.0)
    window_s: float = _opt(0.15, "a state change must persist this long (s)", lo=0.0, hi=5.0)
    tint: bool = _opt(False, "tint every object by its texture level", label="overlay")


@dataclass
class CpsSettings:
    """Coarse pixel shading against VR sickness (CPS paper, SPEC C) and the mitigation modes."""

    mode: str = _opt(
        "none",
        "mitigation: none (full-rate lighting), black-mask or blur-mask "
        "(periphery darkened / blurred where detail would drop) or cps (coarse "
        "shading there); the lighting runs where render.lighting says (compute "
        "is the paper's, fragment keeps it in the graphics pipeline); deferred "
        "path only",
        choices=("none", "black-mask", "blur-mask", "cps"),
        label="mode",
    )
    max_level: int = _opt(
        4,
        "coarsest block allowed: 2^max_level pixels square (0-5)",
        lo=0,
        hi=5,
        label="coarsest block",
    )
    fovea_deg: float = _opt(
        10.0,
        "full detail within this angle of the gaze (degrees)",
        lo=0.0,
        hi=180.0,
        label="fovea radius",
    )
    deg_per_level: float = _opt(
        6.0,
        "falloff: one level coarser per this many degrees beyond the fovea",
        lo=0.1,
        hi=180.0,
        label="falloff",
    )
    near_m: float = _opt(
        1.0,
        "edge ray hit this near or nearer: that side may go to max_level (m)",
        lo=0.0,
        hi=1000.0,
        label="near (coarsest)",
    )
    far_m: float = _opt(
        6.0,
        "edge ray hit this far or farther (or none): no reduction on that side (m)",
        lo=0.0,
        hi=1000.0,
        label="far (no reduction)",
    )
    rays_per_side: int = _opt(
        5, "edge rays per side (left, right, bottom) and eye", lo=1, hi=64, label="rays per side"
    )
    dispatch: str = _opt(
        "multi",
        "compute: one dispatch per level (multi) or one in which a "
        "thread owns a 32x32 tile (single)",
        choices=("multi", "single"),
        label="dispatch",
        choice_labels={"multi": "One dispatch per level", "single": "Single dispatch, 32x32 tiles"},
    )
    filter: str = _opt(
        "hierarchical",
        "reconstruction of coarse blocks: none, bilinear (ordinary) or hierarchical (the paper's)",
        choices=("none", "bilinear", "hierarchical"),
        label="filter",
        choice_labels={
            "none": "None (flat blocks)",
            "bilinear": "Bilinear",
            "hierarchical": "Hierarchical bilinear (paper)",
        },
    )
    temporal: bool = _opt(
        False,
        "alternating temporal filter: the eyes swap strong and weak "
        "reduction each frame and blend with their previous frame",
        label="temporal",
    )
    reproject: bool = _opt(
        True,
        "temporal: reproject the history with depth and the previous "
        "camera, rejecting disocclusions",
        label="history",
    )
    history_weight: float = _opt(
        0.7,
        "temporal: weight of the finer of the two images when blending (0.5-1)",
        lo=0.5,
        hi=1.0,
        label="finer image weight",
    )
    visualize: bool = _opt(
        False,
        "tint pixels by detail level (finest unpainted, then blue, "
        "cyan, green, yellow, red) and mark the edge-ray hits",
        label="detail visualisation",
    )


@dataclass
class PhotonSettings:
    """Photon-mapped indirect light (SPEC D): traced on the CPU, gathered on the GPU."""

    enabled: str = _opt(
        "scene",
        "indirect light from a photon map: scene (only where the scene asks for it), on or off",
        choices=("scene", "on", "off"),
    )
    photons: int = _opt(
        65536,
        "photon paths emitted from the lights (the paper: 128^2 = 16384, "
        "256^2 = 65536, 512^2 = 262144)",
        lo=0,
        hi=1 << 22,
    )
    radius_m: float = _opt(0.3, "gather radius r (m)", lo=1e-3, hi=100.0)
    gather: str = _opt(
        "radius",
        "radius (hash grid, cell r, no heap: the paper's default), "
        "radius-half (cell r/2, 5x5x5), heap (k nearest), kdtree, kdtree-heap, "
        "shared (cooperative shared-memory gather, paper Algorithm 1)",
        choices=("radius", "radius-half", "heap", "kdtree", "kdtree-heap", "shared"),
    )
    k: int = _opt(32, "heap variants: nearest photons kept", lo=1, hi=64)
    fused: bool = _opt(
        False,
        "gather inside the lighting shader (one kernel: the paper's "
        "'single' scheme, no stereo reuse; shared gathers as radius there) "
        "instead of a separate pass before it (its 'hybrid' scheme)",
    )
    stereo_reuse: bool = _opt(
        True,
        "gather the left eye first and reuse its results at the "
        "right-eye pixels that see the same points",
    )
    reuse_tolerance: float = _opt(
        0.01,
        "stereo reuse: largest distance between the left hit "
        "and the right pixel's point, relative to its depth",
        lo=0.0,
        hi=1.0,
    )
    max_bounces: int = _opt(8, "longest photon path (bounces)", lo=1, hi=64)
    seed: int = _opt(0, "random seed of the photon tracer", lo=0, hi=2**31 - 1)
    show_reuse: bool = _opt(
        False, "paint right-eye pixels reused from the left eye green and gathered ones red"
    )


def _unit_scale(value: str) -> str:
    """``auto`` or a positive factor from the file's units to metres (0.01 = centimetres)."""
    text = str(value).strip().lower()
    if text == "auto":
        return text
    factor = float(text)
    if not math.isfinite(factor) or factor <= 0.0:
        raise ValueError("a unit scale is 'auto' or a positive number such as 0.01")
    return repr(factor)


@dataclass
class SceneSettings:
    """How a model file becomes a room: its units and the limits that keep a load safe."""

    unit_scale: str = _opt(
        "auto",
        "metres per file unit: auto (trust the file, warn if the room is implausible), "
        "or a factor such as 0.01 for centimetres or 0.0254 for inches",
        label="units (m per unit)",
        check=_unit_scale,
        choice_labels={
            "auto": "auto (as the file says)",
            "1.0": "metres (1)",
            "0.01": "centimetres (0.01)",
            "0.001": "millimetres (0.001)",
            "0.0254": "inches (0.0254)",
            "0.3048": "feet (0.3048)",
        },
    )
    max_texture_px: int = _opt(
        8192,
        "textures larger than this on their longest side are downscaled when loading",
        lo=16,
        hi=65536,
        label="largest texture (px)",
    )
    max_memory_mb: int = _opt(
        8192,
        "a file whose geometry and textures would need more memory than this is refused",
        lo=64,
        hi=1 << 20,
        label="memory limit per load (MB)",
    )


@dataclass
class Settings:
    stereo: StereoSettings = field(default_factory=StereoSettings)
    render: RenderSettings = field(default_factory=RenderSettings)
    navigation: NavigationSettings = field(default_factory=NavigationSettings)
    gaze: GazeSettings = field(default_factory=GazeSettings)
    tcr: TcrSettings = field(default_factory=TcrSettings)
    cps: CpsSettings = field(default_factory=CpsSettings)
    photons: PhotonSettings = field(default_factory=PhotonSettings)
    scene: SceneSettings = field(default_factory=SceneSettings)

    # -- dotted-key access -------------------------------------------------------------------
    def _locate(self, key: str) -> tuple[Any, dataclasses.Field[Any]]:
        parts = key.split(".")
        node: Any = self
        for i, name in enumerate(parts):
            fields = {f.name: f for f in dataclasses.fields(node)}
            if name not in fields:
                raise SettingsError(f"unknown setting '{key}' (known: {', '.join(self.keys())})")
            f = fields[name]
            if i == len(parts) - 1:
                if dataclasses.is_dataclass(getattr(node, name)):
                    raise SettingsError(f"'{key}' is a section, not a setting")
                return node, f
            node = getattr(node, name)
        raise SettingsError(f"unknown setting '{key}'")

    def get(self, key: str) -> Any:
        node, f = self._locate(key)
        return getattr(node, f.name)

    def set(self, key: str, value: Any) -> None:
        node, f = self._locate(key)
        setattr(node, f.name, _coerce(key, f, getattr(node, f.name), value))

    def apply(self, assignments: list[str] | None) -> None:
        """Apply ``key=value`` strings as given on the command line."""
        for text in assignments or []:
            key, sep, value = text.partition("=")
            if not sep:
                raise SettingsError(f"expected key=value, got '{text}'")
            self.set(key.strip(), value.strip())

    def keys(self) -> list[str]:
        return list(_walk(self, ""))

    def describe(self, key: str) -> dict[str, Any]:
        _node, f = self._locate(key)
        return dict(f.metadata)

    def to_dict(self) -> dict[str, Any]:
        return dataclasses.asdict(self)

    def copy(self) -> Settings:
        return copy.deepcopy(self)

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> Settings:
        """Build settings from a (possibly partial) nested dict; unknown keys are an error."""
        s = cls()
        for key, value in _flatten(data, ""):
            s.set(key, value)
        return s

    # -- presets on disk ---------------------------------------------------------------------
    def save(self, path: str | os.PathLike[str]) -> None:
        atomic_write_json(path, {"vrpreview_settings": 1, "settings": self.to_dict()})

    @classmethod
    def load(cls, path: str | os.PathLike[str]) -> Settings:
        try:
            with open(path, encoding="utf-8") as fh:
                doc = json.load(fh)
        except (OSError, json.JSONDecodeError) as exc:
            raise SettingsError(f"cannot read settings preset {path}: {exc}") from exc
        if not isinstance(doc, dict) or not isinstance(doc.get("settings"), dict):
            raise SettingsError(f"{path} is not a vrpreview settings preset")
        return cls.from_dict(doc["settings"])


def _walk(node: Any, prefix: str):
    for f in dataclasses.fields(node):
        value = getattr(node, f.name)
        if dataclasses.is_dataclass(value):
            yield from _walk(value, f"{prefix}{f.name}.")
        else:
            yield f"{prefix}{f.name}"


def _flatten(data: dict[str, Any], prefix: str):
    for k, v in data.items():
        if isinstance(v, dict):
            yield from _flatten(v, f"{prefix}{k}.")
        else:
            yield f"{prefix}{k}", v


def _coerce(key: str, f: dataclasses.Field[Any], current: Any, value: Any) -> Any:
    meta = f.metadata
    kind = type(current)
    try:
        if kind is bool:
            if isinstance(value, str):
                low = value.lower()
                if low not in ("1", "0", "true", "false", "on", "off", "yes", "no"):
                    raise ValueError(value)
                out: Any = low in ("1", "true", "on", "yes")
            else:
                out = bool(value)
        elif kind is int:
            out = int(value)
        elif kind is float:
            out = float(value)
            if not math.isfinite(out):
                raise ValueError("not a finite number")
        else:
            out = str(value)
        if meta.get("check") is not None:
            out = meta["check"](out)
    except (TypeError, ValueError) as exc:
        raise SettingsError(f"{key}: cannot use {value!r} ({exc})") from exc
    if meta.get("choices") and out not in meta["choices"]:
        raise SettingsError(f"{key}: {out!r} is not one of {', '.join(meta['choices'])}")
    lo, hi = meta.get("lo"), meta.get("hi")
    if lo is not None and out < lo or hi is not None and out > hi:
        raise SettingsError(f"{key}: {out} is outside [{lo}, {hi}]")
    return out
