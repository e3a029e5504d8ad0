"""Where a person would stand in a scene: the spawn search.

For an interior that is on the main floor at eye height, facing down the longest free
direction, found with batched ray casts; a lone object is viewed from outside instead.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from app.raycast import RayCaster
from app.scene import Scene, Viewpoint

EYE_HEIGHT_M = 1.6
# Head room above the eye: a "floor" with less than this up to the next surface is a shelf, a
# vault's upper face or a slab's underside, not somewhere to stand.
_MIN_CLEARANCE_M = EYE_HEIGHT_M + 0.3
_BODY_RADIUS_M = 0.35  # nearest wall allowed around a spawn candidate at eye height
_GRID_TARGET = 2500  # candidate columns for the spawn search; ~60k rays with embree is ~0.1 s
_MAX_LAYERS = 12  # surfaces peeled per column: roof, vaults, floors, slabs...
_RING_DIRECTIONS = 16
_INSIDE_HIT_FRACTION = 0.75  # "most" horizontal rays must hit something to count as enclosed
_FRONT_FACING_FRACTION = 0.5  # of those hits, the share that must face the eye
_MIN_REVERSED_ROOM_M2 = 20.0  # floor area that makes an inside-out enclosure a room
_LEVEL_BIN_M = 0.35  # floor heights closer than this are one level (thresholds, small steps)
# A lone object's bounding sphere covers this share of a 90 degree view from the spawn.
_OBJECT_VIEW_FILL = 0.6


@dataclass
class SpawnResult:
    """Where to stand, and what the search learnt about the walkable level (for default lights).

    ``level_points`` are floor positions on the chosen level that passed the "inside" test, with
    the head room above each in ``level_clearance`` and the distance to the nearest wall at eye
    height in ``level_free``; all are empty for an outside view.
    """

    viewpoint: Viewpoint
    floor_y: float | None
    level_points: np.ndarray  # (K, 3) float64
    level_clearance: np.ndarray  # (K,) float64
    level_free: np.ndarray  # (K,) distance to the nearest wall at eye height
    cell_area: float  # floor area each level point stands for (m^2)
    free_distance: float  # free distance along the view direction (m); inf when unbounded


def find_spawn(scene: Scene, caster: RayCaster | None = None) -> SpawnResult:
    """Stand inside the main room if there is one, otherwise look at the object from outside.

    ``caster`` must have been built from ``scene.triangles()`` with triangle indices as owners
    (as :func:`load_scene` does); it is built here when not given.
    """
    if caster is None:
        caster = RayCaster(scene.triangles(), np.arange(scene.triangle_count))
    lo, hi = (np.asarray(b, np.float64) for b in scene.bounds())
    tris = scene.triangles().astype(np.float64)
    interior = _interior_spawn(caster, _triangle_normals(tris), lo, hi)
    if interior is not None:
        return interior
    return _outside_spawn(lo, hi)


def _triangle_normals(tris: np.ndarray) -> np.ndarray:
    n = np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0])
    return n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-30)


def _ring(n: int) -> np.ndarray:
    a = np.arange(n) * (2.0 * math.pi / n)
    return np.column_stack([np.cos(a), np.zeros(n), np.sin(a)])


def _interior_spawn(
    caster: RayCaster, normals: np.ndarray, lo: np.ndarray, hi: np.ndarray
) -> SpawnResult | None:
    """Search a grid of columns for the lowest large enclosed floor and its most open point.

    Each column is peeled from the top down with one batched cast per layer, so every surface
    under the column is found (roof, vault, floor, slab...). A roughly horizontal surface with at
    least head room up to the surface above it is a floor; its eye point is "inside" when most
    of a ring of horizontal rays hit something (walls all round), none is closer than a body's
    width, and most of what they hit faces the eye: walls seen from inside a room show their
    front faces, while the inside of a closed object (a truck's tank) shows back faces.
    """
    size = hi - lo
    diag = float(np.linalg.norm(size))
    if size[1] < _MIN_CLEARANCE_M or min(size[0], size[2]) < 2.0 * _BODY_RADIUS_M:
        return None  # nothing a person could stand inside
    area = float(size[0] * size[2])
    step = max(math.sqrt(area / _GRID_TARGET), 0.2)
    nx = max(int(round(size[0] / step)), 1)
    nz = max(int(round(size[2] / step)), 1)
    xs = lo[0] + (np.arange(nx) + 0.5) * (size[0] / nx)
    zs = lo[2] + (np.arange(nz) + 0.5) * (size[2] / nz)
    gx, gz = np.meshgrid(xs, zs, indexing="ij")
    xz = np.column_stack([gx.ravel(), gz.ravel()])
    cell_area = float(size[0] / nx * size[2] / nz)

    eps = max(1e-4 * diag, 1e-4)
    ys, tri = _peel_down(caster, xz, float(hi[1]) + 0.01 * diag + 0.1, eps)

    # Floors: a horizontal surface with a surface above it (so there is a ceiling) far enough up.
    above = ys[:, :-1]
    below = ys[:, 1:]
    flat = np.abs(normals[np.maximum(tri[:, 1:], 0), 1]) > 0.7
    clearance = above - below
    ok = np.isfinite(below) & np.isfinite(above) & flat & (clearance >= _MIN_CLEARANCE_M)
    col, layer = np.nonzero(ok)
    if col.size == 0:
        return None
    floor_y = below[col, layer]
    head = clearance[col, layer]
    eyes = np.column_stack([xz[col, 0], floor_y + EYE_HEIGHT_M, xz[col, 1]])

    ring = _ring(_RING_DIRECTIONS)
    dirs = np.tile(ring, (len(eyes), 1))
    dist, who = caster.cast_many(np.repeat(eyes, len(ring), axis=0), dirs)
    facing = np.einsum("ij,ij->i", normals[np.maximum(who, 0)], dirs) < 0.0
    hit = np.isfinite(dist)
    dist = dist.reshape(len(eyes), len(ring))
    hit_frac = hit.reshape(dist.shape).mean(axis=1)
    front_frac = (facing & hit).reshape(dist.shape).sum(axis=1) / np.maximum(
        hit.reshape(dist.shape).sum(axis=1), 1
    )
    nearest = dist.min(axis=1)
    enclosed = (hit_frac >= _INSIDE_HIT_FRACTION) & (nearest >= _BODY_RADIUS_M)
    inside = enclosed & (front_frac >= _FRONT_FACING_FRACTION)
    reversed_walls = not inside.any()
    if reversed_walls:
        # Some exporters (SketchUp, for one) leave walls facing out; such a room still counts
        # if it is big enough to walk around in, which a closed object's cavity is not.
        inside = enclosed
    if not inside.any():
        return None
    eyes, floor_y, head, dist = eyes[inside], floor_y[inside], head[inside], dist[inside]

    level = _main_level(floor_y)
    if reversed_walls and level.sum() * cell_area < _MIN_REVERSED_ROOM_M2:
        return None
    eyes, floor_y, head, dist = eyes[level], floor_y[level], head[level], dist[level]
    # Most free space: the largest distance to the nearest wall, then the roomiest on average.
    finite = np.where(np.isfinite(dist), dist, diag)
    free = finite.min(axis=1)
    score = free + 0.01 * finite.mean(axis=1)
    best = int(np.argmax(score))
    eye = eyes[best]
    yaw, view_free = _longest_view(caster, eye, diag)
    return SpawnResult(
        Viewpoint((float(eye[0]), float(eye[1]), float(eye[2])), yaw, 0.0),
        float(floor_y[best]),
        np.column_stack([eyes[:, 0], floor_y, eyes[:, 2]]),
        head.astype(np.float64),
        free,
        cell_area,
        view_free,
    )


def _peel_down(
    caster: RayCaster, xz: np.ndarray, y_top: float, eps: float
) -> tuple[np.ndarray, np.ndarray]:
    """Heights (NaN past the last) and triangle ids (-1) of every surface under each column."""
    n = len(xz)
    ys = np.full((n, _MAX_LAYERS), np.nan)
    tri = np.full((n, _MAX_LAYERS), -1, np.int64)
    origins = np.column_stack([xz[:, 0], np.full(n, y_top), xz[:, 1]])
    down = np.array([[0.0, -1.0, 0.0]])
    active = np.arange(n)
    for k in range(_MAX_LAYERS):
        if active.size == 0:
            break
        dist, who = caster.cast_many(origins[active], np.repeat(down, active.size, axis=0))
        hit = np.isfinite(dist)
        idx = active[hit]
        y_hit = origins[idx, 1] - dist[hit]
        ys[idx, k] = y_hit
        tri[idx, k] = who[hit]
        origins[idx, 1] = y_hit - eps
        active = idx
    return ys, tri


def _main_level(floor_y: np.ndarray) -> np.ndarray:
    """Mask of the candidates on the lowest floor level that is large.

    "Large" is at least a quarter of the biggest level's sampled area: a crypt stair or a sunken
    tomb is lower than the main floor but small, an organ loft is large but higher.
    """
    base = float(floor_y.min())
    bins = np.round((floor_y - base) / _LEVEL_BIN_M).astype(np.int64)
    counts = np.bincount(bins)
    # A level straddling a bin boundary splits in two: judge each bin with its neighbours.
    padded = np.concatenate([[0], counts, [0]])
    merged = counts + np.maximum(padded[:-2], padded[2:])
    large = np.flatnonzero(merged >= max(0.25 * merged.max(), 3))
    chosen = int(large.min())
    members = bins == chosen
    if not members.any():  # large only thanks to a neighbour: centre on the neighbourhood
        members = np.abs(bins - chosen) <= 1
    centre = float(np.median(floor_y[members]))
    return np.abs(floor_y - centre) <= _LEVEL_BIN_M


def _longest_view(caster: RayCaster, eye: np.ndarray, diag: float) -> tuple[float, float]:
    """Yaw (degrees, 0 = -Z, positive = left) of the longest free horizontal sight line.

    A direction counts only as far as its neighbours +-10 degrees also reach, so a slit between
    two columns does not win over an open nave.
    """
    n = 72
    ring = _ring(n)
    dist, _ = caster.cast_many(np.repeat(eye[None, :], n, axis=0), ring)
    reach = np.where(np.isfinite(dist), dist, 2.0 * diag)
    window = np.stack([np.roll(reach, s) for s in (-2, -1, 0, 1, 2)]).min(axis=0)
    best = int(np.argmax(window))
    d = ring[best]
    yaw = math.degrees(math.atan2(-d[0], -d[2]))
    free = float(dist[best])
    return yaw, free


def _outside_spawn(lo: np.ndarray, hi: np.ndarray) -> SpawnResult:
    """Stand on the +Z side (glTF's front), level with the centre, the object filling the view."""
    centre = (lo + hi) / 2.0
    radius = max(float(np.linalg.norm(hi - lo)) / 2.0, 1e-3)
    half_angle = math.radians(90.0 * _OBJECT_VIEW_FILL / 2.0)
    distance = radius / math.sin(half_angle)
    pos = (float(centre[0]), float(centre[1]), float(centre[2] + distance))
    return SpawnResult(
        Viewpoint(pos, 0.0, 0.0), None, np.zeros((0, 3)), np.zeros(0), np.zeros(0), 0.0, math.inf
    )
