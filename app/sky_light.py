"""How much of the sky each vertex sees: the room's occlusion of the sky light, baked with rays.

From each vertex, on each side of its surface (interiors are seen from both sides), rays leave
in cosine-weighted directions of the hemisphere; the share that leaves the model without
hitting anything is the vertex's sky visibility (1 on an open lawn, near 0 in a closed corner,
in between near a window). A cosine-weighted share is what the diffuse light needs: the sky
light reaching the surface is that share times the unoccluded sky irradiance.

**Aimed at the windows.** Seen from inside, the sky is a small part of the hemisphere: through
a window with blinds the showroom's ceiling sees 0.04 % of it, so of 48 cosine rays most vertices
send none out and one in twenty sends one (2 %, fifty times the true share): blotches of sky light
that the interpolation draws as polygons. Half of each side's rays are therefore aimed at the
room's openings, the sky's portal that the daylight photons use (``app.daylight_photons
.find_portal``: cells of the bounding box that rays from inside leave through), and the two sets
are combined by multiple importance sampling (Veach and Guibas 1995, the balance heuristic): an
escaping ray of either set counts ``cos / (n_c cos + n_p pi p_portal)``, with ``p_portal`` the
solid-angle density of a uniform point on the portal's cells in that direction (0 through a cell
that is not in it). A window that the portal missed (a room the spawn does not see) is still
found by the cosine rays, as before.

**Spread in space.** Each side's value is the Gaussian-weighted mean of the samples near it that
face its way (``_spread``): the rays' noise goes, the fall-off from a window (tens of centimetres
and more) stays, and it does not depend on how the surface was cut into triangles. A vertex
behind a painting, under a cabinet pushed against the wall or inside a light fixture sees no
sky, and nobody sees it; interpolated towards its visible neighbours it would draw the painting's
shadow as a polygon half a metre wide around it. A sample whose rays mostly end within
``COVER_M`` (``COVERED_SHARE``) is covered and weighs nothing, so it takes its uncovered
neighbours' light.

The work is capped (``max_rays``): a big interior samples a subset of its vertices' sides,
each with a chance in proportion to its surface (the walls, floor and ceiling keep all theirs),
and the spread gives the others their value. The bake runs once per scene, on a background
thread (``app.sky_field.VisibilityBake``, with the share by place), and the renderer uploads the
result when it is ready; rays are cast through :class:`app.raycast.RayCaster` (embree).
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable

import numpy as np
from scipy.spatial import cKDTree

from app.ao_bake import sample_points
from app.daylight_photons import Portal, find_portal, scene_box
from app.raycast import RayCaster
from app.scene import Scene

log = logging.getLogger(__name__)
RAYS_PER_SIDE = 48
MAX_RAYS_PER_SIDE = 256  # where the budget allows every side more (sky_visibility)
MAX_RAYS = 2_000_000  # about 3 to 10 s of embree on one core
CHUNK_RAYS = 16384  # rays per embree call: short holds of the interpreter lock
OFFSET_M = 2e-3  # rays start this far off the surface (no self-hits)
NORMAL_WEIGHT_M = 0.25  # nearest-vertex match: a flipped normal counts as 0.5 m away
NEAREST_K, FACING_DEG = 16, 45.0  # ... and of the 16 nearest, the first facing the same way
#: Each side's value is the mean of the samples near it (``_spread``): the SPREAD_K nearest
#: within SPREAD_RADIUS_M, weighed by a Gaussian of SPREAD_SIGMA_M along the surface (the
#: light through a window changes over half a metre and more; 48 rays leave a vertex's
#: share 30-50 % off where little sky is seen) and of SPREAD_NORMAL_M across it (the floor
#: under a coffee table and the table's top, both facing up, are not mixed).
SPREAD_K, SPREAD_SIGMA_M, SPREAD_RADIUS_M, SPREAD_NORMAL_M = 32, 0.25, 0.6, 0.05
FILL_K = 4  # the samples a side that was not sampled takes its value from (_spread)
#: A vertex's rays start this far (at most) towards the centre of its triangles.
INSET_M = 0.02
#: The share of a side's rays aimed at the sky's portal, when the room has one.
PORTAL_SHARE = 0.5
#: A side is covered (behind a painting, under a cabinet) when this share of its cosine rays
#: ends within COVER_M of it; it weighs nothing in ``_spread`` (its neighbours' value).
COVER_M = 0.08
COVERED_SHARE = 0.8


def cosine_directions(normals: np.ndarray, count: int, rng: np.random.Generator) -> np.ndarray:
    """``count`` cosine-weighted unit directions around each normal: (V, count, 3). The
    directions are a stratified (Hammersley) set, turned by a random angle per vertex: far less
    noise than independent random rays for the same count."""
    n = normals.reshape(-1, 3)
    k = np.arange(count)
    radical = np.array([int(f"{i:032b}"[::-1], 2) for i in k], np.float64) / 2.0**32
    u1 = np.broadcast_to((k + 0.5) / count, (n.shape[0], count))
    u2 = (radical[None, :] + rng.random((n.shape[0], 1))) % 1.0
    r, phi = np.sqrt(u1), 2.0 * math.pi * u2
    local = np.stack([r * np.cos(phi), r * np.sin(phi), np.sqrt(np.maximum(0.0, 1.0 - u1))], -1)
    # An orthonormal frame per normal (Duff et al. 2017, "Building an Orthonormal Basis").
    sign = np.where(n[:, 2] >= 0.0, 1.0, -1.0)
    a = -1.0 / (sign + n[:, 2])
    b = n[:, 0] * n[:, 1] * a
    t = np.stack([1.0 + sign * n[:, 0] ** 2 * a, sign * b, -sign * n[:, 0]], -1)
    bt = np.stack([b, sign + n[:, 1] ** 2 * a, -n[:, 1]], -1)
    return (
        local[..., 0:1] * t[:, None, :]
        + local[..., 1:2] * bt[:, None, :]
        + local[..., 2:3] * n[:, None, :]
    )


def lets_light_through(scene: Scene) -> np.ndarray:
    """Per mesh, whether it casts no shadow in the renderer (render/shadows.py ``casts``): a
    glowing pane that shows the sky beyond a window, a lamp's bulb, blended glass."""
    out = np.zeros(len(scene.meshes), bool)
    for i, m in enumerate(scene.meshes):
        if 0 <= m.material < len(scene.materials):
            mat = scene.materials[m.material]
            out[i] = any(mat.emissive) or mat.alpha_mode == "BLEND"
    return out


def occluders(scene: Scene) -> np.ndarray:
    """The triangles that hide the sky, (T, 3, 3) float32: every mesh but those that let the
    sky's light through (:func:`lets_light_through`)."""
    clear = lets_light_through(scene)
    parts = [
        np.asarray(m.positions)[np.asarray(m.indices, np.int64)]
        for m, through in zip(scene.meshes, clear)
        if not through
    ]
    if not parts:
        return np.zeros((0, 3, 3), np.float32)
    return np.concatenate(parts).astype(np.float32)


def sky_visibility(
    scene: Scene,
    caster: RayCaster | None = None,
    rays: int | None = None,
    max_rays: int = MAX_RAYS,
    seed: int = 0,
    cancelled: Callable[[], bool] | None = None,
) -> list[np.ndarray] | None:
    """Per mesh, an (N, 2) float32 array: the share of the sky each vertex sees on the side
    its normal points to and on the other side. None when ``cancelled()`` turned true.

    ``rays`` per side; None: ``RAYS_PER_SIDE``, or as many more as ``max_rays`` allows every
    side (at most ``MAX_RAYS_PER_SIDE``: a small model, the showroom's 17k sides, gets 118
    rather than 48, and through the blinds its walls' light is less patchy)."""
    rng = np.random.default_rng(seed)
    if not scene.meshes:
        return []
    tri = occluders(scene)
    if caster is None:  # its own: embree builds a shared one lazily, not safely from two threads
        caster = RayCaster(tri)
    pos = np.concatenate([_inside_points(m.positions, m.indices) for m in scene.meshes])
    nrm = np.concatenate([m.normals for m in scene.meshes]).astype(np.float64)
    length = np.linalg.norm(nrm, axis=1, keepdims=True)
    nrm = np.where(length > 1e-9, nrm / np.maximum(length, 1e-9), [0.0, 1.0, 0.0])
    total = pos.shape[0]
    # Both sides of every vertex: rows 0..V-1 front, V..2V-1 back.
    side_pos = np.concatenate([pos + nrm * OFFSET_M, pos - nrm * OFFSET_M])
    side_nrm = np.concatenate([nrm, -nrm])
    wanted = side_pos.shape[0]
    if rays is None:
        rays = int(np.clip(max_rays // max(wanted, 1), RAYS_PER_SIDE, MAX_RAYS_PER_SIDE))
    portal = sky_portal(scene, caster, tri, seed) if rays >= 2 else None
    n_portal = int(round(rays * PORTAL_SHARE)) if portal is not None else 0
    n_cos = max(1, rays - n_portal)
    per_side = n_cos + n_portal
    budget = max(1, max_rays // per_side)
    if wanted <= budget:
        sampled = np.arange(wanted)
    else:
        area = np.concatenate([vertex_areas(m.positions, m.indices) for m in scene.meshes])
        sampled = _by_area(np.concatenate([area, area]), budget, rng)
    seen = np.zeros(sampled.shape[0], np.float32)
    covered = np.zeros(sampled.shape[0], bool)
    per_chunk = max(1, CHUNK_RAYS // per_side)
    for start in range(0, sampled.shape[0], per_chunk):
        if cancelled is not None and cancelled():
            return None
        rows = sampled[start : start + per_chunk]
        share, shut_in, _ = seen_share(
            caster, side_pos[rows], side_nrm[rows], n_cos, n_portal, portal, rng
        )
        seen[start : start + len(rows)] = share
        covered[start : start + len(rows)] = shut_in
    values = _spread(side_pos, side_nrm, sampled, np.clip(seen, 0.0, 1.0), covered)
    out_meshes, offset = [], 0
    for m in scene.meshes:
        n = m.positions.shape[0]
        front, back = values[offset : offset + n], values[total + offset : total + offset + n]
        out_meshes.append(np.ascontiguousarray(np.stack([front, back], axis=1)))
        offset += n
    return out_meshes


def _spread(
    pos: np.ndarray, nrm: np.ndarray, sampled: np.ndarray, seen: np.ndarray, covered: np.ndarray
) -> np.ndarray:
    """Every side's value, (len(pos),) float32: the mean of the uncovered samples (``sampled``,
    their ``seen`` share) among its ``SPREAD_K`` nearest that face its way (normals within
    ``FACING_DEG``) and lie within ``SPREAD_RADIUS_M``, weighed by a Gaussian of the distance
    along the side's surface (``SPREAD_SIGMA_M``) and one across it (``SPREAD_NORMAL_M``);
    where there is none, the nearest facing sample's. The sides that were not sampled (a real
    room's furniture, whose vertices are small) take the same mean over the ``FILL_K`` nearest
    samples' spread values: a twelfth of the neighbours for most of the sides.

    A filter in space, not along the mesh: a real room's wall of long thin triangles and fans
    has most vertices unsampled, each took its nearest sample's value (a patchwork of Voronoi
    cells, one noisy value each), and two rings of mesh smoothing did not reach across them.
    A covered sample (behind a painting) weighs nothing, so the wall behind a painting takes
    the light of the wall around it."""
    out = np.full(len(pos), np.nan)
    use = sampled[~covered]
    if len(use):
        tree = cKDTree(np.hstack([pos[use], nrm[use] * NORMAL_WEIGHT_M]))
        vals = seen[~covered].astype(np.float64)
        smooth = _weighed(tree, pos, nrm, use, vals, sampled, SPREAD_K)
        got = np.isfinite(smooth)
        out[sampled[got]] = smooth[got]
        rest = np.setdiff1d(np.arange(len(pos)), sampled[got], assume_unique=True)
        if len(rest):
            good = sampled[got]
            tree = cKDTree(np.hstack([pos[good], nrm[good] * NORMAL_WEIGHT_M]))
            out[rest] = _weighed(tree, pos, nrm, good, smooth[got], rest, FILL_K)
    lost = np.flatnonzero(~np.isfinite(out))
    if len(lost):  # nothing uncovered near: the nearest sample facing its way
        out[lost] = seen[_nearest_facing(pos, nrm, sampled, lost)]
    return out.astype(np.float32)


def _weighed(
    tree: cKDTree,
    pos: np.ndarray,
    nrm: np.ndarray,
    src: np.ndarray,
    vals: np.ndarray,
    rows_all: np.ndarray,
    k: int,
) -> np.ndarray:
    """For the sides ``rows_all``, the weighed mean (``_spread``) of ``vals`` at the sides
    ``src`` (the tree's points) among their ``k`` nearest; NaN where none counts."""
    out = np.full(len(rows_all), np.nan)
    k = min(k, len(src))
    least = math.cos(math.radians(FACING_DEG))
    src_pos, src_nrm = pos[src], nrm[src]
    for start in range(0, len(rows_all), 1 << 15):
        part = np.arange(start, min(start + (1 << 15), len(rows_all)))
        rows = rows_all[part]
        _, idx = tree.query(np.hstack([pos[rows], nrm[rows] * NORMAL_WEIGHT_M]), k=k)
        idx = idx.reshape(len(rows), k)
        delta = src_pos[idx] - pos[rows][:, None, :]
        d2 = np.einsum("rkj,rkj->rk", delta, delta)
        off = np.einsum("rkj,rj->rk", delta, nrm[rows])  # along the normal: another surface
        facing = np.einsum("rj,rkj->rk", nrm[rows], src_nrm[idx])
        w = np.exp(-0.5 * np.maximum(d2 - off**2, 0.0) / SPREAD_SIGMA_M**2)
        w *= np.exp(-0.5 * (off / SPREAD_NORMAL_M) ** 2)
        w *= (facing >= least) & (d2 <= SPREAD_RADIUS_M**2)
        total = w.sum(axis=1)
        got = total > 0.0
        out[part[got]] = (w[got] * vals[idx[got]]).sum(axis=1) / total[got]
    return out


def vertex_areas(positions: np.ndarray, indices: np.ndarray) -> np.ndarray:
    """Each vertex's share of the surface: a third of its triangles' areas, (N,)."""
    pos = np.asarray(positions, np.float64).reshape(-1, 3)
    tri = np.asarray(indices, np.int64).reshape(-1, 3)
    out = np.zeros(pos.shape[0])
    if tri.size == 0:
        return out
    area = 0.5 * np.linalg.norm(
        np.cross(pos[tri[:, 1]] - pos[tri[:, 0]], pos[tri[:, 2]] - pos[tri[:, 0]]), axis=1
    )
    area = np.where(np.isfinite(area), area, 0.0)
    for k in range(3):
        np.add.at(out, tri[:, k], area / 3.0)
    return out


def _by_area(area: np.ndarray, budget: int, rng: np.random.Generator) -> np.ndarray:
    """About ``budget`` of the sides, each kept with a chance in proportion to its surface
    (at most 1): the walls, floor and ceiling a viewer sees, drawn by few large triangles,
    are all kept; a tap's thousand tiny vertices share a few samples and take their value
    from them (``_spread``). Random sides, a twentieth of a real room's, left a wall's few
    vertices to the nearest sample a metre away: blotches of one value each."""
    a = np.maximum(area, 0.0)
    total = float(a.sum())
    if total <= 0.0:
        return np.sort(rng.choice(len(a), budget, False))
    lo, hi = 0.0, budget / total
    while np.minimum(1.0, a * hi).sum() < budget:  # grow the scale until the budget is met
        hi *= 2.0
    for _ in range(40):  # then halve the interval: sum(min(1, c a)) = budget
        mid = 0.5 * (lo + hi)
        if np.minimum(1.0, a * mid).sum() < budget:
            lo = mid
        else:
            hi = mid
    keep = rng.random(len(a)) < np.minimum(1.0, a * hi)
    return np.flatnonzero(keep)


def _nearest_facing(
    pos: np.ndarray, nrm: np.ndarray, sampled: np.ndarray, rest: np.ndarray
) -> np.ndarray:
    """For each side in ``rest``, the index into ``sampled`` of the nearest sampled side that
    faces the same way (normals within ``FACING_DEG``; else the nearest of the
    ``NEAREST_K`` that faces it most). The other side of the same wall is 4 mm away and sees
    the whole sky: weighed by distance and normal together it was taken where a big ceiling's
    samples were sparse, a vertex of the ceiling saw the whole sky and its triangles lit
    up."""
    tree = cKDTree(np.hstack([pos[sampled], nrm[sampled] * NORMAL_WEIGHT_M]))
    query = np.hstack([pos[rest], nrm[rest] * NORMAL_WEIGHT_M])
    _, out = tree.query(query)
    least = math.cos(math.radians(FACING_DEG))
    odd = np.flatnonzero(np.einsum("rj,rj->r", nrm[rest], nrm[sampled][out]) < least)
    k = min(NEAREST_K, len(sampled))
    if len(odd) and k > 1:  # the few whose nearest faces away: look further
        _, near = tree.query(query[odd], k=k)
        facing = np.einsum("rj,rkj->rk", nrm[rest][odd], nrm[sampled][near])
        good = facing >= least
        first = np.where(good.any(axis=1), good.argmax(axis=1), facing.argmax(axis=1))
        out[odd] = near[np.arange(len(odd)), first]
    return out


def _inside_points(positions: np.ndarray, indices: np.ndarray) -> np.ndarray:
    """Each vertex moved towards the centre of its triangles (as the AO bake's
    ``sample_points``), by at most ``INSET_M``: the value is spread across the vertex's
    triangles, so it should be the light of the surface there. At a corner or along a wall's
    foot the wall cuts off half the sky right at the vertex (a floor vertex at a wall saw 0 %
    of the window, 2 cm in 1.9 %); without the inset the living room's daylit FLIP was 0.254
    instead of 0.243 and the noise test's error ratio 0.55."""
    pos = np.asarray(positions, np.float64).reshape(-1, 3)
    move = sample_points(pos, indices) - pos
    length = np.linalg.norm(move, axis=1, keepdims=True)
    scale = np.minimum(1.0, INSET_M / np.maximum(length, 1e-12))
    return pos + move * scale


def seen_share(
    caster: RayCaster,
    o: np.ndarray,
    n: np.ndarray,
    n_cos: int,
    n_portal: int,
    portal: Portal | None,
    rng: np.random.Generator,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The share of the sky seen from points ``o`` facing ``n`` (k,), by ``n_cos`` cosine
    rays and ``n_portal`` rays aimed at the portal, weighed by the balance heuristic; whether
    each point is covered (its cosine rays end within COVER_M), (k,) bool; and the share of
    each point's escaping cosine rays that left through the portal, (k,) (1 where none
    escaped or there is no portal; 0 for a point outside the portal's box: a model's outside).
    """
    k = o.shape[0]
    dirs = cosine_directions(n, n_cos, rng)
    if portal is not None and n_portal:
        aim = portal.sample_open(rng, k * n_portal).reshape(k, n_portal, 3) - o[:, None, :]
        aim /= np.maximum(np.linalg.norm(aim, axis=2, keepdims=True), 1e-12)
        dirs = np.concatenate([dirs, aim], axis=1)
    per_side = dirs.shape[1]
    origins = np.repeat(o, per_side, axis=0)
    flat = dirs.reshape(-1, 3)
    dist, _ = caster.cast_triangles(origins, flat)
    dist = dist.reshape(k, per_side)
    covered = (dist[:, :n_cos] < COVER_M).mean(axis=1) >= COVERED_SHARE
    cos = np.einsum("kj,kij->ki", n, dirs)
    out = np.isinf(dist) & (cos > 0.0)
    if portal is None:
        return out.mean(axis=1), covered, np.ones(k)
    inside = np.all((o > portal.lo) & (o < portal.hi), axis=1)
    out[~inside, n_cos:] = False  # outside the box: the cosine rays alone
    pdf = np.zeros((k, per_side))
    esc = out & inside[:, None]
    pdf[esc] = portal.open_density(origins[esc.ravel()], flat[esc.ravel()])
    escaped = out[:, :n_cos].sum(axis=1)
    left = (pdf[:, :n_cos] > 0.0).sum(axis=1)  # through_portal, its density already found
    through = np.where(escaped > 0, left / np.maximum(escaped, 1), 1.0)
    if not n_portal:
        return out.mean(axis=1), covered, through
    n_p = np.where(inside, n_portal, 0)[:, None]
    with np.errstate(divide="ignore", invalid="ignore"):
        share = cos / (n_cos * cos + n_p * math.pi * pdf)
    return np.where(out, share, 0.0).sum(axis=1), covered, through


def sky_portal(scene: Scene, caster: RayCaster, tri: np.ndarray, seed: int) -> Portal | None:
    """The sky's portal seen from the spawn, or None (a closed room, the spawn outside the
    model, no geometry)."""
    return portal_from(caster, scene_box(tri), scene.spawn.position, seed)


def portal_from(
    caster: RayCaster, box: tuple[np.ndarray, np.ndarray] | None, spawn, seed: int
) -> Portal | None:
    """:func:`sky_portal` for the triangles' ``box`` (``scene_box``) and the spawn's place."""
    if box is None:
        return None
    portal = find_portal(caster, box, np.asarray(spawn, np.float64), seed)
    if not portal.inside or not portal.open.any() or portal.total_area <= 0.0:
        return None
    return portal


def through_portal(portal: Portal | None, o: np.ndarray, d: np.ndarray) -> np.ndarray:
    """Whether rays from ``o`` along unit ``d`` that left the model leave it through the
    room's windows (the sky's portal), (k,) bool: all of them without a portal, none from
    outside its box (a model's outside). A ray that leaves elsewhere went out through a gap
    in the model: under a floor that stops short of its walls, it sees the ground."""
    if portal is None:
        return np.ones(len(o), bool)
    out = np.zeros(len(o), bool)
    inside = np.flatnonzero(np.all((o > portal.lo) & (o < portal.hi), axis=1))
    if len(inside):
        out[inside] = portal.open_density(o[inside], d[inside]) > 0.0
    return out
