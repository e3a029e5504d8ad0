"""The SSIM measurement behind app.metrics' switch to scikit-image (not a test: a script).

Compares the numpy SSIM app.metrics had (copied here) with skimage's structural_similarity on
the same window (Gaussian, sigma 1.5, 11x11, population covariance, K1 0.01, K2 0.03, data
range 1): the largest map difference (whole, and 5 px or more from the border), both means,
and the time of both on one 2x640x720 frame, back to back. Renders are read from
/tmp/ssimimg/{full,cps,corr_full,corr_blur}.png when present (``vrpreview render ...``).

    PYTHONPATH=. python tests/measure_ssim.py [repeats]
"""

import sys
import time

import numpy as np
from PIL import Image
from skimage.metrics import structural_similarity

WEIGHTS = np.array([0.299, 0.587, 0.114])


def _float(img):
    a = np.asarray(img)
    return a.astype(np.float64) / 255.0 if a.dtype == np.uint8 else a.astype(np.float64)


def _gaussian_blur(x, sigma=1.5, radius=5):
    t = np.arange(-radius, radius + 1)
    k = np.exp(-0.5 * (t / sigma) ** 2)
    k /= k.sum()
    pad = np.pad(x, ((radius, radius), (radius, radius)), mode="reflect")
    rows = sum(k[i] * pad[:, i : i + x.shape[1]] for i in range(2 * radius + 1))
    return sum(k[i] * rows[i : i + x.shape[0], :] for i in range(2 * radius + 1))


def ours_map(reference, test):
    a = _float(reference)[..., :3] @ WEIGHTS
    b = _float(test)[..., :3] @ WEIGHTS
    c1, c2 = 0.01**2, 0.03**2
    mu_a, mu_b = _gaussian_blur(a), _gaussian_blur(b)
    var_a = _gaussian_blur(a * a) - mu_a**2
    var_b = _gaussian_blur(b * b) - mu_b**2
    cov = _gaussian_blur(a * b) - mu_a * mu_b
    return ((2 * mu_a * mu_b + c1) * (2 * cov + c2)) / (
        (mu_a**2 + mu_b**2 + c1) * (var_a + var_b + c2)
    )


def sk(reference, test):
    a = _float(reference)[..., :3] @ WEIGHTS
    b = _float(test)[..., :3] @ WEIGHTS
    return structural_similarity(
        a,
        b,
        gaussian_weights=True,
        sigma=1.5,
        use_sample_covariance=False,
        data_range=1.0,
        K1=0.01,
        K2=0.03,
        full=True,
    )


def pairs():
    rng = np.random.default_rng(0)
    r1 = rng.integers(0, 256, (720, 1280, 3), dtype=np.uint8)
    r2 = np.clip(r1.astype(int) + rng.integers(-20, 21, r1.shape), 0, 255).astype(np.uint8)
    yield "random 720x1280 +-20 noise", r1, r2
    yield "random vs random", r1, rng.integers(0, 256, r1.shape, dtype=np.uint8)
    for a, b in (("full", "cps"), ("corr_full", "corr_blur")):
        try:
            A = np.asarray(Image.open(f"/tmp/ssimimg/{a}.png").convert("RGB"))
            B = np.asarray(Image.open(f"/tmp/ssimimg/{b}.png").convert("RGB"))
            yield f"render {a} vs {b} {A.shape[1]}x{A.shape[0]}", A, B
        except OSError as e:
            print("missing", a, b, e)
    flat = np.full((720, 1280, 3), 128, np.uint8)
    yield "flat equal", flat, flat
    yield "flat 128 vs 140", flat, np.full_like(flat, 140)
    for shape in ((1, 1), (3, 3), (10, 10), (11, 11), (11, 40)):
        x = rng.integers(0, 256, (*shape, 3), dtype=np.uint8)
        y = rng.integers(0, 256, (*shape, 3), dtype=np.uint8)
        yield f"tiny {shape[0]}x{shape[1]}", x, y


def main():
    print(
        f"{'case':36s} {'max|map diff|':>14s} {'interior':>10s} {'ours mean':>11s} "
        f"{'sk mssim':>10s} {'|mean diff|':>11s}"
    )
    for name, a, b in pairs():
        om = ours_map(a, b)
        try:
            mssim, smap = sk(a, b)
        except ValueError as e:
            print(f"{name:36s} skimage raises: {str(e)[:60]}; ours mean {om.mean():.6f}")
            continue
        d = np.abs(om - smap)
        inner = d[5:-5, 5:-5] if min(d.shape) > 10 else np.zeros(1)
        print(
            f"{name:36s} {d.max():14.3e} {inner.max():10.3e} {om.mean():11.6f} "
            f"{mssim:10.6f} {abs(om.mean() - mssim):11.3e}"
        )
    # Timing: 2x640x720 (one side-by-side frame, 720x1280), back to back, interleaved.
    rng = np.random.default_rng(1)
    a = rng.integers(0, 256, (720, 1280, 3), dtype=np.uint8)
    b = np.clip(a.astype(int) + rng.integers(-10, 11, a.shape), 0, 255).astype(np.uint8)
    ours_t, sk_t = [], []
    for i in range(int(sys.argv[1]) if len(sys.argv) > 1 else 7):
        order = ((ours_map, ours_t), (sk, sk_t))
        for fn, times in order if i % 2 == 0 else order[::-1]:  # neither always goes first
            t = time.perf_counter()
            fn(a, b)
            times.append(time.perf_counter() - t)
    om, sm = np.median(ours_t), np.median(sk_t)
    print(
        f"time 720x1280 ({len(ours_t)} repeats, median): ours {1000 * om:.0f} ms "
        f"(min {1000 * min(ours_t):.0f}), skimage {1000 * sm:.0f} ms (min {1000 * min(sk_t):.0f}); "
        f"ours/skimage {om / sm:.2f}"
    )


if __name__ == "__main__":
    main()
