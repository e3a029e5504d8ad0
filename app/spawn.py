"""Where a person would stand in a scene: the spawn search.

For an interior that is on the main floor at eye height, facing down the longest free
direction, found with batched ray casts; a lone object is viewed from outside instead.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass

import numpy as np

from app.raycast import RayCaster
from app.scene import Scene, Viewpoint

log = logging.getLogger(__name__)

EYE_HEIGHT_M = 1.6
# Head room above the eye: a "floor" with less than this up to the next surface is a shelf, a
# vault's upper face or a slab's underside, not somewhere to stand.
_MIN_CLEARANCE_M = EYE_HEIGHT_M + 0.3
_BODY_RADIUS_M = 0.35  # nearest wall allowed around a spawn candidate at eye height
_LOW_RING_M = (0.3, 0.6)  # heights above the floor where furniture near the spawn is looked for
_GRID_TARGET = 2500  # candidate columns for the spawn search; ~60k rays with embree is ~0.1 s
_MAX_LAYERS = 12  # surfaces peeled per column: roof, vaults, floors, slabs...
_RING_DIRECTIONS = 16
# "Most" horizontal rays must hit a wall to count as enclosed; below three quarters so that a
# room with one open side (a stage set, a missing wall, a bay onto nothing) still counts.
_INSIDE_HIT_FRACTION = 0.6
# A "wall" farther than this is a sky box, a terrain's horizon or a far building, not a room's.
_MAX_WALL_M = 150.0
# The candidate grid covers where the geometry is, not the raw bounding box, so a 222 m ground
# plane or a sky box does not spread the columns thin: up to this many of the widest triangles are
# left out when they are this many times wider than all the rest.
_MAX_OUTLIERS = 64
_REFINE_CELL_M = 0.3  # a first search coarser than this is refined over the level it found
_OUTLIER_SPAN = 3.0
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
    head_room: float = math.nan  # floor to the surface above the spawn (m); NaN outside


def outside_view(scene: Scene) -> SpawnResult:
    """The fallback view: outside the model, looking at it (needs nothing but its bounds)."""
    lo, hi = (np.asarray(b, np.float64) for b in scene.bounds())
    if not (np.isfinite(lo).all() and np.isfinite(hi).all()):
        lo, hi = np.zeros(3), np.zeros(3)
    return _outside_spawn(lo, hi)


def safe_find_spawn(scene: Scene, caster: RayCaster | None = None) -> tuple[SpawnResult, list[str]]:
    """:func:`find_spawn` that never raises: a failure gives the outside view and a warning."""
    try:
        return find_spawn(scene, caster), []
    except Exception as exc:  # noqa: BLE001 - a spawn bug must not stop a load
        log.exception("spawn search failed on %s", scene.name)
        return outside_view(scene), [
            f"could not find where to stand inside (an unexpected {type(exc).__name__}; "
            "details in the log): viewing the model from outside"
        ]


def find_spawn(scene: Scene, caster: RayCaster | None = None) -> SpawnResult:
    """Stand inside the main room if there is one, otherwise look at the object from outside.

    ``caster`` must have been built from ``scene.triangles()`` with triangle indices as owners
    (as :func:`load_scene` does); it is built here when not given.
    """
    # float32 as the scene holds it (re-centred, so precise to well under a millimetre): a
    # float64 copy would double the search's memory on a million-triangle room.
    tris = scene.triangles()
    if caster is None:
        caster = RayCaster(tris, np.arange(len(tris)))
    lo, hi = (np.asarray(b, np.float64) for b in scene.bounds())
    interior = interior_spawn(tris, caster)
    if interior is not None:
        return interior
    return _outside_spawn(lo, hi)


def interior_spawn(tris: np.ndarray, caster: RayCaster) -> SpawnResult | None:
    """The interior spawn in triangles ``tris`` (``caster`` built from them), or None."""
    if len(tris) == 0:
        return None
    verts = tris.reshape(-1, 3)
    lo, hi = verts.min(axis=0), verts.max(axis=0)
    normals = _triangle_normals(tris)
    dense_lo, dense_hi = _dense_box(tris, lo, hi)
    found = _interior_spawn(caster, normals, dense_lo, dense_hi, lo, hi)
    if found is None and (np.any(dense_lo > lo) or np.any(dense_hi < hi)):
        found = _interior_spawn(caster, normals, lo, hi, lo, hi)  # the room is the sparse part
    if found is None:
        return None
    # A room found on a coarse grid (a house in a large terrain or a city block): search again
    # over that level alone, so the spawn is placed to a few tens of centimetres.
    cell = math.sqrt(found.cell_area)
    pts = found.level_points
    r_lo = np.array([pts[:, 0].min() - cell, lo[1], pts[:, 2].min() - cell])
    r_hi = np.array([pts[:, 0].max() + cell, hi[1], pts[:, 2].max() + cell])
    r_lo, r_hi = np.maximum(r_lo, lo), np.minimum(r_hi, hi)
    searched = float(np.prod((dense_hi - dense_lo)[[0, 2]]))
    if cell > _REFINE_CELL_M and float(np.prod((r_hi - r_lo)[[0, 2]])) < 0.5 * searched:
        fine = _interior_spawn(caster, normals, r_lo, r_hi, lo, hi)
        if fine is not None and fine.floor_y is not None and found.floor_y is not None:
            if abs(fine.floor_y - found.floor_y) <= _LEVEL_BIN_M:
                return fine
    return found


def _dense_box(tris: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Horizontal extent of the scene without its few oversized triangles (the height is kept).

    A ground plane scaled to 222 m, a sky box or a backdrop is a handful of triangles each far
    wider than everything else together; the largest ``k`` triangles are left out when the
    smallest of them is more than ``_OUTLIER_SPAN`` times as wide as the rest of the scene.
    """
    tmin = np.minimum(np.minimum(tris[:, 0], tris[:, 1]), tris[:, 2])  # faster than min(axis=1)
    tmax = np.maximum(np.maximum(tris[:, 0], tris[:, 1]), tris[:, 2])
    span = np.maximum(tmax[:, 0] - tmin[:, 0], tmax[:, 2] - tmin[:, 2])
    m = min(_MAX_OUTLIERS, len(tris) - 1)
    if m <= 0:
        return lo.copy(), hi.copy()
    top = np.argpartition(-span, m - 1)[:m]
    top = top[np.argsort(-span[top])]
    # The rest's box: triangles no wider than the m-th widest (ties may leave some out: harmless).
    rest = span < span[top[-1]]
    if rest.any():
        r_lo, r_hi = tmin[rest].min(axis=0), tmax[rest].max(axis=0)
    else:
        r_lo, r_hi = np.full(3, np.inf), np.full(3, -np.inf)
    best = (lo.copy(), hi.copy())
    # Walk k down from m: the box of triangles top[k:] grows by one triangle per step.
    b_lo, b_hi = r_lo.copy(), r_hi.copy()
    found = False
    for k in range(m, 0, -1):
        if np.all(b_hi >= b_lo):
            width = float(np.max((b_hi - b_lo)[[0, 2]]))
            if not found and span[top[k - 1]] > _OUTLIER_SPAN * width + 1.0:
                best, found = (b_lo.copy(), b_hi.copy()), True
        t = tris[top[k - 1]]
        b_lo, b_hi = np.minimum(b_lo, t.min(axis=0)), np.maximum(b_hi, t.max(axis=0))
    d_lo, d_hi = best
    d_lo[1], d_hi[1] = lo[1], hi[1]
    return d_lo, d_hi


def _triangle_normals(tris: np.ndarray) -> np.ndarray:
    n = np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0])
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-30)
    return n


def _ring(n: int) -> np.ndarray:
    a = np.arange(n) * (2.0 * math.pi / n)
    return np.column_stack([np.cos(a), np.zeros(n), np.sin(a)])


def _interior_spawn(
    caster: RayCaster,
    normals: np.ndarray,
    lo: np.ndarray,
    hi: np.ndarray,
    scene_lo: np.ndarray,
    scene_hi: np.ndarray,
) -> SpawnResult | None:
    """Search a grid of columns for the lowest large enclosed floor and its most open point.

    Each column is peeled from the top down with one batched cast per layer, so every surface
    under the column is found (roof, vault, floor, slab...). A roughly horizontal surface with at
    least head room up to the surface above it is a floor; its eye point is "inside" when most
    of a ring of horizontal rays hit something (walls all round), none is closer than a body's
    width, and most of what they hit faces the eye: walls seen from inside a room show their
    front faces, while the inside of a closed object (a truck's tank) shows back faces.
    The columns cover ``lo``..``hi``; ``scene_lo``..``scene_hi`` are the whole scene's bounds.
    """
    size = hi - lo
    diag = float(np.linalg.norm(scene_hi - scene_lo))
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
    ys, tri = _peel_down(caster, xz, float(scene_hi[1]) + 0.01 * diag + 0.1, eps)

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
    dist = np.where(dist <= _MAX_WALL_M, dist, np.inf)  # a sky box is not a wall
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
    # ... also below the eye: not pressed against a sofa or a coffee table, so the first step
    # forward is not already blocked.
    low_free = np.full(len(eyes), np.inf)
    for h in _LOW_RING_M:
        low = np.column_stack([eyes[:, 0], floor_y + h, eyes[:, 2]])
        d_low, _ = caster.cast_many(np.repeat(low, len(ring), axis=0), np.tile(ring, (len(low), 1)))
        d_low = np.where(np.isfinite(d_low), d_low, diag).reshape(len(eyes), len(ring))
        low_free = np.minimum(low_free, d_low.min(axis=1))
    free = np.minimum(free, low_free)
    score = free + 0.01 * finite.mean(axis=1)
    best = int(np.argmax(score))
    eye = eyes[best]
    yaw, view_free = _longest_view(caster, eye)
    return SpawnResult(
        Viewpoint((float(eye[0]), float(eye[1]), float(eye[2])), yaw, 0.0),
        float(floor_y[best]),
        np.column_stack([eyes[:, 0], floor_y, eyes[:, 2]]),
        head.astype(np.float64),
        free,
        cell_area,
        view_free,
        float(head[best]),
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
    # At least three samples, unless the whole search found fewer (a small room on a coarse grid).
    large = np.flatnonzero(merged >= min(max(0.25 * merged.max(), 3), merged.max()))
    chosen = int(large.min())
    members = bins == chosen
    if not members.any():  # large only thanks to a neighbour: centre on the neighbourhood
        members = np.abs(bins - chosen) <= 1
    centre = float(np.median(floor_y[members]))
    return np.abs(floor_y - centre) <= _LEVEL_BIN_M


def _longest_view(caster: RayCaster, eye: np.ndarray) -> tuple[float, float]:
    """Yaw (degrees, 0 = -Z, positive = left) of the longest free horizontal sight line.

    A direction counts only as far as its neighbours +-10 degrees also reach, so a slit between
    two columns does not win over an open nave; a direction that sees nothing (an open side, a
    window onto no geometry) counts as short, so the view faces into the room, not out of it.
    """
    n = 72
    ring = _ring(n)
    dist, _ = caster.cast_many(np.repeat(eye[None, :], n, axis=0), ring)
    hit = np.isfinite(dist) & (dist <= _MAX_WALL_M)
    reach = np.where(hit, dist, 0.0 if hit.any() else 1.0)
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
