"""The share of the sky each point sees, by place: a grid the shaders read per pixel.

The per-vertex share (``app.sky_light.sky_visibility``) is drawn by interpolating across each
triangle. A real room's wall or ceiling is a few long triangles whose corners lie metres apart:
the light of a window, which falls off over tens of centimetres, cannot be drawn by three
values, and the daylit living room's walls and ceiling showed polygons of sky light (stop 34).
This keeps the share where it was measured instead, on a grid independent of how the surfaces
were cut into triangles (as ``app.ambient_field`` keeps the bounce light):

- points are spread over the surfaces by area (``RAYS`` rays a side, the per-vertex bake's
  cosine and portal rays: ``app.sky_light.seen_share``), on both sides of each surface;
- each side's share is spread with a tent ``SPREAD`` cells wide into six grids by the way it
  faces (+X, -X, +Y, -Y, +Z, -Z, by the squared components of its normal): the inside of a
  wall and the outside of the wall behind it face opposite ways and do not mix;
- a cell keeps the mean of the shares it received (leaning on its neighbours' where it
  received little, ``PRIOR_WEIGHT``); an empty cell takes its neighbours' mean (``DILATE``
  cells out), so a trilinear read beside the last filled cell is not darkened;
- a pixel of normal N reads the means of the grids on N's side that it leans towards
  (``LEAN``), two float fetches (sky.glsl ``sky_share``; in a standalone test on llvmpipe at
  2x640x720 three half-float fetches of sums and weights took 9.3 ms, two of means 6.7, in
  32-bit floats 5.2; 8-bit codes took 3 but drew the cells on a dim wall as a faint plaid; in
  the living room's lighting pass the two cost 9 ms);
- where no point was near (a model's outside, whose rays leave it elsewhere than through the
  windows) the pixel keeps its vertex's share.

A side covered by something lying on it (``app.sky_light.COVERED_SHARE`` of its rays end
within ``COVER_M``: the floor under a cabinet) weighs nothing, so the cabinet's sides take the
light of the room round it. A side whose escaping rays leave the model elsewhere than through
the room's windows (``app.sky_light.through_portal``: the ground seen through a gap under the
floor) weighs by the share that does. Baked before the per-vertex share, on the same
background thread (3.4 s for the living room's 6M rays, the vertices 3.9 s more).
"""

from __future__ import annotations

import logging
import math
import threading
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from app.ambient_field import (
    BUCKETS,
    box_sum,
    facing_splat,
    fill_empty,
    grid_around,
    median_spacing,
    tents,
)
from app.daylight_photons import Portal
from app.raycast import RayCaster
from app.scene import Scene
from app.sky_light import (
    CHUNK_RAYS,
    OFFSET_M,
    PORTAL_SHARE,
    lets_light_through,
    occluders,
    seen_share,
    sky_portal,
    sky_visibility,
)

log = logging.getLogger(__name__)

RAYS = 48  # per side of a point
MAX_RAYS = 6_000_000  # the points' budget
CELL_M = 0.1  # the cell's edge at least (grown until the grid fits MAX_CELLS)
#: ... and at least this many times the points' median spacing, so that a cell on a surface
#: receives a few points' weight (a cathedral's points lie a hand apart, a room's 5 cm).
SPACINGS = 2.0
SPREAD = 2.0  # a point's tent reaches this many cells each way
MAX_CELLS = 1 << 17  # per direction grid
#: A cell's own mean leans on its neighbourhood's (3 x 3 x 3 cells) as if that were this
#: much weight: a cell at a tent's fringe, which a few points' tails reached, is not their
#: noise alone.
PRIOR_WEIGHT = 0.5
DILATE = 3  # empty cells take their filled neighbours' mean, this many cells out
#: A pixel reads a grid only where its normal's squared component along it is above this (the
#: rest is a mean of the grids it reads): a wall reads one of the three its side faces.
LEAN = 0.02


@dataclass(frozen=True)
class SkyField:
    """The sky's share by place and facing. ``total`` and ``weight`` are (6, Z, Y, X) float32:
    per direction grid and cell, the sum of the points' weighted shares and of their weights;
    cell (i, j, k) spans ``origin + cell * [i, j, k]`` to ``origin + cell * [i + 1, j + 1,
    k + 1]``. The shaders read :meth:`packed`: each cell's mean."""

    origin: np.ndarray  # (3,) float64
    cell: float
    dims: tuple[int, int, int]  # cells along x, y, z
    total: np.ndarray
    weight: np.ndarray
    points: int  # sides spread into it

    def means(self) -> np.ndarray:
        """Each cell's share, (6, Z, Y, X) float64, NaN where no point reached within
        ``DILATE`` cells: the points' mean, leaning on the neighbourhood's by
        ``PRIOR_WEIGHT``; an empty cell takes its filled neighbours' mean."""
        total, weight = self.total.astype(np.float64), self.weight.astype(np.float64)
        t3, w3 = box_sum(total), box_sum(weight)
        near = np.divide(t3, w3, out=np.zeros_like(t3), where=w3 > 1e-9)
        mean = np.full(total.shape, np.nan)
        some = (weight + PRIOR_WEIGHT * (w3 > 1e-9)) > 1e-9
        mean[some] = (total + PRIOR_WEIGHT * near)[some] / (weight + PRIOR_WEIGHT)[some]
        return fill_empty(mean, DILATE)

    def packed(self) -> np.ndarray:
        """The grids as the shader reads them, (2 Z, Y, X, 4) float32 (half floats took 25 %
        longer to filter in a standalone test on llvmpipe): slab 0 holds the cells' share
        facing +X, +Y, +Z, slab 1 facing -X, -Y, -Z (two fetches a pixel); -1 where there is
        none (the pixel keeps its vertex's share)."""
        mean = np.where(np.isfinite(m := self.means()), np.clip(m, 0.0, 1.0), -1.0)
        blank = np.zeros_like(mean[0])
        slabs = [np.stack([mean[0], mean[2], mean[4], blank], -1)]
        slabs.append(np.stack([mean[1], mean[3], mean[5], blank], -1))
        return np.concatenate(slabs, axis=0).astype(np.float32)

    def lookup(self, points: np.ndarray, normals: np.ndarray, vertex: np.ndarray) -> np.ndarray:
        """The share of the sky at world ``points`` of unit ``normals`` whose vertices saw
        ``vertex``: the CPU twin of sky.glsl ``sky_share`` (on :meth:`packed`)."""
        pts = np.asarray(points, np.float64).reshape(-1, 3)
        nrm = np.asarray(normals, np.float64).reshape(-1, 3)
        packed = self.packed().astype(np.float64)
        z = self.dims[2]
        dims = np.array(self.dims)
        g = np.clip((pts - self.origin) / self.cell, 0.5, dims - 0.5) - 0.5
        base = np.minimum(np.floor(g).astype(np.int64), np.maximum(dims - 2, 0))
        f = g - base
        read = np.zeros((len(pts), 3))
        for corner in range(8):
            o = np.array([(corner >> a) & 1 for a in range(3)])
            idx = np.minimum(base + o, dims - 1)
            w = np.prod(np.where(o == 1, f, 1.0 - f), axis=1)
            for axis in range(3):
                slab = np.where(nrm[:, axis] >= 0.0, 0, z)
                read[:, axis] += w * packed[idx[:, 2] + slab, idx[:, 1], idx[:, 0], axis]
        return _decode(read, nrm, np.asarray(vertex, np.float64).reshape(-1))


def _decode(read: np.ndarray, nrm: np.ndarray, vertex: np.ndarray) -> np.ndarray:
    """sky.glsl ``sky_share`` after its fetches: ``read`` (P, 3) the filtered shares on the
    normal's side of each axis (below 0: none there)."""
    lean = nrm**2
    w = np.where((read >= 0.0) & (lean > LEAN), lean, 0.0)
    total = w.sum(axis=1)
    field = np.divide((w * read).sum(axis=1), total, out=np.zeros(len(w)), where=total > 0.0)
    return np.where(total > 0.0, field, vertex)


def surface_points(
    scene: Scene, count: int, rng: np.random.Generator
) -> tuple[np.ndarray, np.ndarray]:
    """About ``count`` points spread over the surfaces that hide the sky by area (each
    triangle gets its expected number, rounded at random), and their normals (the vertices'
    normals interpolated, a broken one as none; the face's where those cancel): (P, 3) and
    (P, 3) float64. Triangles of no area, not finite or with an index out of range have no
    points. One mesh at a time: a model's triangles are never all copied at once."""
    clear = lets_light_through(scene)
    meshes = [m for m, through in zip(scene.meshes, clear) if not through]
    areas = [_areas(*_triangles(m))[0] for m in meshes]
    total = float(sum(a.sum() for a in areas))
    points, normals = [np.zeros((0, 3))], [np.zeros((0, 3))]
    if not total > 0.0 or not math.isfinite(total):
        return points[0], normals[0]
    for mesh, area in zip(meshes, areas):
        per_tri = np.floor(area / total * count + rng.random(len(area))).astype(np.int64)
        if not per_tri.sum():
            continue
        idx, pos = _triangles(mesh)
        which = np.repeat(np.arange(len(area)), per_tri)
        u, v = rng.random(len(which)), rng.random(len(which))
        flip = u + v > 1.0
        u, v = np.where(flip, 1.0 - u, u), np.where(flip, 1.0 - v, v)
        bary = np.stack([1.0 - u - v, u, v], axis=1)[:, :, None]
        corners = idx[which]
        vn = np.nan_to_num(np.asarray(mesh.normals, np.float64).reshape(-1, 3))
        nrm = (vn[corners] * bary).sum(axis=1)
        face = _areas(corners, pos)[1]
        length = np.linalg.norm(nrm, axis=1, keepdims=True)
        nrm = np.where(length > 1e-6, nrm / np.maximum(length, 1e-12), face)
        points.append((pos[corners] * bary).sum(axis=1))
        normals.append(nrm)
    return np.concatenate(points), np.concatenate(normals)


def _triangles(mesh) -> tuple[np.ndarray, np.ndarray]:
    """A mesh's triangles whose corners exist, (T, 3) int64, and its positions (V, 3)."""
    pos = np.asarray(mesh.positions, np.float64).reshape(-1, 3)
    idx = np.asarray(mesh.indices, np.int64).reshape(-1, 3)
    return idx[np.all((idx >= 0) & (idx < len(pos)), axis=1)], pos


def _areas(idx: np.ndarray, pos: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each triangle's area (0 where it has none or is not finite), (T,), and unit normal."""
    tri = pos[idx]
    face = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    length = np.linalg.norm(face, axis=1)
    good = np.isfinite(length) & (length > 0.0)
    unit = np.where(good[:, None], face / np.where(good, length, 1.0)[:, None], 0.0)
    return np.where(good, 0.5 * length, 0.0), unit


def sky_field(
    scene: Scene,
    caster: RayCaster,
    portal: Portal | None,
    rays: int | None = None,
    max_rays: int | None = None,
    seed: int = 0,
    cancelled: Callable[[], bool] | None = None,
) -> SkyField | None:
    """The field of ``scene`` (rays through ``caster``, the sky's occluders; half of each
    side's rays aimed at ``portal`` when there is one; ``rays`` a side, ``max_rays`` in all:
    None, ``RAYS`` and ``MAX_RAYS``); None when there is no surface or ``cancelled()`` turned
    true."""
    rng = np.random.default_rng(seed)
    rays = RAYS if rays is None else rays
    max_rays = MAX_RAYS if max_rays is None else max_rays
    n_portal = int(round(rays * PORTAL_SHARE)) if portal is not None and rays >= 2 else 0
    n_cos = max(1, rays - n_portal)
    pos, nrm = surface_points(scene, max(1, max_rays // (2 * (n_cos + n_portal))), rng)
    if not len(pos):
        return None
    side_pos = np.concatenate([pos + nrm * OFFSET_M, pos - nrm * OFFSET_M])
    side_nrm = np.concatenate([nrm, -nrm])
    seen = np.zeros(len(side_pos))
    covered = np.zeros(len(side_pos), bool)
    through = np.ones(len(side_pos))
    per_chunk = max(1, CHUNK_RAYS // (n_cos + n_portal))
    for start in range(0, len(side_pos), per_chunk):
        if cancelled is not None and cancelled():
            return None
        rows = slice(start, start + per_chunk)
        seen[rows], covered[rows], through[rows] = seen_share(
            caster, side_pos[rows], side_nrm[rows], n_cos, n_portal, portal, rng
        )
    weight = np.where(covered, 0.0, through)
    apart = median_spacing(pos)
    return spread_field(
        side_pos, side_nrm, np.clip(seen, 0.0, 1.0), weight, apart if apart > 0.0 else 0.0
    )


def spread_field(
    pos: np.ndarray, nrm: np.ndarray, seen: np.ndarray, weight: np.ndarray, apart: float = 0.0
) -> SkyField | None:
    """The field of sides at ``pos`` facing unit ``nrm`` that saw ``seen`` of the sky, each
    counted ``weight`` (0 to 1), the points ``apart`` metres apart (the cell: ``SPACINGS``
    times that, at least ``CELL_M``); those not finite weigh nothing. None when none
    counts."""
    ok = (weight > 0.0) & np.isfinite(pos).all(axis=1) & np.isfinite(nrm).all(axis=1)
    ok &= np.isfinite(seen) & np.isfinite(weight)
    if not ok.any():
        return None
    pos, nrm, seen, weight = pos[ok], nrm[ok], seen[ok], weight[ok]
    origin, cell, dims = grid_around(pos, max(CELL_M, SPACINGS * apart), SPREAD, MAX_CELLS)
    flat_n = int(np.prod(dims))
    total = np.zeros(BUCKETS * flat_n)
    received = np.zeros(BUCKETS * flat_n)
    for start in range(0, len(pos), 4096):  # (P, 64) tents: a few MB at a time
        part = slice(start, start + 4096)
        p, n, s = pos[part], nrm[part], seen[part]
        flat, tent = tents(p, origin, cell, dims, SPREAD)
        keys, w = facing_splat(n, flat, tent * weight[part, None], flat_n)
        received += np.bincount(keys, w, BUCKETS * flat_n)
        total += np.bincount(keys, w * np.repeat(s, 3 * flat.shape[1]), BUCKETS * flat_n)
    shape = (BUCKETS, int(dims[2]), int(dims[1]), int(dims[0]))
    return SkyField(
        origin,
        cell,
        (int(dims[0]), int(dims[1]), int(dims[2])),
        total.reshape(shape).astype(np.float32),
        received.reshape(shape).astype(np.float32),
        len(pos),
    )


class VisibilityBake:
    """The sky's share by place (:func:`sky_field`: ``field``, set first) and per vertex
    (``app.sky_light.sky_visibility``: ``result``) for one scene, on a background thread."""

    def __init__(self, scene: Scene, **options) -> None:
        self.scene = scene
        self.result: list[np.ndarray] | None = None
        self.field: SkyField | None = None
        self.error: str | None = None
        self._cancel = threading.Event()
        self._done = threading.Event()
        self._thread = threading.Thread(
            target=self._run, kwargs=options, name="sky-visibility", daemon=True
        )
        self._thread.start()

    def _run(self, seed: int = 0, **options) -> None:
        try:
            # Its own caster: embree builds a shared one lazily, not safely from two threads.
            tri = occluders(self.scene)
            caster = RayCaster(tri)
            stop = self._cancel.is_set
            # The field first: it is what the lighting reads wherever a point was near.
            portal = sky_portal(self.scene, caster, tri, seed)
            self.field = sky_field(self.scene, caster, portal, seed=seed, cancelled=stop)
            if not stop():
                self.result = sky_visibility(
                    self.scene, caster, seed=seed, cancelled=stop, **options
                )
        except Exception as exc:  # noqa: BLE001 - a failed bake leaves the sky light out
            self.error = f"{type(exc).__name__}: {exc}"
            log.warning("sky visibility could not be computed: %s", self.error)
        finally:
            self._done.set()

    @property
    def done(self) -> bool:
        return self._done.is_set()

    def wait(self, timeout: float | None = None) -> bool:
        return self._done.wait(timeout)

    def cancel(self) -> None:
        self._cancel.set()
