"""The governor's model (app/governor.py): its knobs, what each step loses, what each costs.

- :data:`KNOBS`: the quality knobs in the order of their steps, each step's loss from the
  measured error table (``governor_errors.json``, written by ``vrpreview study governor``)
  where it has the knob's steps, else from :data:`PRIOR_KNOBS`.
- :func:`cost_factors`: the shape of each pass category's cost against full quality for a
  set of knob values (the governor learns its scale from the timers, and corrects each step
  by what it measures); :func:`category` files a pass under its category.
"""

from __future__ import annotations

import json
import logging
import math
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from app.settings import Settings, SettingsError

log = logging.getLogger(__name__)

# Each pass's cost follows one quantity: the pixels it shades, the triangles it draws, the
# shadow maps it redraws, or the window's pixels (present and overlay run at window size).
# Coarse pixel shading's passes are their own categories: its lighting replaces the full-rate
# lighting, and its block levels and filter are a cost CPS adds (on llvmpipe they outweigh
# what CPS saves at every render scale on the showroom: the model must be able to learn that).
_CATEGORY = {
    "gbuffer": "geometry",
    "forward": "geometry",
    "emissive": "geometry",
    "shadows": "shadows",
    "shadow_mask": "shadow_mask",
    "lighting": "shading",
    "cps_lighting": "cps_shading",
    "cps_levels": "cps",
    "cps_filter": "cps",
    "cps_temporal": "cps",
    "cps_mask": "cps",
    "photons": "photons",
    "present": "output",
    "ab_split": "output",
    "overlay": "output",
    "daylight": "fixed",
    "reflections": "reflections",
}
CATEGORIES = (
    "pixels",
    "geometry",
    "shading",
    "cps_shading",
    "cps",
    "shadow_mask",
    "shadows",
    "photons",
    "output",
    "reflections",
    "fixed",
)
# A category not measured yet (CPS while it is off, the full-rate lighting while the user's
# CPS is on) is priced from one that was: (the other category, its share of that one's cost).
CATEGORY_PRIORS = {
    "cps_shading": ("shading", 1.0),
    "shading": ("cps_shading", 1.0),
    "cps": ("shading", 0.15),  # optimistic: CPS is tried, measured, and given back if it costs
}
#: The share of the geometry pass that a simplified level keeps, per render.lod_bias step,
#: where the renderer has not said how many triangles each level draws.
LOD_SHARE = {0: 1.0, 2: 0.7, 4: 0.55, 8: 0.45}
#: The allowed errors (pixels of the view, before the render scale) at which the renderer
#: counts the triangles in view (``Governor.lod_triangles``): a step's render.lod_bias b at
#: render scale s allows b / s of them.
LOD_ERRORS = (0.0, 1.0, 2.0, 3.0, 4.0, 6.0, 8.0, 12.0, 16.0, 24.0, 32.0, 48.0)
#: The part of the geometry pass that follows the triangles drawn, where they are counted
#: (the rest follows the pixels). Real rooms at 2x640x720 on llvmpipe: the bathroom 0.72,
#: the staircase 0.51 of the pass at full quality (367k and 241k triangles).
VERTEX_SHARE = 0.6


def triangle_share(triangles: dict[float, int], lod: float, scale: float) -> float:
    """The triangles drawn at ``render.lod_bias`` ``lod`` and render scale ``scale`` over
    those of the full level, from the renderer's count per allowed error (the nearest
    counted error at or below ``lod / scale``: never fewer triangles than will be drawn)."""
    full = triangles.get(0.0, 0)
    if full <= 0:
        return 1.0
    allowed = lod / max(scale, 1e-3) if lod > 0 else 0.0
    counted = max((e for e in triangles if e <= allowed + 1e-9), default=0.0)
    return min(1.0, triangles[counted] / full)


def category(pass_name: str) -> str:
    return _CATEGORY.get(pass_name, "pixels")


@dataclass(frozen=True)
class Knob:
    """One quality knob: ``steps`` are settings assignments from the first cheaper step to
    the cheapest (step 0 is the user's own value); ``error`` the quality each step loses
    (FLIP against full quality, whole frame). ``fovea`` knobs change the sharp area around
    the gaze: they go last."""

    name: str  # plain words for the panel
    key: str  # the settings key it is addressed by (skipped where it does not exist)
    steps: tuple[dict[str, Any], ...]
    error: tuple[float, ...]
    fovea: bool = False
    cheaper_is_higher: bool = False  # the key's value grows as the step gets cheaper
    # Its last step only when no other knob's step saves time, and it is given back first.
    last_resort: bool = False

    def error_of(self, step: dict[str, Any]) -> float:
        """The quality ``step`` (one of :attr:`steps`) loses against the step before it."""
        return self.error[self.steps.index(step)]

    def usable_steps(self, user: Settings) -> list[dict[str, Any]]:
        """The steps cheaper than what the user set (none where the key does not exist)."""
        try:
            mine = user.get(self.key)
        except SettingsError:
            return []
        if self.key == "cps.max_level" and user.cps.mode != "cps":
            return list(self.steps)  # CPS off: the governor may turn it on, from level 1
        names = [step[self.key] for step in self.steps]
        if mine in names and isinstance(mine, str):  # the steps after the user's own
            return list(self.steps[names.index(mine) + 1 :])
        out = []
        for step in self.steps:
            value = step[self.key]
            if isinstance(value, str):
                if value != mine:
                    out.append(step)
                continue
            if (value > mine) if self.cheaper_is_higher else (value < mine):
                out.append(step)
        return out


# The priors of the error table, per step the quality lost against the step before (FLIP-like
# units): small for the periphery's knobs (CPS blocks, fewer shadow redraws), larger for what
# the whole frame shows (hard shadow edges, the render scale after FSR 1's quality modes 0.77,
# 0.67, 0.59, 0.5 per axis, growing with the pixels lost), four times larger for the fovea's
# knobs. The measured table (ERROR_TABLE, from ``vrpreview study governor``) replaces them
# where it has a knob's steps.
PRIOR_KNOBS: tuple[Knob, ...] = (
    Knob(
        "shadow redraws",
        "render.shadow_updates_per_frame",
        ({"render.shadow_updates_per_frame": 1},),
        (0.002,),
    ),
    Knob(
        "coarse lighting in the periphery",
        "cps.max_level",
        tuple({"cps.mode": "cps", "cps.max_level": n} for n in (1, 2, 3, 4)),
        (0.004, 0.004, 0.006, 0.008),
        cheaper_is_higher=True,
    ),
    Knob(
        "simpler far geometry",
        "render.lod_bias",
        tuple({"render.lod_bias": n} for n in (2, 4, 8, 16)),
        (0.004, 0.006, 0.01, 0.03),  # 16 px: a last resort for rooms of many triangles
        cheaper_is_higher=True,
    ),
    Knob(
        "coarser textures",
        "tcr.level_bias",
        tuple({"tcr.level_bias": n} for n in (1, 2)),
        (0.003, 0.005),
        cheaper_is_higher=True,
    ),
    Knob(
        "reflections",
        "render.reflections",
        ({"render.reflections": "off"},),
        # Measured, not by the study (its reference keeps a run's reflections off, as its
        # shadows): FLIP 0.028 over the frame, 0.002 in the fovea, on six frames of the
        # showroom walk at 2 x 640x720 (the floor's sheen of the window and the lamps).
        (0.034,),
    ),
    Knob(
        "shadows",
        "render.shadows",
        ({"render.shadows": "hard"}, {"render.shadows": "off"}),
        (0.012, 0.3),  # none at all: a last resort (a hundred lamps in view)
        last_resort=True,
    ),
    Knob("plain enlarging", "render.upscaler", ({"render.upscaler": "bilinear"},), (0.006,)),
    Knob(
        "render scale",
        "render.scale",
        tuple({"render.scale": s} for s in (0.85, 0.77, 0.67, 0.59, 0.5, 0.42, 0.35)),
        (0.006, 0.006, 0.008, 0.01, 0.012, 0.016, 0.02),
    ),
    Knob(
        "sharp area around the gaze",
        "cps.fovea_deg",
        tuple({"cps.fovea_deg": d} for d in (7.0, 5.0, 3.5)),
        (0.04, 0.04, 0.05),
        fovea=True,
    ),
    Knob(
        "detail falloff",
        "cps.deg_per_level",
        tuple({"cps.deg_per_level": d} for d in (4.0, 3.0, 2.0)),
        (0.04, 0.04, 0.05),
        fovea=True,
    ),
)

#: The measured table: ``vrpreview study governor`` writes it (governor_errors.json in its
#: folder); the one beside this file was measured on the showroom walk at 2x640x720.
ERROR_TABLE = Path(__file__).with_name("governor_errors.json")
#: How much more an error in the fovea (where the viewer looks) counts than one elsewhere.
FOVEA_WEIGHT = 3.0
#: The least a step may cost (measured steps can come out at 0 on a scene they do not touch).
MIN_STEP_ERROR = 1e-4


def step_weight(figures: dict[str, float]) -> float:
    """One number for a step's loss: the frame's FLIP plus the fovea's, weighted."""
    return float(figures.get("flip", 0.0)) + FOVEA_WEIGHT * float(figures.get("fovea_flip", 0.0))


def load_error_table(path: Path = ERROR_TABLE) -> dict[str, list[float]]:
    """Per knob key, each step's measured ``weight`` (its loss counted from full quality or
    from its base); {} where the file is missing or unreadable (the priors then stand)."""
    try:
        data = json.loads(Path(path).read_text(encoding="utf-8"))
        out: dict[str, list[float]] = {}
        for key, steps in data["knobs"].items():
            weights = [float(s["weight"]) for s in steps]
            if weights and all(math.isfinite(w) and w >= 0.0 for w in weights):
                out[str(key)] = weights
        return out
    except FileNotFoundError:
        return {}
    except (OSError, ValueError, KeyError, TypeError) as exc:
        log.warning("governor error table %s unreadable (%s): the priors are used", path, exc)
        return {}


def measured_knobs(
    table: dict[str, list[float]], priors: tuple[Knob, ...] = PRIOR_KNOBS
) -> tuple[Knob, ...]:
    """The knobs with the table's errors: each step's loss over the worst step before it (the
    table holds losses from full quality), at least :data:`MIN_STEP_ERROR`; a knob with more
    steps than the table measured keeps its priors for the steps beyond."""
    out = []
    for knob in priors:
        weights = table.get(knob.key)
        if weights is None or not 0 < len(weights) <= len(knob.steps):
            out.append(knob)
            continue
        # Counted from the worst step before it, so the increments add up to the worst loss.
        before = [0.0, *np.maximum.accumulate(weights)[:-1]]
        errors = tuple(max(MIN_STEP_ERROR, float(w - b)) for w, b in zip(weights, before))
        out.append(replace(knob, error=errors + knob.error[len(errors) :]))
    return tuple(out)


KNOBS: tuple[Knob, ...] = measured_knobs(load_error_table())


def cost_factors(
    values: dict[str, Any], triangles: dict[float, int] | None = None
) -> dict[str, float]:
    """Each category's cost relative to full quality for these knob values (the model's
    shape; its scale is learnt): fullscreen work follows the pixels (scale squared), the
    geometry part its pixels and part its triangles (``triangles``: the renderer's count
    per allowed error, :func:`triangle_share`; else ``LOD_SHARE``), soft shadow edges cost
    more taps in the shadow mask than hard ones, CPS's lighting lights fewer samples outside
    the fovea (0 where CPS is off, as the full-rate lighting is 0 where it is on)."""
    s = float(values.get("render.scale", 1.0))
    lod = float(values.get("render.lod_bias", 0) or 0)
    lod_share = min((v for k, v in LOD_SHARE.items() if k <= lod), default=1.0)
    bias = int(values.get("tcr.level_bias", 0) or 0)
    cps_on = values.get("cps.mode") == "cps"
    level = int(values.get("cps.max_level", 0)) if cps_on else 0
    fovea = float(values.get("cps.fovea_deg", 10.0))
    falloff = float(values.get("cps.deg_per_level", 6.0))
    periphery = 1.0 - 0.5 * (1.0 - 0.5**level) if cps_on else 1.0
    if cps_on:  # a smaller sharp area and a faster falloff light fewer full-rate samples
        periphery *= 0.85 + 0.15 * min(1.0, fovea / 10.0) * min(1.0, falloff / 6.0)
    upscaler = values.get("render.upscaler", "edge")
    shadows = values.get("render.shadows", "soft")
    soft = {"soft": 1.0, "hard": 0.85}.get(shadows, 0.0)  # off: no mask, no maps drawn
    updates = max(1, int(values.get("render.shadow_updates_per_frame", 2)))
    return {
        "pixels": s * s,
        "geometry": (
            (VERTEX_SHARE * triangle_share(triangles, lod, s) + (1.0 - VERTEX_SHARE) * s * s)
            if triangles
            else (0.4 + 0.6 * s * s) * lod_share
        )
        * 0.97**bias,
        "shading": 0.0 if cps_on else s * s,
        "cps_shading": s * s * periphery if cps_on else 0.0,
        "cps": 0.2 + 0.8 * s * s if cps_on else 0.0,
        "shadow_mask": s * s * soft,
        "shadows": min(1.0, updates / 2.0) if soft > 0.0 else 0.0,
        "photons": s * s,
        # Enlarging the eyes (tone map at the drawn size, then EASU at the view's) measured
        # 2-2.5x the plain present on llvmpipe; bilinear enlarging about the same as none.
        "output": 1.0 if s >= 0.999 else (2.0 if upscaler == "edge" else 1.0),
        "reflections": s * s if values.get("render.reflections", "screen") == "screen" else 0.0,
        "fixed": 1.0,
    }


#: The cost categories in the frame-rate panel's words.
CATEGORY_WORDS = {
    "pixels": "screen effects",
    "geometry": "drawing the surfaces",
    "shading": "lighting",
    "shadows": "shadow maps",
    "output": "showing the picture",
    "fixed": "daylight",
}


def shown_value(key: str, value: Any) -> str:
    """A knob's value as the panel shows it (the render scale in %, angles in degrees)."""
    if key == "render.scale":
        return f"{round(100 * float(value))}%"
    if key in ("cps.fovea_deg", "cps.deg_per_level"):
        return f"{value:g}°"
    return str(value)
