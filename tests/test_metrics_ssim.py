"""SSIM is scikit-image's (Wang et al. 2004 with its Gaussian window), on renders and edge cases."""

from __future__ import annotations

import math

import numpy as np
import pytest
from skimage.metrics import structural_similarity

from app import metrics, scenes
from app.session import Session
from app.settings import Settings

LUMA = np.array([0.299, 0.587, 0.114])


def skimage_ssim(a: np.ndarray, b: np.ndarray) -> tuple[float, np.ndarray]:
    """skimage with the paper's window, as its documentation says to match Wang et al."""
    return structural_similarity(
        a.astype(np.float64) @ LUMA / 255.0,
        b.astype(np.float64) @ LUMA / 255.0,
        gaussian_weights=True,
        sigma=1.5,
        use_sample_covariance=False,
        data_range=1.0,
        full=True,
    )


def noisy_pair(shape=(90, 160), spread=20, seed=0):
    rng = np.random.default_rng(seed)
    a = rng.integers(0, 256, (*shape, 3), dtype=np.uint8)
    b = np.clip(a.astype(int) + rng.integers(-spread, spread + 1, a.shape), 0, 255)
    return a, b.astype(np.uint8)


def rendered_pair() -> tuple[np.ndarray, np.ndarray]:
    """The showroom at full rate and with a blurred periphery (two real frames)."""
    from render.offscreen import OffscreenHost

    settings = Settings()
    scene = scenes.resolve("showroom")
    session = Session(settings)
    session.set_scene(scene, scenes.default_path(scene))
    session.apply_path_frame(100)
    host = OffscreenHost(320, 180, settings)
    try:
        host.set_scene(scene)
        host.set_text_image(None)
        full = host.draw(session.frame_input(*host.eye_size))
        settings.cps.mode = "blur-mask"
        blurred = host.draw(session.frame_input(*host.eye_size))
    finally:
        host.close()
    return full, blurred


@pytest.mark.parametrize("case", ["noise", "random", "render", "gradient"])
def test_ssim_is_skimage_structural_similarity(case):
    if case == "noise":
        a, b = noisy_pair()
    elif case == "random":
        a, _ = noisy_pair(seed=1)
        b, _ = noisy_pair(seed=2)
    elif case == "render":
        a, b = rendered_pair()
        assert not np.array_equal(a, b)
    else:
        ramp = np.linspace(0, 255, 64)
        a = np.repeat(np.add.outer(ramp, ramp)[..., None] / 2, 3, axis=2).astype(np.uint8)
        b = np.roll(a, 2, axis=1)
    expected, expected_map = skimage_ssim(a, b)
    assert metrics.ssim(a, b) == pytest.approx(expected, abs=1e-6)
    np.testing.assert_allclose(metrics.ssim_map(a, b), expected_map, atol=1e-6)
    whole = metrics.compare(a, b, ppd=10.0)
    assert whole["ssim"] == pytest.approx(expected, abs=1e-6)
    assert -1.0 <= expected < 1.0


def test_inside_a_mask_ssim_is_the_mean_of_the_map_there():
    a, b = noisy_pair(spread=60)
    b[:, 80:] = a[:, 80:]  # the right half unchanged
    mask = np.zeros(a.shape[:2], bool)
    mask[:, 100:] = True
    _, expected_map = skimage_ssim(a, b)
    assert metrics.ssim(a, b, mask) == pytest.approx(expected_map[mask].mean(), abs=1e-9)
    assert metrics.ssim(a, b, mask) > 0.99 > metrics.ssim(a, b, ~mask)
    regions = metrics.compare_regions(a, b, 10.0, {"right": mask, "none": np.zeros_like(mask)})
    assert regions["right"]["ssim"] == pytest.approx(expected_map[mask].mean(), abs=1e-9)
    assert math.isnan(regions["none"]["ssim"]) and regions["none"]["pixels"] == 0


def test_flat_images_give_the_luminance_term_alone():
    a = np.full((40, 60, 3), 128, np.uint8)
    assert metrics.ssim(a, a) == pytest.approx(1.0, abs=1e-12)
    b = np.full_like(a, 140)
    x, y, c1 = 128 / 255, 140 / 255, 0.01**2
    assert metrics.ssim(a, b) == pytest.approx((2 * x * y + c1) / (x * x + y * y + c1), abs=1e-9)


@pytest.mark.parametrize("shape", [(1, 1), (3, 3), (10, 10), (4, 200)])
def test_images_smaller_than_the_window_use_one_global_window(shape):
    rng = np.random.default_rng(3)
    a = rng.integers(0, 256, (*shape, 3), dtype=np.uint8)
    b = rng.integers(0, 256, (*shape, 3), dtype=np.uint8)
    with pytest.raises(ValueError, match="win_size exceeds image extent"):
        skimage_ssim(a, b)  # what the fallback is for
    assert metrics.ssim(a, a) == pytest.approx(1.0)
    la, lb = a.astype(np.float64) @ LUMA / 255.0, b.astype(np.float64) @ LUMA / 255.0
    c1, c2 = 0.01**2, 0.03**2
    cov = ((la - la.mean()) * (lb - lb.mean())).mean()
    expected = ((2 * la.mean() * lb.mean() + c1) * (2 * cov + c2)) / (
        (la.mean() ** 2 + lb.mean() ** 2 + c1) * (la.var() + lb.var() + c2)
    )
    assert metrics.ssim(a, b) == pytest.approx(expected, abs=1e-12)
    assert metrics.ssim_map(a, b).shape == shape


def test_images_of_different_sizes_are_refused_with_the_sizes():
    with pytest.raises(ValueError, match="different sizes"):
        metrics.ssim(np.zeros((20, 20, 3), np.uint8), np.zeros((20, 21, 3), np.uint8))
