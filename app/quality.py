"""What "full quality" means, where the fovea is, and the error of a frame against it.

The benchmark, the study and the window's quality panel all measure against the same reference
(:func:`full_quality`, drawn by :class:`render.quality.FullQualityReference`) with the same
fovea/periphery split (:func:`fovea_mask`) and metrics (:mod:`app.metrics`, on display values:
the tone-mapped sRGB frames a user sees), as :class:`ErrorFigures`. A model, not part of the
lab: render's quality probe (for the window) uses it, and render may not import the lab.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import asdict, dataclass
from typing import cast

import numpy as np

from app import metrics
from app.cps import detail_map
from app.frame import FrameInput
from app.settings import CpsSettings, Settings

# The converged photon map: 4M photon paths gathered within 10 cm (in the showroom about 700
# photons per estimate: a few per cent of noise at a 10 cm blur), the same for every run.
CONVERGED_PHOTONS = 1 << 22
CONVERGED_RADIUS_M = 0.1


def full_quality(settings: Settings, converged_photons: bool = True) -> Settings:
    """The reference a setting's errors are measured against: finest textures (TCR off),
    full-rate lighting without a mask (CPS none) and, where there is indirect light, the
    photon map gathered per eye without reuse (converged: 4M paths at r = 10 cm, unless
    ``converged_photons`` is False: then the current map), drawn at full resolution with no
    frame rate held, the meshes as loaded and soft shadow edges (where shadows are on);
    everything else the same."""
    ref = settings.copy()
    ref.tcr.enabled = False
    ref.tcr.tint = False
    ref.cps.mode = "none"
    ref.cps.visualize = False
    if converged_photons:
        ref.photons.photons = CONVERGED_PHOTONS
        ref.photons.radius_m = CONVERGED_RADIUS_M
    ref.photons.gather = "radius"
    ref.photons.indirect = "gather"  # the converged reference is the paper's gather
    ref.photons.fused = False
    ref.photons.stereo_reuse = False
    ref.photons.show_reuse = False
    ref.render.target_fps = "0"  # the reference holds no frame rate: every knob at full
    # One frame's reference depends on that frame alone: no running mean of its own (a
    # refining frame's jitter is drawn once, at full quality).
    ref.render.refine = "off"
    ref.render.scale = 1.0
    ref.tcr.level_bias = 0
    ref.render.lod_bias = 0.0  # the meshes as loaded
    if ref.render.shadows == "hard":
        ref.render.shadows = "soft"  # shadows on: their filtered edges
    return ref


def fovea_mask(cps: CpsSettings, frame: FrameInput, eye: int) -> np.ndarray:
    """Pixels of one eye the detail map keeps at level 0 (GL row order, row 0 at the bottom).

    With CPS on these are the pixels it shades at full rate. Without CPS the fovea is the same
    region around the gaze by angle alone (``cps.fovea_deg`` and the falloff, no edge caps),
    so every run has a fovea/periphery split."""
    view = frame.eyes[eye]
    caps: tuple[float, float, float]
    if cps.mode == "cps" and frame.cps_caps:
        caps = frame.cps_caps[eye]
    else:
        caps = (cps.max_level,) * 3
    # FrameInput types the caps as floats; they are SideCaps levels (ints), as detail_map takes.
    sides = cast(Mapping[str, int], dict(zip(("left", "right", "bottom"), caps)))
    levels = detail_map(view, view.width, view.height, frame.gaze, sides, cps)
    return levels == 0


def stereo_fovea(cps: CpsSettings, frame: FrameInput) -> np.ndarray:
    """Both eyes' fovea side by side, row 0 at the top (as read-back images are)."""
    return np.hstack([np.flipud(fovea_mask(cps, frame, e)) for e in range(2)])


@dataclass(frozen=True)
class ErrorFigures:
    """The error of one region of one frame against full quality (display values).

    ``psnr_db`` is infinite for identical pixels; ``flip`` is NaN without flip-evaluator."""

    psnr_db: float
    ssim: float
    flip: float
    pixels: int

    def to_dict(self) -> dict[str, float | int]:
        return asdict(self)


@dataclass
class FrameErrors:
    """:func:`measure`'s figures for one frame: the whole frame, the fovea and the periphery
    (None where a region is empty or, without a fovea, not asked for), further named
    ``regions`` (e.g. the gazed object), the largest foveal difference and the per-pixel error
    map (FLIP; without flip-evaluator the largest channel difference)."""

    frame: ErrorFigures | None
    fovea: ErrorFigures | None
    periphery: ErrorFigures | None
    regions: dict[str, ErrorFigures | None]
    fovea_max_abs_diff: int | None
    flip_map: np.ndarray
    has_fovea: bool = True

    def region(self, name: str) -> ErrorFigures | None:
        if name in ("frame", "fovea", "periphery"):
            return getattr(self, name)
        return self.regions.get(name)

    def to_dict(self) -> dict:
        """The figures as plain data ({} for an empty region), the error map as it is."""
        names = ["frame", *(("fovea", "periphery") if self.has_fovea else ()), *self.regions]
        out: dict = {}
        for name in names:
            figures = self.region(name)
            out[name] = figures.to_dict() if figures is not None else {}
        out["fovea_max_abs_diff"] = self.fovea_max_abs_diff
        out["flip_map"] = self.flip_map
        return out


def measure(
    reference: np.ndarray,
    test: np.ndarray,
    fovea: np.ndarray | None,
    ppd: float,
    regions: dict[str, np.ndarray] | None = None,
) -> FrameErrors:
    """PSNR, SSIM and FLIP of ``test`` against ``reference`` for the frame, the fovea and the
    periphery (without a ``fovea``: the frame only) and any further ``regions``."""
    masks: dict[str, np.ndarray | None] = {"frame": None}
    if fovea is not None:
        masks.update(fovea=fovea, periphery=~fovea)
    masks.update(regions or {})
    flip_error = metrics.flip_map(reference, test, ppd)
    figures = {
        name: ErrorFigures(r["psnr_db"], r["ssim"], r["flip"], int(r["pixels"]))
        if r["pixels"]
        else None
        for name, r in metrics.compare_regions(reference, test, ppd, masks, flip_error).items()
    }
    diff = np.abs(reference.astype(int) - test.astype(int))
    return FrameErrors(
        frame=figures.pop("frame"),
        fovea=figures.pop("fovea", None),
        periphery=figures.pop("periphery", None),
        regions=figures,
        fovea_max_abs_diff=(int(diff[fovea].max()) if fovea is not None and fovea.any() else None),
        flip_map=flip_error if flip_error is not None else diff.max(axis=2) / 255.0,
        has_fovea=fovea is not None,
    )


# A short magma-like ramp: black (no error), purple, orange, pale yellow (FLIP 1).
_RAMP = np.array([[0, 0, 4], [80, 18, 123], [182, 54, 121], [251, 136, 97], [252, 253, 191]], float)


def heat_map(error: np.ndarray, scale: float = 0.25) -> np.ndarray:
    """An (H, W, 4) uint8 overlay of a per-pixel error in [0, 1]: the ramp over [0, scale]
    (errors at or above ``scale`` are the brightest), alpha rising with the error so that
    correct pixels stay visible underneath."""
    e = np.nan_to_num(np.asarray(error, float), nan=0.0, posinf=1.0, neginf=0.0)
    t = np.clip(e / max(scale, 1e-6), 0.0, 1.0) * (len(_RAMP) - 1)
    lo = np.floor(t).astype(int)
    hi = np.minimum(lo + 1, len(_RAMP) - 1)
    f = (t - lo)[..., None]
    rgb = _RAMP[lo] * (1 - f) + _RAMP[hi] * f
    alpha = np.clip(0.15 + 3.0 * e / max(scale, 1e-6), 0.0, 0.85) * (e > 1e-4)
    return np.dstack([rgb, 255.0 * alpha]).round().astype(np.uint8)
