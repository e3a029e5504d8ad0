"""CPU reference radiance estimate (SPEC D): radius gather and k-nearest baseline vs brute force."""

from __future__ import annotations

import math

import numpy as np
import pytest

import app.lab.photon_ref as ref
from app.lab.photon_ref import build_tree, estimate_knn, estimate_radius
from app.photon_map import PhotonMap, encode_directions


def make_photons(n: int, seed: int = 0, scale: float = 1.0, offset: float = 0.0) -> PhotonMap:
    rng = np.random.default_rng(seed)
    d = rng.normal(size=(n, 3))
    return PhotonMap(
        (offset + rng.random((n, 3)) * scale).astype(np.float32),
        rng.random((n, 3)).astype(np.float32),
        encode_directions(d),
    )


def brute(
    ph: PhotonMap, pts: np.ndarray, nrm: np.ndarray, r: float, k: int | None = None
) -> np.ndarray:
    """The estimate by definition: full sort per point, no tree."""
    pos = ph.positions.astype(np.float64)
    dirs = ph.directions.astype(np.float64)
    pw = ph.power.astype(np.float64)
    out = np.zeros((len(pts), 3))
    for i, (p, n) in enumerate(zip(np.asarray(pts, float), np.asarray(nrm, float))):
        if not (np.isfinite(p).all() and np.isfinite(n).all()):
            continue
        d = pos - p
        d2 = d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1] + d[:, 2] * d[:, 2]
        facing = dirs[:, 0] * n[0] + dirs[:, 1] * n[1] + dirs[:, 2] * n[2]
        counted = np.flatnonzero((d2 < r * r) & (facing < 0))
        nearest = counted[np.argsort(d2[counted], kind="stable")][:k]
        if k is None or len(counted) < k or d2[nearest[-1]] == 0.0:
            # (r_k == 0: all k at the point; the documented fallback to the radius form)
            out[i] = pw[counted].sum(axis=0) / (math.pi * r * r)
        else:
            out[i] = pw[nearest].sum(axis=0) / (math.pi * d2[nearest[-1]])
    return out


def queries(m: int, seed: int = 1, scale: float = 1.0, offset: float = 0.0):
    rng = np.random.default_rng(seed)
    return offset + rng.random((m, 3)) * scale, rng.normal(size=(m, 3))


@pytest.mark.parametrize("r", [0.03, 0.15, 0.6])
def test_radius_vs_brute_force(r) -> None:
    ph = make_photons(2000)
    pts, nrm = queries(300)
    got = estimate_radius(ph, pts, nrm, r)
    np.testing.assert_allclose(got, brute(ph, pts, nrm, r), rtol=1e-12, atol=0)
    assert got.shape == (300, 3) and got.dtype == np.float64
    if r >= 0.15:
        assert (got > 0).any()
    # a prebuilt tree and a single worker give the same
    np.testing.assert_allclose(
        estimate_radius(ph, pts, nrm, r, tree=build_tree(ph), workers=1), got, rtol=1e-12, atol=0
    )


@pytest.mark.parametrize("r,k", [(0.1, 1), (0.1, 8), (0.3, 8), (0.3, 60), (0.05, 500)])
def test_knn_vs_brute_force_sort(r, k) -> None:
    ph = make_photons(2000, seed=3)
    pts, nrm = queries(250, seed=4)
    got = estimate_knn(ph, pts, nrm, r, k)
    np.testing.assert_allclose(got, brute(ph, pts, nrm, r, k), rtol=1e-12, atol=0)


def test_knn_needs_more_neighbours_than_first_asked() -> None:
    # The 4k nearest all face away, the counting ones lie behind them: the query must widen.
    n_away, n_toward = 400, 50
    rng = np.random.default_rng(8)
    near = rng.normal(0, 0.01, (n_away, 3))
    far = rng.normal(0, 1, (n_toward, 3))
    far = 0.05 + 0.02 * far / np.linalg.norm(far, axis=1, keepdims=True)
    dirs = np.concatenate(
        [np.tile([0.0, 0.0, 1.0], (n_away, 1)), np.tile([0.0, 0.0, -1.0], (n_toward, 1))]
    )
    ph = PhotonMap(
        np.concatenate([near, far]).astype(np.float32),
        rng.random((n_away + n_toward, 3)).astype(np.float32),
        encode_directions(dirs),
    )
    pts = np.zeros((3, 3))
    nrm = np.tile([0.0, 0.0, 1.0], (3, 1))
    for k in (5, 20, 49, 50, 51):
        got = estimate_knn(ph, pts, nrm, 1.0, k)
        np.testing.assert_allclose(got, brute(ph, pts, nrm, 1.0, k), rtol=1e-12, atol=0)
        assert (got > 0).all()


def test_chunked_path_matches(monkeypatch: pytest.MonkeyPatch) -> None:
    ph = make_photons(1500, seed=5)
    pts, nrm = queries(400, seed=6)
    whole_r = estimate_radius(ph, pts, nrm, 0.25)
    whole_k = estimate_knn(ph, pts, nrm, 0.25, 10)
    monkeypatch.setattr(ref, "_PAIR_BUDGET", 97)
    monkeypatch.setattr(ref, "_MAX_CHUNK", 37)
    np.testing.assert_allclose(estimate_radius(ph, pts, nrm, 0.25), whole_r, rtol=1e-12, atol=0)
    np.testing.assert_allclose(estimate_knn(ph, pts, nrm, 0.25, 10), whole_k, rtol=1e-12, atol=0)


def test_tiny_and_huge_radius() -> None:
    ph = make_photons(300, seed=2, scale=2.0, offset=-1.0)
    pts, nrm = queries(40, seed=3, scale=2.0, offset=-1.0)
    pts[:5] = ph.positions[:5]  # exactly at photons: distance 0 < tiny r
    for r in (1e-9, 1e6):
        np.testing.assert_allclose(
            estimate_radius(ph, pts, nrm, r), brute(ph, pts, nrm, r), rtol=1e-12, atol=0
        )
        for k in (1, 7, 1000):
            np.testing.assert_allclose(
                estimate_knn(ph, pts, nrm, r, k), brute(ph, pts, nrm, r, k), rtol=1e-12, atol=0
            )
    tiny = estimate_radius(ph, pts, nrm, 1e-9)
    assert not tiny[5:].any()
    # huge r: every facing photon counts, over the huge disc
    big = estimate_radius(ph, pts, nrm, 1e6)
    assert big.max() < 1e-8 and (big > 0).any()


def test_large_coordinates() -> None:
    ph = make_photons(1000, seed=12, scale=50.0, offset=-1e6)
    pts, nrm = queries(100, seed=13, scale=50.0, offset=-1e6)
    for r in (1.0, 10.0):
        np.testing.assert_allclose(
            estimate_radius(ph, pts, nrm, r), brute(ph, pts, nrm, r), rtol=1e-12, atol=0
        )
        np.testing.assert_allclose(
            estimate_knn(ph, pts, nrm, r, 5), brute(ph, pts, nrm, r, 5), rtol=1e-12, atol=0
        )


def test_strict_radius_and_facing_tests() -> None:
    down = encode_directions(np.array([[0.0, 0.0, -1.0]] * 4))
    pos = np.array([[0.5, 0, 0], [0, 0.49999, 0], [0, 0, 0], [0, 0, 0.25]], np.float32)
    power = np.array([[1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 1]], np.float32)
    ph = PhotonMap(pos, power, down)
    up = np.array([[0.0, 0.0, 1.0]])
    r = 0.5
    e = estimate_radius(ph, np.zeros((1, 3)), up, r)[0] * math.pi * r * r
    # exactly at distance r: out; just inside: in
    np.testing.assert_allclose(e, [1.0, 2.0, 2.0])
    # facing the other way: nothing arrives at the front
    assert not estimate_radius(ph, np.zeros((1, 3)), -up, r).any()
    # a normal perpendicular to the travel direction (dot == 0) does not count either
    assert not estimate_radius(ph, np.zeros((1, 3)), np.array([[1.0, 0, 0]]), r).any()
    # zero normal: nothing counts
    assert not estimate_radius(ph, np.zeros((1, 3)), np.zeros((1, 3)), r).any()
    # k nearest: photons at 0 (blue), 0.25 (white): r_k = 0.25
    e2 = estimate_knn(ph, np.zeros((1, 3)), up, r, 2)[0]
    np.testing.assert_allclose(e2, np.array([1.0, 1.0, 2.0]) / (math.pi * 0.25**2))


def test_knn_all_at_the_point_falls_back_to_radius() -> None:
    ph = PhotonMap(
        np.zeros((3, 3), np.float32),
        np.ones((3, 3), np.float32),
        encode_directions(np.array([[0.0, 0.0, -1.0]] * 3)),
    )
    up = np.array([[0.0, 0.0, 1.0]])
    e = estimate_knn(ph, np.zeros((1, 3)), up, 0.1, 2)
    np.testing.assert_allclose(e, estimate_radius(ph, np.zeros((1, 3)), up, 0.1))
    assert np.isfinite(e).all()


def test_edge_cases() -> None:
    ph = make_photons(100)
    pts, nrm = queries(6)
    # no photons
    empty = PhotonMap.empty()
    assert not estimate_radius(empty, pts, nrm, 0.2).any()
    assert not estimate_knn(empty, pts, nrm, 0.2, 4).any()
    assert estimate_radius(empty, pts, nrm, 0.2).shape == (6, 3)
    # one photon
    one = ph.subset(np.array([0]))
    np.testing.assert_allclose(estimate_radius(one, pts, nrm, 0.7), brute(one, pts, nrm, 0.7))
    np.testing.assert_allclose(estimate_knn(one, pts, nrm, 0.7, 3), brute(one, pts, nrm, 0.7, 3))
    # no points
    assert estimate_radius(ph, np.zeros((0, 3)), np.zeros((0, 3)), 0.2).shape == (0, 3)
    assert estimate_knn(ph, np.zeros((0, 3)), np.zeros((0, 3)), 0.2, 3).shape == (0, 3)
    # NaN / inf points or normals give 0, the rest is unaffected
    bad_p, bad_n = pts.copy(), nrm.copy()
    bad_p[1] = np.nan
    bad_p[2, 0] = np.inf
    bad_n[3, 2] = np.nan
    for fn in (
        lambda p, n: estimate_radius(ph, p, n, 0.5),
        lambda p, n: estimate_knn(ph, p, n, 0.5, 5),
    ):
        got = fn(bad_p, bad_n)
        assert not got[1:4].any()
        np.testing.assert_allclose(got[[0, 4, 5]], fn(pts, nrm)[[0, 4, 5]])


@pytest.mark.parametrize("bad", [0.0, -0.1, float("nan"), float("inf")])
def test_bad_radius(bad) -> None:
    ph = make_photons(10)
    pts, nrm = queries(2)
    with pytest.raises(ValueError, match="r must be"):
        estimate_radius(ph, pts, nrm, bad)
    with pytest.raises(ValueError, match="r must be"):
        estimate_knn(ph, pts, nrm, bad, 3)


def test_bad_arguments() -> None:
    ph = make_photons(10)
    pts, nrm = queries(2)
    for k in (0, -1, 2.5, True):
        with pytest.raises(ValueError, match="k must be"):
            estimate_knn(ph, pts, nrm, 0.1, k)
    with pytest.raises(ValueError, match="shape"):
        estimate_radius(ph, pts, nrm[:1], 0.1)
