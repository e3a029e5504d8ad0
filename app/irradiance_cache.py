"""A world-space irradiance cache from a photon map: one texture lookup instead of a gather.

Christensen 1999 (faster photon map global illumination) precomputes irradiance at a set of
points once per photon map, so that rendering looks it up instead of gathering photons per
pixel. Here the points sit on a regular grid of cells of edge ``radius / 2`` (15 cm at the
default 30 cm radius, so a cell is always smaller than the blur the gather itself makes): every
cell that holds photons gets one cache point, the mean position of its photons (on the surface
they landed on), and at that point the irradiance for six normal directions (+X, -X, +Y, -Y,
+Z, -Z: an "ambient cube") with the same estimate as the gather (``app.lab.photon_ref``):

    E(P, N) = sum(power of the photons within r that arrived against N) / (pi r^2)

A pixel with normal N looks up the three directions on N's side, weighted by N's squared
components, each interpolated trilinearly between the neighbouring cells
(``render/shaders/irradiance_cache.comp.glsl``). The interpolation is normalised by the
cells' weights, so empty air next to a surface does not darken it.

Where light is sparse (a hallway lit only by bounces, the far side of a large house), a cell
where no direction counts ``MIN_PHOTONS`` photons within r gathers again within 2r (only
there: a direction no surface faces counts none anywhere, and regathering every cell for it
took the showroom-gi's cache from 0.4 to 2.1 s), and a direction or cell that no photon
reached takes its known neighbours' mean ``FILL_CELLS`` cells out (at weight ``FILL_WEIGHT``;
beyond, weight 0). Without these, the daylit staircase's dim wall showed 15 cm cells of black
(no photon in any of the cells around the pixel) and hard-edged islands of light; with them
its FLIP against Cycles went 0.313 -> 0.299 (docs/reference_flip.md, "Stop 36"). A 4r sphere
as well smoothed more and scored worse there (0.338): it mixes the light of surfaces a metre
apart.

The cache is built with scipy's cKDTree on the CPU (a second or two for 64k photons), on the
photon service's worker thread right after a trace (``app.indirect``), and kept on the
``PhotonMap`` per radius (``cache_for``) so the renderer only uploads it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from app.ambient_field import fill_empty
from app.hashgrid import check_radius
from app.photon_map import PhotonMap

BUCKETS = 6  # +X, -X, +Y, -Y, +Z, -Z
MAX_CELLS = 1 << 19  # cells in the dense grid at most (the cell grows beyond): 6 x 8 MB
# GL 4.5 promises 3D textures of 2048 texels a side: the six grids stack (with an empty slice
# between them) along the axis with the fewest cells (a storey's height, not a 60 m hall's
# length, which overflowed the texture and lost the light), and the cell grows until they fit.
MAX_TEXELS = 2048
MIN_PHOTONS = 32  # a cell where no direction counts this many gathers again over 2r
GROW = (2.0,)  # the wider sphere's radius, in gather radii
FILL_CELLS = 2  # empty cells this many cells from known ones take their mean...
FILL_WEIGHT = 0.5  # ... at this weight in the interpolation (known cells weigh 1)
_CHUNK = 4096  # cache points per cKDTree query (bounds the pair lists' memory)


@dataclass
class IrradianceCache:
    """Irradiance per cell and normal direction on a dense grid.

    ``values`` is (6, Z, Y, X, 4) float32: rgb = E * a (linear, the photon map's units), a = 1
    where photons of the cell counted for that direction, ``FILL_WEIGHT`` where the cell took
    its known neighbours' mean, 0 where nothing is known; the cell (i, j, k) spans
    ``origin + cell * [i, j, k]`` to ``origin + cell * [i + 1, j + 1, k + 1]``.
    """

    origin: np.ndarray  # (3,) float32, corner of cell (0, 0, 0)
    cell: float
    dims: tuple[int, int, int]  # cells along x, y, z
    values: np.ndarray
    radius: float
    points: int  # cache points (cells with photons)
    build_ms: float = 0.0

    @property
    def nbytes(self) -> int:
        return int(self.values.nbytes)

    @property
    def stack_axis(self) -> int:
        """The axis (0 x, 1 y, 2 z) the GPU texture stacks the six grids along."""
        return stack_axis(self.dims)

    def lookup(self, points: np.ndarray, normals: np.ndarray) -> np.ndarray:
        """E (M, 3) at world points with unit normals, as the shader interpolates it (a CPU
        twin of ``irradiance_cache.comp.glsl``, for tests and tools)."""
        pts = np.asarray(points, np.float64).reshape(-1, 3)
        nrm = np.asarray(normals, np.float64).reshape(-1, 3)
        out = np.zeros((len(pts), 3))
        if self.points == 0 or len(pts) == 0:
            return out
        dims = np.array(self.dims)
        g = (pts - self.origin) / self.cell - 0.5  # texel-centre coordinates
        g = np.clip(g, 0.0, dims - 1.0)
        base = np.minimum(np.floor(g).astype(np.int64), np.maximum(dims - 2, 0))
        f = g - base
        n2 = nrm * nrm
        for axis in range(3):
            bucket = np.where(nrm[:, axis] >= 0.0, 2 * axis, 2 * axis + 1)
            acc = np.zeros((len(pts), 4))
            for corner in range(8):
                o = np.array([(corner >> a) & 1 for a in range(3)])
                idx = np.minimum(base + o, dims - 1)
                w = np.prod(np.where(o == 1, f, 1.0 - f), axis=1)
                acc += w[:, None] * self.values[bucket, idx[:, 2], idx[:, 1], idx[:, 0]]
            safe = np.where(acc[:, 3] > 1e-6, acc[:, 3], 1.0)
            e = np.where(acc[:, 3:4] > 1e-6, acc[:, :3] / safe[:, None], 0.0)
            out += n2[:, axis : axis + 1] * e
        return out


def stack_axis(dims) -> int:
    """The axis with the fewest cells (the first of equals)."""
    return int(np.argmin(np.asarray(dims)))


def fits_texture(dims) -> bool:
    """Whether a grid of ``dims`` cells, its six directions stacked along ``stack_axis``,
    fits a 3D texture of ``MAX_TEXELS`` a side."""
    d = np.asarray(dims, np.int64)
    return int(d.max()) <= MAX_TEXELS and BUCKETS * (int(d.min()) + 1) <= MAX_TEXELS


def empty_cache(radius: float) -> IrradianceCache:
    return IrradianceCache(
        np.zeros(3, np.float32),
        1.0,
        (1, 1, 1),
        np.zeros((BUCKETS, 1, 1, 1, 4), np.float32),
        radius,
        0,
    )


def build_cache(photons: PhotonMap, radius: float, cell: float | None = None) -> IrradianceCache:
    """The cache of ``photons`` for gather radius ``radius`` (cells of ``cell``, default r/2)."""
    import time

    from scipy.spatial import cKDTree

    start = time.perf_counter()
    r = check_radius(radius)
    pos = np.asarray(photons.positions, np.float64)
    finite = np.isfinite(pos).all(axis=1) & np.isfinite(photons.power).all(axis=1)
    if len(photons) == 0 or not finite.any():
        return empty_cache(r)
    pos = pos[finite]
    power = np.asarray(photons.power, np.float64)[finite]
    dirs = photons.directions.astype(np.float64)[finite]
    lo, hi = pos.min(axis=0), pos.max(axis=0)
    c = float(cell) if cell is not None else r / 2.0
    if not (math.isfinite(c) and c > 0.0):
        raise ValueError(f"cache cell must be a positive length, not {cell!r}")
    while True:  # a dense grid: grow the cell until it fits
        dims = np.maximum(np.ceil((hi - lo) / c + 1e-6).astype(np.int64), 1)
        if int(np.prod(dims)) <= MAX_CELLS and fits_texture(dims):
            break
        c *= 1.25
    origin = lo - 0.5 * (dims * c - (hi - lo))  # centre the photons in the grid
    ijk = np.clip(((pos - origin) / c).astype(np.int64), 0, dims - 1)
    flat = (ijk[:, 2] * dims[1] + ijk[:, 1]) * dims[0] + ijk[:, 0]
    occupied, inverse, counts = np.unique(flat, return_inverse=True, return_counts=True)
    centre = np.stack([np.bincount(inverse, weights=pos[:, a]) / counts for a in range(3)], axis=1)
    photon = _Photons(cKDTree(pos), pos, power, dirs)
    e, n = photon.gather(centre, r)
    for grow in GROW:  # where light is sparse (no direction counted many), a wider sphere
        few = np.flatnonzero(n.max(axis=1) < MIN_PHOTONS)
        if len(few) == 0:
            break
        e2, n2 = photon.gather(centre[few], r * grow)
        better = n2 > n[few]
        rows, buckets = np.nonzero(better)
        e[few[rows], buckets] = e2[rows, buckets]
        n[few[rows], buckets] = n2[rows, buckets]
    # A direction no photon of the cell counted for (a way no surface there faces) and an
    # empty cell are unknown, not dark: the cells FILL_CELLS out
    # from the known ones take their mean at weight FILL_WEIGHT, the rest weigh 0.
    grid = np.full((BUCKETS, int(np.prod(dims)), 3), np.nan, np.float32)
    known = (n > 0).T  # (6, occupied)
    grid[:, occupied] = np.where(known[..., None], e.transpose(1, 0, 2), np.nan)
    grid = grid.reshape(BUCKETS, int(dims[2]), int(dims[1]), int(dims[0]), 3)
    was_known = np.isfinite(grid[..., 0])
    grid = fill_empty(grid, FILL_CELLS)
    weight = np.where(was_known, 1.0, np.where(np.isfinite(grid[..., 0]), FILL_WEIGHT, 0.0))
    values = np.zeros(grid.shape[:4] + (4,), np.float32)
    values[..., :3] = np.nan_to_num(grid, nan=0.0) * weight[..., None]
    values[..., 3] = weight
    return IrradianceCache(
        origin.astype(np.float32),
        c,
        (int(dims[0]), int(dims[1]), int(dims[2])),
        values,
        r,
        len(occupied),
        (time.perf_counter() - start) * 1e3,
    )


def _class_directions() -> np.ndarray:
    """(27, 6): 1 where a direction class (``_Photons.cls``) counts for a direction: +axis
    for photons travelling against it, -axis for those travelling along it."""
    ways = np.array([[c % 3, c // 3 % 3, c // 9] for c in range(27)])
    out = np.zeros((27, BUCKETS))
    for axis in range(3):
        out[ways[:, axis] == 0, 2 * axis] = 1.0
        out[ways[:, axis] == 2, 2 * axis + 1] = 1.0
    return out


_CLASS_DIRECTIONS = _class_directions()


@dataclass
class _Photons:
    """The photons a cache is built from, in a kd-tree."""

    tree: Any  # scipy.spatial.cKDTree over pos (scipy is loaded when a cache is built)
    pos: np.ndarray  # (N, 3)
    power: np.ndarray  # (N, 3)
    dirs: np.ndarray  # (N, 3) travel directions
    cls: np.ndarray = field(init=False)  # (N,) the class of each photon's direction

    def __post_init__(self) -> None:
        # Each photon's way along each axis (0: against it, 1: along none, 2: along it) as one
        # of 27 classes, so a cell's sums for the six directions come from one bincount per
        # channel (``_CLASS_DIRECTIONS``).
        way = (np.sign(self.dirs) + 1).astype(np.int64)
        self.cls = way[:, 0] + 3 * way[:, 1] + 9 * way[:, 2]

    def gather(self, centre: np.ndarray, r: float) -> tuple[np.ndarray, np.ndarray]:
        """E (M, 6, 3) at the points ``centre`` for the six directions over a sphere of
        radius ``r``, and the photons counted for each (M, 6)."""
        m = len(centre)
        e = np.zeros((m, BUCKETS, 3))
        n = np.zeros((m, BUCKETS), np.int64)
        r2 = r * r
        for a in range(0, m, _CHUNK):
            b = min(m, a + _CHUNK)
            # Within r (the tree's test; checking the distances again cost half the build).
            lists = self.tree.query_ball_point(centre[a:b], r, return_sorted=False)
            lens = np.fromiter(map(len, lists), np.int64, count=b - a)
            if lens.sum() == 0:
                continue
            pid = np.repeat(np.arange(b - a), lens)
            ph = np.concatenate([np.asarray(x, np.int64) for x in lists if len(x)])
            idx = pid * 27 + self.cls[ph]
            size = (b - a) * 27
            count = np.bincount(idx, minlength=size).reshape(b - a, 27)
            n[a:b] = np.rint(count @ _CLASS_DIRECTIONS).astype(np.int64)
            for ch in range(3):
                power = np.bincount(idx, weights=self.power[ph, ch], minlength=size)
                e[a:b, :, ch] = power.reshape(b - a, 27) @ _CLASS_DIRECTIONS
        return e / (math.pi * r2), n


def cache_for(photons: PhotonMap, radius: float) -> IrradianceCache:
    """The cache of ``photons`` at ``radius``, built once and kept on the map (a worker thread
    builds it after tracing; the renderer then finds it ready)."""
    key = ("irradiance_cache", float(radius))
    cache = photons.derived.get(key)
    if cache is None:
        cache = build_cache(photons, radius)
        photons.derived[key] = cache
    return cache
