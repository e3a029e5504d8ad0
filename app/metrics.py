"""Image error against a full-quality reference: PSNR, SSIM and FLIP, whole or inside a mask.

All three are computed on display values (the tone-mapped, sRGB-encoded 8-bit frames a user
sees), as floats in [0, 1]. SSIM is scikit-image's ``structural_similarity`` (against the numpy
SSIM this module had: equal to 1e-12 away from the border, and faster). FLIP (NVIDIA's
perceptual metric, flip-evaluator package) needs the viewing condition as pixels per degree,
which we take from the eye's field of view.
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


# Wang et al. 2004 as scikit-image spells it: an 11x11 Gaussian window (sigma 1.5, truncated at
# 3.5 sigma), population covariance, K1 0.01, K2 0.03, values in [0, 1]. skimage's filter is
# scipy's (1.4x faster than the numpy blur this module had, and equal to it to 1e-12 away from
# the border); its border is the reflect mode that repeats the edge pixel.
SSIM_SIGMA = 1.5
SSIM_WINDOW = 11  # 2 * int(3.5 * sigma + 0.5) + 1: the smallest side skimage accepts
_K1, _K2 = 0.01, 0.03
_LUMA = np.array([0.299, 0.587, 0.114])


def _luma(img: np.ndarray) -> np.ndarray:
    a = _float(img)
    return a[..., :3] @ _LUMA if a.ndim == 3 else a


def _skimage_ssim(a: np.ndarray, b: np.ndarray) -> tuple[float, np.ndarray]:
    from skimage.metrics import structural_similarity

    mssim, smap = structural_similarity(
        a,
        b,
        gaussian_weights=True,
        sigma=SSIM_SIGMA,
        use_sample_covariance=False,
        data_range=1.0,
        K1=_K1,
        K2=_K2,
        full=True,
    )
    return float(mssim), np.asarray(smap, np.float64)


def _global_ssim(a: np.ndarray, b: np.ndarray) -> float:
    """SSIM of the whole image as one window (uniform weights): for images smaller than the
    window, where skimage refuses."""
    c1, c2 = _K1**2, _K2**2
    mu_a, mu_b = float(a.mean()), float(b.mean())
    var_a, var_b = float(a.var()), float(b.var())
    cov = float(((a - mu_a) * (b - mu_b)).mean())
    return ((2 * mu_a * mu_b + c1) * (2 * cov + c2)) / (
        (mu_a**2 + mu_b**2 + c1) * (var_a + var_b + c2)
    )


def _ssim(reference: np.ndarray, test: np.ndarray) -> tuple[float, np.ndarray]:
    a, b = _luma(reference), _luma(test)
    if a.shape != b.shape:
        raise ValueError(f"SSIM of images of different sizes: {a.shape} and {b.shape}")
    if min(a.shape) < SSIM_WINDOW:
        value = _global_ssim(a, b) if a.size else math.nan
        return value, np.full(a.shape, value)
    return _skimage_ssim(a, b)


def ssim_map(reference: np.ndarray, test: np.ndarray) -> np.ndarray:
    """Per-pixel SSIM on luma: scikit-image's ``structural_similarity`` map (Wang et al. 2004,
    11x11 Gaussian window, sigma 1.5); an image under 11 px on a side gets its one global
    SSIM everywhere."""
    return _ssim(reference, test)[1]


def ssim(reference: np.ndarray, test: np.ndarray, mask: np.ndarray | None = None) -> float:
    """SSIM on luma. Whole image (no ``mask``): skimage's mean, which leaves out the 5 px
    border where the window hangs over the edge; inside a mask: the map's mean there."""
    if mask is None:
        return _ssim(reference, test)[0]
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
    whole, sm = _ssim(reference, test)
    out = {}
    for name, mask in masks.items():
        m = _select(mask, np.shape(reference))
        out[name] = {
            "psnr_db": psnr(reference, test, m),
            "ssim": whole if mask is None else float(sm[m].mean()) if m.any() else math.nan,
            "flip": float(fm[m].mean()) if fm is not None and m.any() else math.nan,
            "pixels": int(m.sum()),
        }
    return out
