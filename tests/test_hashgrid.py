"""Hash grid (paper 3.1) and kd-tree baseline: structure against brute force, search coverage."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from app.hashgrid import MAX_CELLS, GridTooLarge, HashGrid, KdTree, _left_sizes, within_share


def brute_coords(grid: HashGrid, p: np.ndarray) -> np.ndarray:
    return np.floor((np.asarray(p, np.float64) - grid.origin) / grid.cell).astype(np.int64)


def check_structure(grid: HashGrid, positions: np.ndarray) -> None:
    """Order, prefix sum, hash and padding against an independent brute-force binning."""
    p = np.asarray(positions, np.float64).reshape(-1, 3)
    n = len(p)
    X, Y, Z = grid.dims
    assert grid.start.dtype == np.uint32 and grid.start.shape == (X * Y * Z + 1,)
    assert grid.order.dtype == np.int64
    assert np.array_equal(np.sort(grid.order), np.arange(n))
    assert grid.start[0] == 0 and int(grid.start[-1]) == n
    assert (np.diff(grid.start.astype(np.int64)) >= 0).all()
    # origin is exactly a float32 value, as the GPU receives it
    assert np.array_equal(grid.origin.astype(np.float32).astype(np.float64), grid.origin)
    assert grid.cell >= grid.radius / grid.reach and grid.cell == float(np.float32(grid.cell))
    if n == 0:
        return
    c = brute_coords(grid, p)
    # every photon at least `reach` cells inside: the padding layers are empty
    assert (c >= grid.reach).all() and (c <= np.array(grid.dims) - 1 - grid.reach).all()
    assert (grid.origin <= p.min(axis=0) - grid.reach * grid.cell).all()
    h = c[:, 2] * X * Y + c[:, 1] * X + c[:, 0]
    assert np.array_equal(grid.hash(c), h)
    assert np.array_equal(grid.cell_coords(p), c)
    assert np.array_equal(np.diff(grid.start.astype(np.int64)), np.bincount(h, minlength=X * Y * Z))
    assert (np.diff(h[grid.order]) >= 0).all()
    for slot in range(0, n, max(1, n // 50)):  # the cell of a slot holds that photon
        cell = h[grid.order[slot]]
        assert grid.start[cell] <= slot < grid.start[cell + 1]


def brute_within(p: np.ndarray, q: np.ndarray, r: float) -> np.ndarray:
    d = np.asarray(p, np.float64) - np.asarray(q, np.float64)
    return np.flatnonzero(d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1] + d[:, 2] * d[:, 2] < r * r)


def check_queries(grid: HashGrid, positions: np.ndarray, queries: np.ndarray) -> None:
    """candidates() is the photons of the (2R+1)^3 cells (clamped) and holds all within r."""
    p = np.asarray(positions, np.float64).reshape(-1, 3)
    c = brute_coords(grid, p)
    visited, within = grid.visit_stats(queries)
    for i, q in enumerate(np.asarray(queries, np.float64)):
        slots = grid.candidates(q)
        got = grid.order[slots]
        assert len(np.unique(slots)) == len(slots) == visited[i]
        assert (np.diff(slots) > 0).all()
        near = brute_within(p, q, grid.radius)
        assert set(near.tolist()) <= set(got.tolist())
        assert within[i] == len(near)
        qc = brute_coords(grid, q[None])[0]
        if ((qc >= 0) & (qc < np.array(grid.dims))).all():
            expect = np.flatnonzero((np.abs(c - qc) <= grid.reach).all(axis=1))
            assert np.array_equal(np.sort(got), expect)
        else:
            assert len(slots) == 0 and len(near) == 0


@pytest.mark.parametrize("cpr", [1, 2])
@pytest.mark.parametrize(
    "offset,scale,r",
    [
        (0.0, 5.0, 0.3),
        (-40.0, 10.0, 0.7),  # negative coordinates
        (1e6, 100.0, 1.0),  # large coordinates
        (-1e6, 1000.0, 37.0),
        (1e6, 5000.0, 1000.0),
        (0.25, 1e-8, 1e-9),  # tiny radius, few photons close together
    ],
)
def test_structure_and_queries_vs_brute_force(cpr, offset, scale, r) -> None:
    rng = np.random.default_rng(7)
    n = 400 if r >= 0.3 else 12
    pos = (offset + rng.random((n, 3)) * scale).astype(np.float32)
    grid = HashGrid.build(pos, r, cpr)
    assert grid.reach == cpr and grid.radius == r
    check_structure(grid, pos)
    near = pos[rng.integers(0, n, 40)] + rng.normal(0.0, r, (40, 3))
    far = offset + (rng.random((10, 3)) * 3 - 1) * scale  # partly outside the padded grid
    check_queries(grid, pos, np.concatenate([near, far, pos[:5]]))


def test_wide_span_both_signs() -> None:
    rng = np.random.default_rng(3)
    pos = (rng.random((2000, 3)) * 2e6 - 1e6).astype(np.float32)
    grid = HashGrid.build(pos, 1e5)
    check_structure(grid, pos)
    check_queries(grid, pos, pos[:20] + rng.normal(0, 5e4, (20, 3)))


def test_huge_radius_single_cell() -> None:
    rng = np.random.default_rng(4)
    pos = rng.random((100, 3)).astype(np.float32)
    grid = HashGrid.build(pos, 1e6)
    assert grid.dims == (3, 3, 3)
    check_structure(grid, pos)
    assert len(grid.candidates(np.array([0.5, 0.5, 0.5]))) == 100
    check_queries(grid, pos, np.array([[0.5, 0.5, 0.5], [1e5, -1e5, 0.0], [5e6, 0, 0]]))


def test_empty_and_single_photon() -> None:
    empty = HashGrid.build(np.zeros((0, 3), np.float32), 0.1)
    assert min(empty.dims) >= 1 and not empty.start.any() and len(empty.order) == 0
    assert len(empty.candidates(np.zeros(3))) == 0
    v, w = empty.visit_stats(np.random.default_rng(0).random((10, 3)))
    assert not v.any() and not w.any()
    assert math.isnan(within_share(empty, np.zeros((3, 3))))

    one = np.array([[1.5, -2.0, 3.0]], np.float32)
    for cpr in (1, 2):
        grid = HashGrid.build(one, 0.5, cpr)
        assert grid.dims == (2 * cpr + 1,) * 3
        check_structure(grid, one)
        check_queries(
            grid,
            one,
            np.array(
                [[1.5, -2.0, 3.0], [1.9, -2.0, 3.0], [2.2, -2, 3], [1.5, -2.49, 3.0], [10.0, 0, 0]]
            ),
        )


def test_outside_and_nan_points_visit_nothing() -> None:
    pos = np.random.default_rng(1).random((50, 3)).astype(np.float32)
    grid = HashGrid.build(pos, 0.2)
    pts = np.array([[np.nan, 0.5, 0.5], [np.inf, 0, 0], [-5.0, 0.5, 0.5], [0.5, 0.5, 1e30]])
    v, w = grid.visit_stats(pts)
    assert not v.any() and not w.any()
    for q in pts:
        assert len(grid.candidates(q)) == 0
    assert (grid.cell_coords(pts[:2]) == -1).any(axis=1).all()


@pytest.mark.parametrize("bad", [0.0, -1.0, float("nan"), float("inf"), "x", None])
def test_bad_radius(bad) -> None:
    with pytest.raises(ValueError, match="radius"):
        HashGrid.build(np.zeros((3, 3), np.float32), bad)


def test_bad_inputs() -> None:
    with pytest.raises(ValueError, match="finite"):
        HashGrid.build(np.array([[0.0, np.nan, 0.0]]), 1.0)
    for cpr in (0, 1.5, True):
        with pytest.raises(ValueError, match="cells_per_radius"):
            HashGrid.build(np.zeros((3, 3)), 1.0, cpr)


def test_grid_too_large_message() -> None:
    pos = np.array([[0.0, 0.0, 0.0], [50.0, 40.0, 30.0]], np.float32)
    with pytest.raises(GridTooLarge) as info:
        HashGrid.build(pos, 1e-3)
    msg = str(info.value)
    assert info.value.cells > MAX_CELLS
    assert f"{info.value.cells:.6g} cells" in msg and str(MAX_CELLS) in msg
    assert "radius 0.001" in msg and "raise the radius" in msg and "fewer photons" in msg
    assert isinstance(info.value, ValueError)
    # overflowing dims are caught too, before any allocation
    with pytest.raises(GridTooLarge, match="cells"):
        HashGrid.build(np.array([[0, 0, 0], [1e30, 1, 1]], np.float32), 1e-30)
    # the limit is a parameter; exactly at the limit still builds
    grid = HashGrid.build(pos, 10.0)
    HashGrid.build(pos, 10.0, max_cells=grid.cell_count)
    with pytest.raises(GridTooLarge):
        HashGrid.build(pos, 10.0, max_cells=grid.cell_count - 1)


@pytest.mark.parametrize("cpr,theory", [(1, 4 / 3 * math.pi / 27), (2, 4 / 3 * math.pi * 8 / 125)])
def test_within_share_matches_theory(cpr, theory) -> None:
    rng = np.random.default_rng(11)
    side = 30.0
    pos = (rng.random((150_000, 3)) * side).astype(np.float32)
    grid = HashGrid.build(pos, 1.0, cpr)
    pts = 2.0 + rng.random((20_000, 3)) * (side - 4.0)  # away from the border
    share = within_share(grid, pts)
    assert abs(share - theory) < 0.01 * theory, (share, theory)


coord = st.floats(-50.0, 50.0, allow_nan=False, width=32)


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    pts=st.lists(st.tuples(coord, coord, coord), min_size=0, max_size=25),
    qs=st.lists(st.tuples(coord, coord, coord), min_size=1, max_size=6),
    base=st.sampled_from([0.0, -1e6, 1e6, 123.25]),
    unit=st.sampled_from([1e-3, 0.1, 1.0, 20.0]),
    r=st.sampled_from([1.0, 3.0, 7.5, 100.0]),
    cpr=st.sampled_from([1, 2]),
)
def test_property_candidates_hold_all_within_r(pts, qs, base, unit, r, cpr) -> None:
    pos = (base + np.array(pts, np.float64).reshape(-1, 3) * unit).astype(np.float32)
    r *= unit
    try:
        grid = HashGrid.build(pos, r, cpr)
    except GridTooLarge as exc:
        # float32 rounding far from the origin can widen the extent past the cell limit: that
        # is the documented refusal, as long as the grid really would be too large.
        assert exc.cells > MAX_CELLS, exc
        return
    check_structure(grid, pos)
    # queries near the photons (and at them), in the photons' units
    q = base + np.array(qs, np.float64).reshape(-1, 3) * unit
    if len(pos):
        q = np.concatenate(
            [q, pos[:3].astype(np.float64), pos[:3] + np.array(qs[:1]) * unit * 0.01]
        )
    check_queries(grid, pos, q)


# ---------------------------------------------------------------- kd-tree


def subtree_bounds(pos: np.ndarray, tree: KdTree) -> tuple[np.ndarray, np.ndarray]:
    lo = pos[tree.order].astype(np.float64)
    hi = lo.copy()
    n = len(lo)
    for i in range(n - 1, -1, -1):
        for c in (2 * i + 1, 2 * i + 2):
            if c < n:
                lo[i] = np.minimum(lo[i], lo[c])
                hi[i] = np.maximum(hi[i], hi[c])
    return lo, hi


def check_kd(pos: np.ndarray, tree: KdTree) -> None:
    n = len(pos)
    assert tree.order.dtype == np.int64 and tree.axis.dtype == np.uint8
    assert np.array_equal(np.sort(tree.order), np.arange(n))
    assert tree.axis.shape == (n,) and (tree.axis <= 2).all()
    lo, hi = subtree_bounds(pos, tree)
    for i in range(n):
        a = int(tree.axis[i])
        v = float(pos[tree.order[i], a])
        if 2 * i + 1 < n:
            assert hi[2 * i + 1, a] <= v
        if 2 * i + 2 < n:
            assert lo[2 * i + 2, a] >= v
    if n > 1:  # the root splits on the axis of the largest extent
        ext = pos.max(axis=0).astype(np.float64) - pos.min(axis=0)
        assert ext[tree.axis[0]] == ext.max()


def test_left_sizes() -> None:
    for n in range(1, 200):
        # heap-shaped tree of n nodes: count the nodes under index 1
        size, level = 0, [1]
        while level:
            size += sum(1 for i in level if i < n)
            level = [c for i in level if i < n for c in (2 * i + 1, 2 * i + 2)]
        assert _left_sizes(np.array([n]))[0] == size, n


@pytest.mark.parametrize("n", [0, 1, 2, 3, 4, 5, 7, 8, 9, 31, 33, 100, 1000])
def test_kd_invariants(n) -> None:
    rng = np.random.default_rng(n)
    pos = (rng.random((n, 3)) * np.array([4.0, 1.0, 2.0]) - 1.0).astype(np.float32)
    tree = KdTree.build(pos)
    check_kd(pos, tree)


def test_kd_duplicates_and_flat() -> None:
    rng = np.random.default_rng(5)
    dup = rng.integers(0, 3, (300, 3)).astype(np.float32)
    check_kd(dup, KdTree.build(dup))
    flat = np.zeros((64, 3), np.float32)
    flat[:, 0] = rng.random(64)
    tree = KdTree.build(flat)
    check_kd(flat, tree)
    assert tree.axis[0] == 0


def test_kd_query_vs_brute_force() -> None:
    rng = np.random.default_rng(9)
    pos = (rng.random((3000, 3)) * 10 - 5).astype(np.float32)
    tree = KdTree.build(pos)
    for r in (0.05, 0.5, 2.0, 100.0):
        for q in list(rng.random((15, 3)) * 12 - 6) + [pos[0].astype(np.float64)]:
            assert np.array_equal(tree.query_radius(q, r), brute_within(pos, q, r))
    assert len(KdTree.build(np.zeros((0, 3))).query_radius(np.zeros(3), 1.0)) == 0
    assert len(tree.query_radius(np.array([np.nan, 0, 0]), 1.0)) == 0
    with pytest.raises(ValueError):
        tree.query_radius(np.zeros(3), 0.0)


def test_kd_large_coordinates() -> None:
    rng = np.random.default_rng(2)
    pos = (1e6 + rng.random((500, 3)) * 100).astype(np.float32)
    tree = KdTree.build(pos)
    check_kd(pos, tree)
    q = pos[3].astype(np.float64) + 0.5
    assert np.array_equal(tree.query_radius(q, 5.0), brute_within(pos, q, 5.0))
