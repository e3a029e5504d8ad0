"""What "full quality" means, where the fovea is, and the error of a frame against it.

The benchmark, the study and the window's quality panel all measure against the same reference
(:func:`full_quality`) with the same fovea/periphery split (:func:`fovea_mask`) and metrics
(:mod:`app.metrics`, on display values: the tone-mapped sRGB frames a user sees).
"""

from __future__ import annotations

import math

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
    ``converged_photons`` is False: then the current map); everything else the same."""
    ref = settings.copy()
    ref.tcr.enabled = False
    ref.tcr.tint = False
    ref.cps.mode = "none"
    ref.cps.visualize = False
    if converged_photons:
        ref.photons.photons = CONVERGED_PHOTONS
        ref.photons.radius_m = CONVERGED_RADIUS_M
    ref.photons.gather = "radius"
    ref.photons.fused = False
    ref.photons.stereo_reuse = False
    ref.photons.show_reuse = False
    return ref


def fovea_mask(cps: CpsSettings, frame: FrameInput, eye: int) -> np.ndarray:
    """Pixels of one eye the detail map keeps at level 0 (GL row order, row 0 at the bottom).

    With CPS on these are the pixels it shades at full rate. Without CPS the fovea is the same
    region around the gaze by angle alone (``cps.fovea_deg`` and the falloff, no edge caps),
    so every run has a fovea/periphery split."""
    view = frame.eyes[eye]
    if cps.mode == "cps" and frame.cps_caps:
        caps = frame.cps_caps[eye]
    else:
        caps = (cps.max_level,) * 3
    levels = detail_map(
        view, view.width, view.height, frame.gaze, dict(zip(("left", "right", "bottom"), caps)), cps
    )
    return levels == 0


def stereo_fovea(cps: CpsSettings, frame: FrameInput) -> np.ndarray:
    """Both eyes' fovea side by side, row 0 at the top (as read-back images are)."""
    return np.hstack([np.flipud(fovea_mask(cps, frame, e)) for e in range(2)])


def measure(
    reference: np.ndarray,
    test: np.ndarray,
    fovea: np.ndarray | None,
    ppd: float,
    regions: dict[str, np.ndarray] | None = None,
) -> dict:
    """PSNR, SSIM and FLIP for the frame, the fovea and the periphery (``{}`` for an empty
    one; absent without a ``fovea``) and any further ``regions``; the largest foveal
    difference, and the per-pixel error map (FLIP; without flip-evaluator the largest channel
    difference)."""
    masks: dict[str, np.ndarray | None] = {"frame": None}
    if fovea is not None:
        masks.update(fovea=fovea, periphery=~fovea)
    masks.update(regions or {})
    flip_error = metrics.flip_map(reference, test, ppd)
    out: dict = {
        name: r if r["pixels"] else {}
        for name, r in metrics.compare_regions(reference, test, ppd, masks, flip_error).items()
    }
    diff = np.abs(reference.astype(int) - test.astype(int))
    out["fovea_max_abs_diff"] = (
        int(diff[fovea].max()) if fovea is not None and fovea.any() else None
    )
    out["flip_map"] = flip_error if flip_error is not None else diff.max(axis=2) / 255.0
    return out


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


def summary_lines(report: dict) -> list[str]:
    """The figures as short lines for a panel or a log."""
    lines = []
    for region in ("frame", "fovea", "periphery"):
        r = report.get(region) or {}
        if not r:
            lines.append(f"{region}: -")
            continue
        psnr = r.get("psnr", math.nan)
        psnr_text = "identical" if psnr == math.inf else f"{psnr:.1f} dB"
        lines.append(
            f"{region}: PSNR {psnr_text}, SSIM {r.get('ssim', math.nan):.3f}, "
            f"FLIP {r.get('flip', math.nan):.3f}"
        )
    return lines
