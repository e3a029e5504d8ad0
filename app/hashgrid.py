"""Photon-map search structures of the paper (section 3.1): the hash grid and the kd-tree baseline.

Both are built on the CPU with numpy and uploaded as flat arrays; the GPU gathers walk them.

Hash grid: the photons' bounding box is cut into cubes of edge ``cell = radius / cells_per_radius``
with ``reach`` (= ``cells_per_radius``) empty padding layers on every side. A cube's hash is
``z*X*Y + y*X + x`` (paper eq. 2); photons are sorted by hash and ``start`` (the prefix sum of the
per-cube counts) gives each cube's run of sorted slots. A query visits the (2*reach+1)^3 cubes
around its own as (2*reach+1)^2 runs of consecutive hashes along x.

Semantics shared with the GPU gather:

* ``origin`` is the photons' minimum minus ``reach + PAD_MARGIN`` cells, rounded down to a float32
  value, so ``origin.astype(float32)`` is exact and every photon lies at least ``reach`` cells
  inside: the padding layers are always empty. (The float32 rounding can add padding cells only
  when a cell is below float32 resolution at the photons' coordinates.)
* ``cell`` is ``radius / cells_per_radius`` rounded up to a float32 value (relative change below
  6e-8), so ``reach * cell >= radius`` holds in float32 too and no photon within r is missed.
* A query's neighbour coordinates are clamped to ``[0, dims-1]``. Clamping only ever repeats a
  padding row, which is empty, so nothing is counted twice.
* A query point whose own cube is outside the padded grid (or non-finite) visits nothing: every
  photon is more than ``reach`` cells, hence at least r, away from it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

MAX_CELLS = 1 << 24  # start array is uint32 of cells+1 entries on the GPU (64 MiB max)
PAD_MARGIN = 1e-3  # extra fraction of a cell below the minimum photon, against rounding
_VISIT_CHUNK = 1 << 18  # photon visits expanded at once by visit_stats (cache sized)
_COORD_LIMIT = float(1 << 62)  # cell coordinates are clipped here before the int64 cast


class GridTooLarge(ValueError):
    """The hash grid for this radius and photon spread needs more cells than the GPU limit."""

    def __init__(
        self,
        radius: float,
        extent: np.ndarray,
        dims: tuple[float, float, float],
        cells: float,
        limit: int,
    ) -> None:
        self.radius = float(radius)
        self.cells = cells
        self.limit = int(limit)
        ex = ", ".join(f"{float(e):.4g}" for e in extent)
        dm = " x ".join(f"{d:.4g}" for d in dims)
        # Cells scale as 1/r^3 for photons spread in 3D: suggest the radius that would fit then.
        hint = ""
        if math.isfinite(cells):
            hint = f" (to about {radius * (cells / limit) ** (1.0 / 3.0):.3g} or more)"
        super().__init__(
            f"hash grid too large: radius {radius:.4g} over a photon extent of ({ex}) needs "
            f"{dm} = {cells:.6g} cells, more than the limit of {limit} cells "
            f"(start array of {(limit + 1) * 4 / 2**20:.0f} MiB); raise the radius{hint} "
            f"or trace fewer photons spread over a smaller part of the scene"
        )


def _f32_down(x: np.ndarray) -> np.ndarray:
    """Largest float32 values <= x (as float64)."""
    x = np.asarray(x, np.float64)
    f = x.astype(np.float32)
    f = np.where(f.astype(np.float64) > x, np.nextafter(f, np.float32(-np.inf)), f)
    return f.astype(np.float64)


def _f32_up(x: float) -> float:
    """Smallest positive float32 value >= x."""
    f = np.float32(x)
    if float(f) < x or f <= 0:
        f = np.nextafter(f, np.float32(np.inf))
    return float(f)


def check_radius(radius: float, name: str = "radius") -> float:
    """The radius as a float, or ValueError when it is not a finite positive number."""
    try:
        r = float(radius)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a number, got {radius!r}") from None
    if not math.isfinite(r) or r <= 0.0:
        raise ValueError(f"{name} must be finite and > 0, got {radius!r}")
    return r


def _positions(positions: np.ndarray) -> np.ndarray:
    p = np.asarray(positions, np.float64).reshape(-1, 3)
    if not np.isfinite(p).all():
        # The tracer never stores non-finite photons; silently dropping them would hide a bug.
        raise ValueError("photon positions must be finite")
    return p


def _expand_runs(begin: np.ndarray, length: np.ndarray) -> np.ndarray:
    """Concatenation of ``arange(b, b + n)`` for every run, without a Python loop."""
    nz = length > 0
    b, n = begin[nz].astype(np.int64), length[nz].astype(np.int64)
    total = int(n.sum())
    if total == 0:
        return np.zeros(0, np.int64)
    # A cumulative sum of steps: +1 inside a run, a jump to the next run's begin at its first slot
    # (faster than repeat + arange for the short runs a grid query has).
    step = np.ones(total, np.int64)
    first = np.cumsum(n) - n
    step[0] = b[0]
    step[first[1:]] = b[1:] - (b[:-1] + n[:-1] - 1)
    return np.cumsum(step)


@dataclass(frozen=True, eq=False)  # arrays inside: identity equality
class HashGrid:
    """Uniform hash grid over the photons (see the module docstring for the exact semantics)."""

    radius: float  # query radius r
    cell: float  # cell edge, r / cells_per_radius rounded up to float32
    reach: int  # cells searched each side of the query's cell (1: 3x3x3, 2: 5x5x5)
    origin: np.ndarray  # (3,) float64 holding float32 values: corner of cell (0, 0, 0)
    dims: tuple[int, int, int]  # X, Y, Z including `reach` padding layers on each side
    order: np.ndarray  # (N,) int64: photon index stored at each sorted slot
    start: np.ndarray  # (X*Y*Z + 1,) uint32: cell h holds sorted slots start[h] .. start[h+1]-1
    sorted_positions: np.ndarray = field(
        repr=False, compare=False, default_factory=lambda: np.zeros((0, 3))
    )
    # (N, 3) float64 photon positions in sorted-slot order (for visit_stats)

    @staticmethod
    def build(
        positions: np.ndarray, radius: float, cells_per_radius: int = 1, max_cells: int = MAX_CELLS
    ) -> HashGrid:
        """Sort the photons into cells of edge ``radius / cells_per_radius``.

        Raises ValueError for a bad radius or non-finite positions and GridTooLarge when the grid
        would need more than ``max_cells`` cells (checked before anything big is allocated).
        """
        r = check_radius(radius)
        if (
            isinstance(cells_per_radius, bool)
            or int(cells_per_radius) != cells_per_radius
            or cells_per_radius < 1
        ):
            raise ValueError(f"cells_per_radius must be an integer >= 1, got {cells_per_radius!r}")
        reach = int(cells_per_radius)
        cell = _f32_up(r / reach)
        p = _positions(positions)
        n = len(p)
        if n >= 1 << 32:
            raise ValueError("too many photons for uint32 start indices")
        if n == 0:
            # Nothing to find: one empty cell, so the GPU arrays are never zero-sized.
            return HashGrid(
                r,
                cell,
                reach,
                np.zeros(3),
                (1, 1, 1),
                np.zeros(0, np.int64),
                np.zeros(2, np.uint32),
                np.zeros((0, 3)),
            )
        pmin, pmax = p.min(axis=0), p.max(axis=0)
        origin = _f32_down(pmin - (reach + PAD_MARGIN) * cell)
        for _ in range(4):  # only matters when a cell is near float64 resolution
            low = np.floor((pmin - origin) / cell)
            if (low >= reach).all():
                break
            origin = _f32_down(origin - np.where(low < reach, reach * cell, 0.0))
        # The floor is monotonic, so the maximum photon gives the highest occupied cell exactly.
        with np.errstate(over="ignore", invalid="ignore"):
            top = np.floor((pmax - origin) / cell)
        tx, ty, tz = (float(t) + 1.0 + reach for t in top)
        dims_f = (tx, ty, tz)
        cells_f = math.prod(dims_f)
        if not all(math.isfinite(d) and d < _COORD_LIMIT for d in dims_f) or cells_f > max_cells:
            raise GridTooLarge(r, pmax - pmin, dims_f, cells_f, max_cells)
        dims = (int(dims_f[0]), int(dims_f[1]), int(dims_f[2]))
        ncells = dims[0] * dims[1] * dims[2]

        coords = np.floor((p - origin) / cell).astype(np.int64)
        h = (coords[:, 2] * dims[1] + coords[:, 1]) * dims[0] + coords[:, 0]
        order = np.argsort(h, kind="stable").astype(np.int64)
        hs = h[order]
        start = np.empty(ncells + 1, np.uint32)
        start[0] = 0
        # Counts per cell in chunks of cells: bounded memory even for 2^24 cells.
        step = 1 << 20
        edges = np.searchsorted(hs, np.arange(0, ncells + step, step).clip(max=ncells))
        for i, c0 in enumerate(range(0, ncells, step)):
            c1 = min(c0 + step, ncells)
            a, b = int(edges[i]), int(edges[i + 1])
            cnt = np.bincount(hs[a:b] - c0, minlength=c1 - c0)
            start[c0 + 1 : c1 + 1] = a + np.cumsum(cnt)
        return HashGrid(r, cell, reach, origin, dims, order, start, np.ascontiguousarray(p[order]))

    @property
    def cell_count(self) -> int:
        return self.dims[0] * self.dims[1] * self.dims[2]

    def cell_coords(self, points: np.ndarray) -> np.ndarray:
        """(M, 3) int64 ``floor((p - origin) / cell)``, unclamped; non-finite points give -1."""
        with np.errstate(over="ignore", invalid="ignore"):
            q = np.floor((np.asarray(points, np.float64).reshape(-1, 3) - self.origin) / self.cell)
        q = np.where(np.isfinite(q), q, -1.0)
        return np.clip(q, -_COORD_LIMIT, _COORD_LIMIT).astype(np.int64)

    def hash(self, coords: np.ndarray) -> np.ndarray:
        """``z*X*Y + y*X + x`` in int64 (meaningful for coordinates inside the grid)."""
        c = np.asarray(coords, np.int64).reshape(-1, 3)
        x_, y_, _ = self.dims
        return c[:, 2] * (x_ * y_) + c[:, 1] * x_ + c[:, 0]

    def _runs(self, coords: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Sorted-slot [begin, end) of each of the (2R+1)^2 x-runs, (M, (2R+1)^2) each.

        ``coords`` must lie inside the grid; neighbour coordinates are clamped to it.
        """
        R = self.reach
        hi = np.array(self.dims, np.int64) - 1
        x0 = np.clip(coords[:, 0] - R, 0, hi[0])
        x1 = np.clip(coords[:, 0] + R, 0, hi[0])
        begin, end = [], []
        for dz in range(-R, R + 1):
            z = np.clip(coords[:, 2] + dz, 0, hi[2])
            for dy in range(-R, R + 1):
                y = np.clip(coords[:, 1] + dy, 0, hi[1])
                row = (z * self.dims[1] + y) * self.dims[0]
                begin.append(self.start[row + x0])
                end.append(self.start[row + x1 + 1])
        return (np.stack(begin, axis=1).astype(np.int64), np.stack(end, axis=1).astype(np.int64))

    def _inside(self, coords: np.ndarray) -> np.ndarray:
        return np.all((coords >= 0) & (coords < np.array(self.dims, np.int64)), axis=1)

    def candidates(self, point: np.ndarray) -> np.ndarray:
        """Sorted slots (ascending, int64) a query at ``point`` visits; empty outside the grid."""
        c = self.cell_coords(point)[:1]
        if len(c) == 0 or not self._inside(c)[0]:
            return np.zeros(0, np.int64)
        b, e = self._runs(c)
        return _expand_runs(b[0], e[0] - b[0])

    def visit_stats(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Per query point: photons visited and photons strictly within r (int64 each)."""
        pts = np.asarray(points, np.float64).reshape(-1, 3)
        m = len(pts)
        visited = np.zeros(m, np.int64)
        within = np.zeros(m, np.int64)
        c = self.cell_coords(pts)
        idx = np.flatnonzero(self._inside(c))
        if len(idx) == 0 or len(self.order) == 0:
            return visited, within
        begin, end = self._runs(c[idx])
        length = end - begin
        per_point = length.sum(axis=1)
        visited[idx] = per_point
        sp = [np.ascontiguousarray(self.sorted_positions[:, a]) for a in range(3)]
        r2 = self.radius * self.radius
        # Chunks of query points whose visits together stay under the expansion budget.
        cum = np.cumsum(per_point)
        cuts = np.searchsorted(cum, np.arange(_VISIT_CHUNK, int(cum[-1]), _VISIT_CHUNK))
        bounds = np.unique(np.concatenate([[0], cuts + 1, [len(idx)]]).clip(0, len(idx)))
        for a, b in zip(bounds[:-1], bounds[1:]):
            slots = _expand_runs(begin[a:b].ravel(), length[a:b].ravel())
            if len(slots) == 0:
                continue
            counts = per_point[a:b]
            d2 = np.zeros(len(slots))
            d = np.empty(len(slots))
            for ax in range(3):
                np.take(sp[ax], slots, out=d, mode="clip")  # "clip": unbuffered
                d -= np.repeat(pts[idx[a:b], ax], counts)
                d *= d
                d2 += d
            hit = np.concatenate([[0], np.cumsum(d2 < r2, dtype=np.int64)])
            ends = np.cumsum(counts)
            within[idx[a:b]] = hit[ends] - hit[ends - counts]
        return visited, within


def within_share(grid: HashGrid, points: np.ndarray) -> float:
    """Share of the visited photons that lie within r (NaN when nothing is visited).

    For uniformly spread photons: (4/3 pi) / 27 = 15.5% at reach 1, (4/3 pi 8) / 125 = 26.8% at 2.
    """
    visited, within = grid.visit_stats(points)
    total = int(visited.sum())
    return float(within.sum()) / total if total else float("nan")


def _left_sizes(n: np.ndarray) -> np.ndarray:
    """Left-subtree size of a left-complete (heap-shaped) binary tree of n >= 1 nodes."""
    n = np.asarray(n, np.int64)
    h = np.frexp(n.astype(np.float64))[1].astype(np.int64) - 1  # floor(log2 n)
    full = (np.int64(1) << h) - 1  # nodes on the complete levels
    half = np.where(h > 0, np.int64(1) << np.maximum(h - 1, 0), 0)  # last-level slots on the left
    return np.where(h > 0, half - 1 + np.minimum(n - full, half), 0)


@dataclass(frozen=True, eq=False)  # arrays inside: identity equality
class KdTree:
    """Left-balanced kd-tree in an array (Jensen's balanced photon map): children of i are 2i+1,
    2i+2; node i holds photon ``order[i]`` and splits on ``axis[i]``. Every photon of the left
    subtree has coordinate <= the node's on that axis, every one of the right subtree >=."""

    order: np.ndarray  # (N,) int64 photon index at node i
    axis: np.ndarray  # (N,) uint8 split axis of node i (0, 1, 2); leaves: the same rule
    positions: np.ndarray = field(
        repr=False, compare=False, default_factory=lambda: np.zeros((0, 3))
    )
    # (N, 3) float64 photon positions in photon order (for query_radius)

    @staticmethod
    def build(positions: np.ndarray) -> KdTree:
        """Level by level: every subtree of one depth is split at once (no Python per node).

        Each subtree splits on the axis of its points' largest extent at the element whose rank
        on that axis equals its left-complete left size. Ranks per axis are computed once, so a
        split is an ``argpartition`` of padded rows (one per subtree) aligned on the median.
        """
        pos = _positions(positions)
        n = len(pos)
        order = np.zeros(n, np.int64)
        axis = np.zeros(n, np.uint8)
        if n == 0:
            return KdTree(order, axis, pos)
        ar = np.arange(n, dtype=np.int64)
        by_axis = [np.argsort(pos[:, a], kind="stable") for a in range(3)]
        sorted_vals = [pos[by_axis[a], a] for a in range(3)]
        ranks = []  # rank of each live element on each axis, kept in the current layout
        for a in range(3):
            rk = np.empty(n, np.int64)
            rk[by_axis[a]] = ar
            ranks.append(rk)
        length = np.array([n], np.int64)  # live subtrees, stored contiguously in this order
        node = np.array([0], np.int64)
        while len(length):
            s = len(length)
            live = len(ranks[0])
            start = np.zeros(s, np.int64)
            np.cumsum(length[:-1], out=start[1:])
            seg = np.repeat(np.arange(s, dtype=np.int64), length)
            # Ranks are monotonic in the coordinate, so min/max rank give the extent exactly.
            ext = np.stack(
                [
                    sorted_vals[a][np.maximum.reduceat(ranks[a], start)]
                    - sorted_vals[a][np.minimum.reduceat(ranks[a], start)]
                    for a in range(3)
                ],
                axis=1,
            )
            ax = np.argmax(ext, axis=1)
            ax_el = ax[seg]
            key = np.where(ax_el == 0, ranks[0], np.where(ax_el == 1, ranks[1], ranks[2]))
            left = _left_sizes(length)
            right = length - left - 1
            lmax = int(left.max())
            width = lmax + 1 + int(right.max())
            # Row per subtree; -1 pads on the left and n pads on the right put every median
            # at column lmax, so one argpartition splits all subtrees of this depth.
            flat = seg * width + (lmax - left)[seg] + ar[:live] - start[seg]
            rows = np.full((s, width), n, np.int64)
            rows[np.arange(width)[None, :] < (lmax - left)[:, None]] = -1
            rows.ravel()[flat] = key
            part = np.argpartition(rows, lmax, axis=1)
            slot_to_live = np.full(s * width, -1, np.int64)
            slot_to_live[flat] = ar[:live]
            part += (np.arange(s, dtype=np.int64) * width)[:, None]
            src = slot_to_live[part]
            med = src[:, lmax]
            order[node] = by_axis[0][ranks[0][med]]
            axis[node] = ax
            lp = src[:, :lmax].ravel()
            rp = src[:, lmax + 1 :].ravel()
            nxt = np.concatenate([lp[lp >= 0], rp[rp >= 0]])
            ranks = [rk[nxt] for rk in ranks]
            length = np.concatenate([left, right])
            node = np.concatenate([2 * node + 1, 2 * node + 2])
            keep = length > 0
            length, node = length[keep], node[keep]
        return KdTree(order, axis, pos)

    def query_radius(self, point: np.ndarray, r: float) -> np.ndarray:
        """Photon indices (ascending) strictly within r of ``point``, by walking the array tree
        as the GPU does: visit the near child, and the far one when the split plane is < r."""
        r = check_radius(r, "r")
        p = np.asarray(point, np.float64).reshape(3)
        n = len(self.order)
        if n == 0 or not np.isfinite(p).all():
            return np.zeros(0, np.int64)
        r2 = r * r
        found: list[int] = []
        stack = [0]
        while stack:
            i = stack.pop()
            ph = int(self.order[i])
            q = self.positions[ph]
            d = p - q
            if d[0] * d[0] + d[1] * d[1] + d[2] * d[2] < r2:
                found.append(ph)
            a = int(self.axis[i])
            diff = float(d[a])
            near, far = (2 * i + 1, 2 * i + 2) if diff <= 0 else (2 * i + 2, 2 * i + 1)
            if far < n and diff * diff < r2:
                stack.append(far)
            if near < n:
                stack.append(near)
        return np.array(sorted(found), np.int64)
