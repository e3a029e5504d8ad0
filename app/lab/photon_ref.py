"""CPU reference of the photon-map radiance estimate (SPEC D), with scipy's cKDTree.

This is the peer a user would pick, and the ground truth the GPU gathers are checked against.
For a query point P with normal N and radius r a photon COUNTS when

    |x_p - P|^2 < r^2  (strict, float64 from the float32 positions)  and  dot(N, dir_p) < 0,

``dir_p`` being the decoded travel direction (the photon arrived at the front of the surface).
The irradiance is ``E(P) = sum(power_p over counted) / (pi r^2)`` per RGB channel; the renderer
multiplies by rho / pi later. A point or normal with a non-finite component gives 0; so does a
zero normal (nothing arrives against it).

The query points are processed in Z order, in chunks sized so that the photon lists of a chunk
hold about ``_PAIR_BUDGET`` pairs (estimated from a few probe points), which keeps memory bounded
for any radius; the sums are vectorised (``np.bincount`` over the flattened lists).
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Iterator

import numpy as np
from scipy.spatial import cKDTree

from app.hashgrid import check_radius
from app.photon_map import PhotonMap

_PAIR_BUDGET = 1 << 21  # photon-point pairs listed at once (Python lists cost ~36 B a pair)
_MAX_CHUNK = 16384  # query points per cKDTree call at most
_PROBES = 16  # points of a chunk whose photon counts estimate the chunk's pairs
_QUERY_SLACK = 1.0 + 1e-12  # scipy's own distance rounding must not drop a photon our test keeps


def build_tree(photons: PhotonMap) -> cKDTree:
    """The kd-tree over the photon positions (float64 copies of the float32 values)."""
    return cKDTree(np.asarray(photons.positions, np.float64).reshape(-1, 3))


def _inputs(
    photons: PhotonMap, points: np.ndarray, normals: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    pts = np.asarray(points, np.float64).reshape(-1, 3)
    nrm = np.asarray(normals, np.float64).reshape(-1, 3)
    if pts.shape != nrm.shape:
        raise ValueError(f"points {pts.shape} and normals {nrm.shape} differ in shape")
    valid = np.flatnonzero(np.isfinite(pts).all(axis=1) & np.isfinite(nrm).all(axis=1))
    return pts, nrm, valid


def _columns(photons: PhotonMap) -> tuple[list[np.ndarray], list[np.ndarray], list[np.ndarray]]:
    """Positions, decoded directions and power as float64 columns (fast 1-D gathers)."""
    pos = np.asarray(photons.positions, np.float64)
    dirs = photons.directions.astype(np.float64)
    power = np.asarray(photons.power, np.float64)
    return (
        [np.ascontiguousarray(pos[:, a]) for a in range(3)],
        [np.ascontiguousarray(dirs[:, a]) for a in range(3)],
        [np.ascontiguousarray(power[:, a]) for a in range(3)],
    )


def _spread_bits(v: np.ndarray) -> np.ndarray:
    """10-bit integers with two zero bits inserted after each bit (Morton code helper)."""
    v = v.astype(np.uint64) & np.uint64(0x3FF)
    for shift, mask in ((16, 0x030000FF), (8, 0x0300F00F), (4, 0x030C30C3), (2, 0x09249249)):
        v = (v | (v << np.uint64(shift))) & np.uint64(mask)
    return v


def _morton_order(pts: np.ndarray) -> np.ndarray:
    """Query points in Z order, so a chunk of them is spatially compact (tight pair bound)."""
    if len(pts) < 2:
        return np.arange(len(pts))
    lo = pts.min(axis=0)
    span = float((pts.max(axis=0) - lo).max()) or 1.0
    q = np.clip((pts - lo) / span * 1023.0, 0, 1023)
    code = (
        _spread_bits(q[:, 0])
        | (_spread_bits(q[:, 1]) << np.uint64(1))
        | (_spread_bits(q[:, 2]) << np.uint64(2))
    )
    return np.argsort(code, kind="stable")


def _chunks(tree: cKDTree, pts: np.ndarray, r: float, workers: int) -> Iterator[tuple[int, int]]:
    """Ranges of the (Z-ordered) ``pts`` whose photon lists hold about the pair budget.

    A range's pair count is estimated from a few of its points, so a huge radius or a dense spot
    makes the ranges shorter instead of exhausting memory; Z order keeps the density in a range
    close to that of its sample.
    """
    n = len(pts)
    a = 0
    while a < n:
        window = min(_MAX_CHUNK, n - a)
        probe = a + np.linspace(0, window - 1, min(_PROBES, window)).astype(np.int64)
        per_point = tree.query_ball_point(pts[probe], r, return_length=True, workers=workers)
        mean = max(float(np.mean(per_point)), 1.0)
        size = int(min(window, max(1, _PAIR_BUDGET // mean)))
        yield a, a + size
        a += size


def estimate_radius(
    photons: PhotonMap,
    points: np.ndarray,
    normals: np.ndarray,
    r: float,
    *,
    tree: cKDTree | None = None,
    workers: int = -1,
) -> np.ndarray:
    """Irradiance E (M, 3) float64 at each point from the photons that count within r.

    ``tree`` (from :func:`build_tree` on the same photons) saves rebuilding it between calls;
    ``workers`` goes to ``cKDTree.query_ball_point`` (-1: all cores).
    """
    r = check_radius(r, "r")
    pts, nrm, valid = _inputs(photons, points, normals)
    out = np.zeros((len(pts), 3))
    if len(photons) == 0 or len(valid) == 0:
        return out
    tree = build_tree(photons) if tree is None else tree
    pos, dirs, power = _columns(photons)
    rows = valid[_morton_order(pts[valid])]
    qp, qn = pts[rows], nrm[rows]
    r2 = r * r
    for a, b in _chunks(tree, qp, r * _QUERY_SLACK, workers):
        lists = tree.query_ball_point(
            qp[a:b], r * _QUERY_SLACK, workers=workers, return_sorted=False
        )
        lens = np.fromiter(map(len, lists), np.int64, count=b - a)
        flat = np.fromiter(itertools.chain.from_iterable(lists), np.int64, count=int(lens.sum()))
        pid = np.repeat(np.arange(b - a), lens)
        d2 = np.zeros(len(flat))
        facing = np.zeros(len(flat))
        for ax in range(3):
            d = pos[ax][flat] - qp[a:b, ax][pid]
            d2 += d * d
            facing += dirs[ax][flat] * qn[a:b, ax][pid]
        keep = (d2 < r2) & (facing < 0.0)
        pk, fk = pid[keep], flat[keep]
        for c in range(3):
            out[rows[a:b], c] = np.bincount(pk, weights=power[c][fk], minlength=b - a)
    out /= math.pi * r2
    return out


def estimate_knn(
    photons: PhotonMap,
    points: np.ndarray,
    normals: np.ndarray,
    r: float,
    k: int,
    *,
    tree: cKDTree | None = None,
    workers: int = -1,
) -> np.ndarray:
    """The k-nearest (max-heap) baseline, (M, 3) float64.

    Among the photons that count within r (normal test first), keep the k nearest. With at least
    k of them: ``E = sum of their power / (pi r_k^2)``, r_k the k-th nearest distance; with fewer:
    ``E = sum of all counted / (pi r^2)``. When r_k is 0 (k photons exactly at P) the second form
    is used, as an infinite density is no use to anyone.
    """
    r = check_radius(r, "r")
    if isinstance(k, bool) or int(k) != k or k < 1:
        raise ValueError(f"k must be an integer >= 1, got {k!r}")
    k = int(k)
    pts, nrm, valid = _inputs(photons, points, normals)
    out = np.zeros((len(pts), 3))
    n = len(photons)
    if n == 0 or len(valid) == 0:
        return out
    tree = build_tree(photons) if tree is None else tree
    pos, dirs, power = _columns(photons)
    r2 = r * r
    todo = valid
    want = min(4 * k, n)  # neighbours asked for; grows for rows whose first ones mostly don't count
    while len(todo):
        again = []
        step = max(1, _PAIR_BUDGET // want)
        for a in range(0, len(todo), step):
            rows = todo[a : a + step]
            dist, idx = tree.query(
                pts[rows], k=want, distance_upper_bound=r * _QUERY_SLACK, workers=workers
            )
            dist, idx = dist.reshape(len(rows), want), idx.reshape(len(rows), want)
            found = idx < n
            safe = np.where(found, idx, 0)
            d2 = np.zeros(safe.shape)
            facing = np.zeros(safe.shape)
            for ax in range(3):
                d = pos[ax][safe] - pts[rows, ax][:, None]
                d2 += d * d
                facing += dirs[ax][safe] * nrm[rows, ax][:, None]
            within = found & (d2 < r2)
            # Re-sort by our own distance so the k nearest match a brute-force sort exactly.
            d2 = np.where(within, d2, np.inf)
            srt = np.argsort(d2, axis=1, kind="stable")
            d2 = np.take_along_axis(d2, srt, axis=1)
            safe = np.take_along_axis(safe, srt, axis=1)
            counted = np.take_along_axis(within & (facing < 0.0), srt, axis=1)
            rank = np.cumsum(counted, axis=1)
            n_counted = rank[:, -1]
            # All neighbours within r are listed when the answer ran short of `want`.
            complete = (~found).any(axis=1) | (want >= n)
            use = counted & (rank <= k)
            kth = np.where(use & (rank == k), d2, 0.0).max(axis=1)
            # r_k == 0 (all k at P) takes the all-counted form, which needs the full list too.
            nearest = (n_counted >= k) & (kth > 0.0)
            redo = ~nearest & ~complete
            again.append(rows[redo])
            area = np.where(nearest, kth, r2) * math.pi
            use = np.where(nearest[:, None], use, counted)
            done = ~redo
            for c in range(3):
                e = np.where(use, power[c][safe], 0.0).sum(axis=1) / area
                out[rows[done], c] = e[done]
        todo = np.concatenate(again) if again else np.zeros(0, np.int64)
        want = min(want * 4, n)
    return out
