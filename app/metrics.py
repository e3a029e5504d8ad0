"""Image error against a full-quality reference: PSNR, SSIM and FLIP, whole or inside a mask.

All three are computed on display values (the tone-mapped, sRGB-encoded 8-bit frames a user
sees), as floats in [0, 1]. FLIP (NVIDIA's perceptual metric, flip-evaluator package) needs the
viewing condition as pixels per degree, which we take from the eye's field of view.
"""

from __future__ import annotations

import math

import numpy as np


def _float(img: np.ndarray) -> np.ndarray:
    a = np.asarray(img)
    return a.astype(np.float64) / 255.0 if a.dtype == np.uint8 else a.astype(np.float64)


def _select(mask: np.ndarray | None, shape: tuple[int, ...]) -> np.ndarray:
    if mask is None:
        return np.ones(shape[:2], bool)
    return np.asarray(mask, bool)


def psnr(reference: np.ndarray, test: np.ndarray, mask: np.ndarray | None = None) -> float:
    """Peak signal-to-noise ratio in dB (inf for identical pixels; nan for an empty mask)."""
    a, b = _float(reference), _float(test)
    m = _select(mask, a.shape)
    if not m.any():
        return math.nan
    mse = float(((a - b) ** 2)[m].mean())
    return math.inf if mse == 0.0 else 10.0 * math.log10(1.0 / mse)


def _gaussian_blur(x: np.ndarray, sigma: float = 1.5, radius: int = 5) -> np.ndarray:
    t = np.arange(-radius, radius + 1)
    k = np.exp(-0.5 * (t / sigma) ** 2)
    k /= k.sum()
    pad = np.pad(x, ((radius, radius), (radius, radius)), mode="reflect")
    rows = sum(k[i] * pad[:, i : i + x.shape[1]] for i in range(2 * radius + 1))
    return sum(k[i] * rows[i : i + x.shape[0], :] for i in range(2 * radius + 1))


def ssim_map(reference: np.ndarray, test: np.ndarray) -> np.ndarray:
    """Wang et al. 2004 SSIM on luma with an 11x11 Gaussian window (sigma 1.5)."""
    weights = np.array([0.299, 0.587, 0.114])
    a = _float(reference)[..., :3] @ weights
    b = _float(test)[..., :3] @ weights
    c1, c2 = 0.01**2, 0.03**2
    mu_a, mu_b = _gaussian_blur(a), _gaussian_blur(b)
    var_a = _gaussian_blur(a * a) - mu_a**2
    var_b = _gaussian_blur(b * b) - mu_b**2
    cov = _gaussian_blur(a * b) - mu_a * mu_b
    return ((2 * mu_a * mu_b + c1) * (2 * cov + c2)) / (
        (mu_a**2 + mu_b**2 + c1) * (var_a + var_b + c2)
    )


def ssim(reference: np.ndarray, test: np.ndarray, mask: np.ndarray | None = None) -> float:
    m = _select(mask, np.shape(reference))
    if not m.any():
        return math.nan
    return float(ssim_map(reference, test)[m].mean())


def pixels_per_degree(width_px: int, horizontal_fov_deg: float) -> float:
    return width_px / max(horizontal_fov_deg, 1e-6)


def flip_map(reference: np.ndarray, test: np.ndarray, ppd: float) -> np.ndarray | None:
    """Per-pixel FLIP error in [0, 1] (LDR, sRGB inputs), or None without flip-evaluator."""
    try:
        import flip_evaluator
    except ImportError:
        return None
    err, _mean, _params = flip_evaluator.evaluate(
        _float(reference).astype(np.float32),
        _float(test).astype(np.float32),
        "LDR",
        inputsRGB=True,
        applyMagma=False,
        computeMeanError=False,
        parameters={"ppd": ppd},
    )
    return np.asarray(err, np.float64).reshape(np.shape(reference)[:2])


def flip(
    reference: np.ndarray, test: np.ndarray, ppd: float, mask: np.ndarray | None = None
) -> float:
    m = _select(mask, np.shape(reference))
    fm = flip_map(reference, test, ppd)
    if fm is None or not m.any():
        return math.nan
    return float(fm[m].mean())


def compare(
    reference: np.ndarray, test: np.ndarray, ppd: float, mask: np.ndarray | None = None
) -> dict[str, float]:
    """PSNR, SSIM and FLIP of ``test`` against ``reference``, optionally inside ``mask``."""
    return compare_regions(reference, test, ppd, {"": mask})[""]


def compare_regions(
    reference: np.ndarray,
    test: np.ndarray,
    ppd: float,
    masks: dict[str, np.ndarray | None],
    flip_error: np.ndarray | None = None,
) -> dict[str, dict[str, float]]:
    """:func:`compare` for several regions (None: the whole image) of one pair of images,
    computing the SSIM and FLIP maps once (``flip_error``: a FLIP map already computed)."""
    fm = flip_error if flip_error is not None else flip_map(reference, test, ppd)
    sm = ssim_map(reference, test)
    out = {}
    for name, mask in masks.items():
        m = _select(mask, np.shape(reference))
        out[name] = {
            "psnr_db": psnr(reference, test, m),
            "ssim": float(sm[m].mean()) if m.any() else math.nan,
            "flip": float(fm[m].mean()) if fm is not None and m.any() else math.nan,
            "pixels": int(m.sum()),
        }
    return out
