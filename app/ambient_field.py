"""The even light by place: the ambient estimate's bounce light kept where it was found.

Setting ``render.ambient_by_place``. The estimate (``app.ambient``) solves the light bounced
round the room on a few thousand surface points and then averages it into one level (turned
by the way a surface faces). One level, however right its mean, lights a far corner as much
as the wall beside a sunlit window: against Cycles the daylit showroom got worse when the
level was raised to the right mean (docs/reference_flip.md). This keeps each point's own
value instead, on a coarse grid the shaders look up (an irradiance volume, as games bake them):

- every face of a probe point (its position, the way it faces, its bounce light
  ``E_ind / pi``) is spread over the cells around it with a tent ``SPREAD`` cells wide, into
  six grids by the way it faces (+X, -X, +Y, -Y, +Z, -Z, by the squared components of its
  normal, as the photon map's irradiance cache keeps arrival directions);
- a cell stores the mean it received, as sure as the weight it received against
  ``FULL_WEIGHT`` (at most 1) and the one level for the rest: ``mean x sure + (1 - sure) x
  level`` (the level of a surface facing that grid's way): where no face was found nearby
  (an open space, a grid's edge) the level stands in, so nothing is darker than before for
  want of points;
- a pixel of normal N reads the three grids on N's side trilinearly, weighted by N's squared
  components (two fetches: the six grids packed in two RGBA slabs);
- the colour: one per cell for every way of facing (luminance 1; the faces' bounce colours,
  ``AmbientProbe._chroma``, weighted by the light they bring), red and blue in the second
  slab's spare channels, green from the luminance: a wooden floor warms the ceiling.

Faces that see nothing (a wall's outer side), faces covered by something lying on them
(most of their rays end within ``COVERED_M``: the floor under a rug, which no one sees and
which receives nothing) and faces deep in creases (``app.ambient.FIELD_CREASE_MAX``) are
left out. The cell is ``SPACINGS`` times the points' median
nearest-neighbour distance (within ``CELL_M``: 0.39 m on the showroom), so each cell averages a
few dozen faces' 16 rays (with 128 rays a face the field moved by a few %: what it shows is the
light, not noise); 80-110 kB on the GPU. Built with the estimate, each time the lights or
the sun change. Where each face falls on the grid (:class:`FieldLayout`) is worked out once
per probe: a new estimate only weighs the faces' light into it (the daylit showroom's
estimate 82 -> 65 ms, the bathroom's 47 -> 29 ms, the same field to the bit).
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np

BUCKETS = 6  # +X, -X, +Y, -Y, +Z, -Z
SPREAD = 2.0  # a face's tent reaches this many cells each way
# A cell that received this much weight (one face's whole tent) is taken as it is. At 8 the
# one level stood in for a share of most cells near a room's visible surfaces and pulled them
# to the room's mean: 0.75 of a path trace at the living room's visible surfaces, 0.83 at 1.
FULL_WEIGHT = 1.0
SPACINGS = 4.0  # the cell, in median nearest-neighbour distances of the points
CELL_M = (0.1, 2.0)  # the cell's edge, metres, at least and at most
MAX_CELLS = 1 << 17  # per direction grid (the cell grows beyond): 6 x 1 MB at most
MAX_DIM = 1024  # cells along any axis: two slabs stacked along z fit GL's 2048 texels a side
COVERED_M = 0.05  # a ray that ends this close met something lying on the face
COVERED_SHARE = 0.5  # a face is covered when this share of its rays end that close
LUMA = np.array([0.2126, 0.7152, 0.0722])


@dataclass(frozen=True)
class AmbientField:
    """The bounce light by place and facing, on a grid.

    ``values`` is (6, Z, Y, X) float32: per direction grid and cell ``mean x sure + (1 - sure)
    x level`` (the level of a surface facing that way where the cell is unsure); cell (i, j, k)
    spans ``origin + cell * [i, j, k]`` to ``origin + cell * [i + 1, j + 1, k + 1]``.
    """

    origin: np.ndarray  # (3,) float64
    cell: float
    dims: tuple[int, int, int]  # cells along x, y, z
    values: np.ndarray
    faces: int  # faces spread into it
    # (Z, Y, X, 3) the bounce light's colour per cell, its luminance 1 (grey where none was
    # found): one for every way of facing (a wooden floor warms the ceiling above it).
    chroma: np.ndarray

    def _corners(self, points: np.ndarray) -> Iterator[tuple[tuple[np.ndarray, ...], np.ndarray]]:
        """For each of the 8 cells around each point (trilinear between cell centres, clamped
        at the grid's edge, as the GPU filters): their (z, y, x) indices and weights."""
        dims = np.array(self.dims)
        g = np.clip((points - self.origin) / self.cell, 0.5, dims - 0.5) - 0.5
        base = np.minimum(np.floor(g).astype(np.int64), np.maximum(dims - 2, 0))
        f = g - base
        for corner in range(8):
            o = np.array([(corner >> a) & 1 for a in range(3)])
            idx = np.minimum(base + o, dims - 1)
            yield (idx[:, 2], idx[:, 1], idx[:, 0]), np.prod(np.where(o == 1, f, 1.0 - f), axis=1)

    def lookup(self, points: np.ndarray, normals: np.ndarray) -> np.ndarray:
        """The even light (luminance) at world ``points`` of unit ``normals``: a CPU twin of
        shading.glsl ``even_light`` (the three grids on the normal's side by its squared
        components)."""
        pts = np.asarray(points, np.float64).reshape(-1, 3)
        nrm = np.asarray(normals, np.float64).reshape(-1, 3)
        out = np.zeros(len(pts))
        for at, w in self._corners(pts):
            for axis in range(3):
                bucket = np.where(nrm[:, axis] >= 0.0, 2 * axis, 2 * axis + 1)
                out += w * nrm[:, axis] ** 2 * self.values[(bucket,) + at]
        return out

    def colour_at(self, points: np.ndarray) -> np.ndarray:
        """The bounce light's colour (M, 3) at world ``points`` (luminance 1), as the shader
        interpolates it (red and blue stored, green from the luminance)."""
        pts = np.asarray(points, np.float64).reshape(-1, 3)
        rb = np.zeros((len(pts), 2))
        for at, w in self._corners(pts):
            rb += w[:, None] * self.chroma[at][:, [0, 2]]
        return _with_green(rb[:, 0], rb[:, 1])

    def packed(self) -> np.ndarray:
        """The grids as the shader reads them, (2 Z, Y, X, 4) float16: slab 0 holds
        (+X, -X, +Y, -Y), slab 1 (+Z, -Z, red, blue of the colour): two fetches a pixel."""
        v, c = self.values, self.chroma
        first = np.stack([v[0], v[1], v[2], v[3]], axis=-1)
        second = np.stack([v[4], v[5], c[..., 0], c[..., 2]], axis=-1)
        return np.concatenate([first, second], axis=0).astype(np.float16)


def _with_green(red: np.ndarray, blue: np.ndarray) -> np.ndarray:
    """A colour of luminance 1 from its red and blue (shading.glsl even_light does the same)."""
    green = np.maximum((1.0 - LUMA[0] * red - LUMA[2] * blue) / LUMA[1], 0.0)
    return np.stack([red, green, blue], axis=1)


def cell_size(points: np.ndarray) -> float:
    """``SPACINGS`` times the points' median nearest-neighbour distance (half their spacing
    on a surface), within ``CELL_M``."""
    spacing = SPACINGS * median_spacing(points)
    if not math.isfinite(spacing):
        return CELL_M[1]
    return min(max(spacing, CELL_M[0]), CELL_M[1])


def median_spacing(points: np.ndarray) -> float:
    """The median distance from each point to its nearest neighbour; NaN for fewer than 2."""
    from scipy.spatial import cKDTree

    if len(points) < 2:
        return math.nan
    dist, _ = cKDTree(points).query(points, k=2)
    return float(np.median(dist[:, 1]))


AXES = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], float)


@dataclass(frozen=True)
class FieldLayout:
    """Where each face's tent falls on the grid: the part of :func:`build_field` that depends
    only on the faces' places and facing, kept by the probe (its faces do not move) so that a
    new set of lights (each step of the time slider) only weighs the faces' light into it.

    ``splat`` (6 cells, faces) holds each face's tent times its share of each way of facing,
    ``tent`` (cells, faces) its tent alone (the colour's weights); ``weight`` what each cell
    of each grid received."""

    origin: np.ndarray
    cell: float
    dims: np.ndarray  # (3,) int64, cells along x, y, z
    splat: object  # scipy.sparse.csr_matrix (6 x cells, faces)
    tent: object  # scipy.sparse.csr_matrix (cells, faces)
    weight: np.ndarray  # (6, cells)

    @classmethod
    def of(cls, points: np.ndarray, facing: np.ndarray, cell: float) -> FieldLayout:
        """The layout of faces at finite ``points`` facing unit ``facing`` on cells of
        ``cell`` metres (grown until the grid fits ``MAX_CELLS``)."""
        from scipy.sparse import csr_matrix

        pts = np.asarray(points, np.float64).reshape(-1, 3)
        nrm = np.asarray(facing, np.float64).reshape(-1, 3)
        origin, c, dims = grid_around(pts, float(cell), SPREAD, MAX_CELLS)
        flat_n = int(np.prod(dims))
        flat, tent = tents(pts, origin, c, dims, SPREAD)
        keys, w = facing_splat(nrm, flat, tent, flat_n)
        faces = np.repeat(np.arange(len(pts)), 3 * flat.shape[1])
        shape = (BUCKETS * flat_n, len(pts))
        splat = csr_matrix((w, (keys, faces)), shape=shape)  # duplicates summed
        weight = np.bincount(keys, w, BUCKETS * flat_n).reshape(BUCKETS, flat_n)
        cells_of = np.repeat(np.arange(len(pts)), flat.shape[1])
        by_cell = csr_matrix((tent.ravel(), (flat.ravel(), cells_of)), shape=(flat_n, len(pts)))
        return cls(origin, c, dims, splat, by_cell, weight)

    def field(self, values: np.ndarray, levels: np.ndarray, chroma: np.ndarray) -> AmbientField:
        """The field of this layout's faces with bounce light ``values`` (F,), finite and not
        negative, colours ``chroma`` (F, 3) and ``levels`` (6,) where a cell is unsure."""
        flat_n = int(np.prod(self.dims))
        total = np.asarray(self.splat @ values).reshape(BUCKETS, flat_n)
        # The colour, one per cell: the faces' colours weighted by the light they bring.
        lit = np.asarray(self.tent @ values)
        colour = np.asarray(self.tent @ (chroma * values[:, None]))
        colour = np.where(lit[:, None] > 1e-12, colour / np.maximum(lit, 1e-12)[:, None], 1.0)
        weight = self.weight
        sure = np.minimum(weight / FULL_WEIGHT, 1.0)
        mean = np.divide(total, weight, out=np.zeros_like(total), where=weight > 0.0)
        level = np.asarray(levels, np.float64).reshape(BUCKETS, 1)
        out = (mean * sure + (1.0 - sure) * level).astype(np.float32)
        d = self.dims
        out = out.reshape(BUCKETS, int(d[2]), int(d[1]), int(d[0]))
        colour = colour.reshape(int(d[2]), int(d[1]), int(d[0]), 3).astype(np.float32)
        shape = (int(d[0]), int(d[1]), int(d[2]))
        return AmbientField(self.origin, self.cell, shape, out, values.shape[0], colour)


def grid_around(
    pts: np.ndarray, cell: float, spread: float, max_cells: int
) -> tuple[np.ndarray, float, np.ndarray]:
    """A grid over finite points ``pts`` with room for a tent ``spread`` cells wide each side:
    its origin (the corner of cell 0), its cell (``cell`` metres, grown until the grid has at
    most ``max_cells`` cells and ``MAX_DIM`` along each axis: the textures stack two slabs
    along z, and GL promises 2048 texels a side) and its dims (3,) int64 along x, y, z."""
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    c = cell
    while True:
        dims = np.maximum(np.ceil((hi - lo) / c + 2.0 * spread).astype(np.int64), 1)
        if int(np.prod(dims)) <= max_cells and int(dims.max()) <= MAX_DIM:
            break
        c *= 1.25
    return 0.5 * (lo + hi) - 0.5 * dims * c, c, dims


def tents(
    pts: np.ndarray, origin: np.ndarray, cell: float, dims: np.ndarray, spread: float
) -> tuple[np.ndarray, np.ndarray]:
    """The cells each point's tent (``spread`` cells each way, separable) reaches: their flat
    index (z, y, x order) and the tent's weight there, both (P, O); 0 outside the grid."""
    h = (pts - origin) / cell - 0.5  # in cell-centre units
    base = np.floor(h).astype(np.int64)
    reach = int(math.ceil(spread))
    steps = np.arange(-reach + 1, reach + 1)
    offsets = np.stack(np.meshgrid(steps, steps, steps, indexing="ij"), -1).reshape(-1, 3)
    idx = base[:, None, :] + offsets[None, :, :]  # (P, O, 3)
    tent = np.prod(np.maximum(0.0, 1.0 - np.abs(h[:, None, :] - idx) / spread), axis=2)
    tent *= ((idx >= 0) & (idx < dims)).all(axis=2)
    flat = (idx[..., 2] * dims[1] + idx[..., 1]) * dims[0] + idx[..., 0]
    return np.clip(flat, 0, int(np.prod(dims)) - 1), tent


def facing_splat(
    nrm: np.ndarray, flat: np.ndarray, tent: np.ndarray, flat_n: int
) -> tuple[np.ndarray, np.ndarray]:
    """Each point's tent (``tents``) shared among the three grids its unit normal ``nrm``
    faces, by the squared components (they sum to 1): the keys ``grid * flat_n + cell`` and
    weights, both (P * 3 * O,), in point, axis, cell order."""
    bucket_of = np.where(nrm >= 0.0, [0, 2, 4], [1, 3, 5])  # (P, 3)
    keys = (bucket_of[:, :, None] * flat_n + flat[:, None, :]).ravel()
    return keys, ((nrm * nrm)[:, :, None] * tent[:, None, :]).ravel()


def box_sum(a: np.ndarray) -> np.ndarray:
    """The sum over each cell's 3 x 3 x 3 neighbourhood of grids ``a`` (G, Z, Y, X, ...)."""
    out = a
    for axis in (1, 2, 3):
        pad = [(0, 0)] * a.ndim
        pad[axis] = (1, 1)
        p = np.pad(out, pad)
        n = out.shape[axis]
        out = (
            np.take(p, range(0, n), axis=axis)
            + np.take(p, range(1, n + 1), axis=axis)
            + np.take(p, range(2, n + 2), axis=axis)
        )
    return out


def fill_empty(mean: np.ndarray, steps: int) -> np.ndarray:
    """``mean`` (G, Z, Y, X, ...) with its NaN (empty) cells given their filled neighbours'
    mean, ``steps`` cells out from the filled ones (in place; returned)."""
    for _ in range(steps):
        empty = ~np.isfinite(mean)
        if not empty.any():
            break
        filled = (~empty).astype(np.float64)
        sums, counts = box_sum(np.where(empty, 0.0, mean)), box_sum(filled)
        grow = empty & (counts > 0.0)
        mean[grow] = sums[grow] / counts[grow]
    return mean


def usable(points: np.ndarray, facing: np.ndarray) -> np.ndarray:
    """Which faces have a finite place and facing (the others are left out of the field)."""
    pts = np.asarray(points, np.float64).reshape(-1, 3)
    nrm = np.asarray(facing, np.float64).reshape(-1, 3)
    return np.asarray(np.isfinite(pts).all(axis=1) & np.isfinite(nrm).all(axis=1))


def _checked_cell(cell: float | None, pts: np.ndarray) -> float:
    c = float(cell) if cell is not None else cell_size(pts)
    if not (math.isfinite(c) and c > 0.0):
        raise ValueError(f"ambient field cell must be a positive length, not {cell!r}")
    return c


def build_field(
    points: np.ndarray,
    facing: np.ndarray,
    values: np.ndarray,
    levels: np.ndarray,
    cell: float | None = None,
    chroma: np.ndarray | None = None,
    layout: FieldLayout | None = None,
) -> AmbientField | None:
    """The field of faces at ``points`` facing ``facing`` (unit) with bounce light ``values``
    (the radiance scale of a white surface), ``levels`` (6,) the one level of a surface
    facing +X, -X, +Y, -Y, +Z, -Z where a cell is unsure; None when no face is usable (none,
    or none finite). ``chroma`` (F, 3): each face's bounce colour of luminance 1 (None: grey).

    ``layout``: these faces' :class:`FieldLayout` (of the usable ones), used when every face's
    light and colour are usable too; otherwise the faces left are laid out afresh."""
    pts = np.asarray(points, np.float64).reshape(-1, 3)
    nrm = np.asarray(facing, np.float64).reshape(-1, 3)
    val = np.asarray(values, np.float64).reshape(-1)
    col = np.ones((len(pts), 3)) if chroma is None else np.asarray(chroma, np.float64)
    placed = usable(pts, nrm)
    ok = placed & np.isfinite(val) & (val >= 0.0)
    ok &= np.isfinite(col).all(axis=1) & (col >= 0.0).all(axis=1)
    if not ok.any():
        return None
    if layout is not None and (ok == placed).all():
        return layout.field(val[ok], levels, col[ok])
    pts, nrm = pts[ok], nrm[ok]
    return FieldLayout.of(pts, nrm, _checked_cell(cell, pts)).field(val[ok], levels, col[ok])
