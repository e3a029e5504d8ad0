"""Ambient occlusion baked per vertex with embree (``app.raycast.RayCaster``).

Each vertex casts cosine-weighted rays over the hemisphere of its normal, up to ``radius_m``;
its occlusion is the share of rays that reach open space (1: nothing nearby, 0: buried). With
cosine-weighted directions that share is the cosine-weighted visibility the ambient term needs.
Interiors are drawn from both sides (a room's shell often has its normals facing out), so each
vertex gets two values, ``Mesh.ao[:, 0]`` over its normal and ``[:, 1]`` behind it; the
renderer picks the side it sees.

Per-vertex values can only be as fine as the mesh: a floor made of two triangles has its four
vertices in the room's corners, and casting from the corners would darken the whole floor. So
each vertex casts from halfway towards the centre of the triangles around it: on a fine mesh
that is a few centimetres, on a coarse one it lands in the open and the surface stays bright
(coarse meshes get no corner shading from the bake; the screen method has no such limit).

The bake runs when first needed, in a worker thread (:class:`BackgroundBake`); the
renderer uploads it when it is ready. The cost is capped: vertices at the same place with the
same normal (a triangle soup repeats each corner several times) are cast once, and a ray
budget lowers the rays per vertex on huge interiors (at least ``MIN_RAYS``). The directions
come from a fixed seed, so a bake is deterministic. Degenerate input (NaN vertices,
zero-length normals, empty meshes) gives 1.
"""

from __future__ import annotations

import logging
import threading
import time
from dataclasses import dataclass, replace

import numpy as np

from app.raycast import RayCaster
from app.scene import Scene

log = logging.getLogger(__name__)

RAYS = 16  # per vertex, when the budget allows
MIN_RAYS = 4
RAY_BUDGET = 3_000_000  # rays per bake, both sides: about 2 s of embree on two quiet cores
BATCH = 250_000  # rays per embree call: bounds the arrays and how long one holds the GIL
SEED = 14
OFFSET_M = 2e-3  # ray origins leave the surface by this much (no self-hits)
# How far an occluder still counts: the screen method's default reach (render.ao_radius_m).
# Against Cycles (docs/reference_flip.md, stop 40) 0.3 m was closer than 0.75 m on every
# lamp-lit view (by 0.0003-0.0010): the even light by place already darkens a room's far
# corners, the bake only needs the contact shadows it cannot see.
RADIUS_M = 0.3


@dataclass
class BakeReport:
    vertices: int  # vertices of the scene
    cast: int  # distinct vertices cast from
    rays_per_vertex: int  # per side
    seconds: float


def hemisphere_pattern(n: int, seed: int = SEED) -> np.ndarray:
    """``n`` cosine-weighted directions around +Z: a Fibonacci spiral on the unit disk (one
    sample per ring of equal area, jittered with a fixed seed) lifted to the hemisphere."""
    rng = np.random.default_rng(seed)
    i = np.arange(n) + rng.random(n)  # one sample per stratum of the disk's area
    r = np.sqrt(i / n)
    phi = np.arange(n) * (np.pi * (3.0 - np.sqrt(5.0)))  # golden angle
    x, y = r * np.cos(phi), r * np.sin(phi)
    z = np.sqrt(np.maximum(0.0, 1.0 - x * x - y * y))
    return np.stack([x, y, z], axis=1)


def _frames(normals: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit tangents per unit normal (Frisvad's branchless basis, Duff et al. 2017)."""
    nx, ny, nz = normals[:, 0], normals[:, 1], normals[:, 2]
    sign = np.where(nz >= 0.0, 1.0, -1.0)
    a = -1.0 / (sign + nz)
    b = nx * ny * a
    t = np.stack([1.0 + sign * nx * nx * a, sign * b, -sign * nx], axis=1)
    bt = np.stack([b, sign + ny * ny * a, -ny], axis=1)
    return t, bt


def vertex_occlusion(
    positions: np.ndarray,
    normals: np.ndarray,
    caster: RayCaster,
    radius_m: float = RADIUS_M,
    rays: int = RAYS,
    seed: int = SEED,
) -> np.ndarray:
    """Occlusion in [0, 1] (1: open) for each (position, normal), float32."""
    pos = np.asarray(positions, np.float64).reshape(-1, 3)
    nrm = np.asarray(normals, np.float64).reshape(-1, 3)
    n = pos.shape[0]
    out = np.ones(n, np.float32)
    if n == 0 or rays <= 0 or not np.isfinite(radius_m) or radius_m <= 0.0:
        return out
    length = np.linalg.norm(nrm, axis=1)
    good = np.isfinite(pos).all(axis=1) & np.isfinite(nrm).all(axis=1) & (length > 1e-8)
    idx = np.flatnonzero(good)
    if idx.size == 0:
        return out
    p = pos[idx]
    nn = nrm[idx] / length[idx, None]
    t, bt = _frames(nn)
    pattern = hemisphere_pattern(rays, seed)
    per_batch = max(1, BATCH // rays)
    open_share = np.empty(idx.size, np.float32)
    for start in range(0, idx.size, per_batch):
        sl = slice(start, start + per_batch)
        # (V, R, 3) directions: pattern in each vertex's frame
        d = (
            pattern[None, :, 0:1] * t[sl, None, :]
            + pattern[None, :, 1:2] * bt[sl, None, :]
            + pattern[None, :, 2:3] * nn[sl, None, :]
        )
        o = np.broadcast_to((p[sl] + nn[sl] * OFFSET_M)[:, None, :], d.shape)
        dist, _ = caster.cast_triangles(o.reshape(-1, 3), d.reshape(-1, 3), t_max=radius_m)
        hit = np.isfinite(dist).reshape(-1, rays)
        open_share[sl] = 1.0 - hit.mean(axis=1)
    out[idx] = open_share
    return out


def sample_points(mesh_positions: np.ndarray, indices: np.ndarray) -> np.ndarray:
    """Each vertex moved halfway towards the mean centre of its triangles (float64)."""
    pos = np.asarray(mesh_positions, np.float64).reshape(-1, 3)
    idx = np.asarray(indices, np.int64).reshape(-1, 3)
    n = pos.shape[0]
    ok = np.all((idx >= 0) & (idx < n), axis=1)
    idx = idx[ok]
    if idx.size == 0:
        return pos
    centre = pos[idx].mean(axis=1)
    total = np.zeros_like(pos)
    count = np.zeros(n)
    for k in range(3):
        np.add.at(total, idx[:, k], centre)
        np.add.at(count, idx[:, k], 1.0)
    used = count > 0
    out = pos.copy()
    out[used] = 0.5 * (pos[used] + total[used] / count[used, None])
    return np.where(np.isfinite(out), out, pos)


def bake_scene(
    scene: Scene,
    caster: RayCaster | None = None,
    radius_m: float = RADIUS_M,
    rays: int = RAYS,
    budget: int = RAY_BUDGET,
) -> tuple[Scene, BakeReport]:
    """``scene`` with ``Mesh.ao`` (N, 2) set on every mesh (a copy; the other arrays are
    shared): the occlusion over each vertex's normal and behind it."""
    began = time.perf_counter()
    if caster is None:
        caster = scene.ray_caster or RayCaster(scene.triangles())
    meshes = scene.meshes
    total = sum(int(m.positions.shape[0]) for m in meshes)
    if total == 0:
        return scene, BakeReport(0, 0, 0, 0.0)
    pos = np.concatenate([sample_points(m.positions, m.indices) for m in meshes])
    nrm = np.concatenate([np.asarray(m.normals, np.float32).reshape(-1, 3) for m in meshes])
    # One cast per place and direction: 1 mm positions, normals to about a degree.
    key = np.concatenate(
        [
            np.round(np.nan_to_num(pos, nan=0.0, posinf=0.0, neginf=0.0) * 1000.0),
            np.round(np.nan_to_num(nrm, nan=0.0, posinf=0.0, neginf=0.0) * 64.0),
        ],
        axis=1,
    ).astype(np.int64)
    _, first, inverse = np.unique(key, axis=0, return_index=True, return_inverse=True)
    inverse = inverse.reshape(-1)
    per_vertex = int(np.clip(budget // max(1, 2 * first.size), MIN_RAYS, rays))
    p, n = pos[first], nrm[first]
    sides = [vertex_occlusion(p, s * n, caster, radius_m, per_vertex) for s in (1.0, -1.0)]
    ao = np.stack(sides, axis=1)[inverse]
    # A vertex with bad data was cast as part of a shared key: keep 1 for it.
    bad = ~(np.isfinite(pos).all(axis=1) & np.isfinite(nrm).all(axis=1))
    ao[bad] = 1.0  # both sides
    baked = []
    offset = 0
    for m in meshes:
        count = int(m.positions.shape[0])
        baked.append(replace(m, ao=np.ascontiguousarray(ao[offset : offset + count])))
        offset += count
    report = BakeReport(total, int(first.size), per_vertex, time.perf_counter() - began)
    log.info(
        "%s: ambient occlusion baked for %d vertices (%d cast, %d rays each) in %.2f s",
        scene.name,
        total,
        report.cast,
        per_vertex,
        report.seconds,
    )
    return replace(scene, meshes=baked), report


def ensure_baked(scene: Scene, caster: RayCaster | None = None) -> Scene:
    """``scene`` if every mesh has its occlusion, else a baked copy; never raises (a failed
    bake leaves the meshes without, and the renderer draws them unoccluded)."""
    if all(m.ao is not None for m in scene.meshes):
        return scene
    try:
        return bake_scene(scene, caster)[0]
    except Exception:  # noqa: BLE001 - occlusion is a nicety, never a reason to fail a load
        log.exception("baking ambient occlusion failed for %s", scene.name)
        return scene


class BackgroundBake:
    """:func:`ensure_baked` in a worker thread: the renderer starts one when a scene without
    occlusion is first drawn with the baked method, draws it unoccluded meanwhile, and takes
    ``result`` once ``done`` (so a load never waits for a bake it may not use)."""

    def __init__(self, scene: Scene) -> None:
        self.scene = scene
        self.result: Scene | None = None
        self._finished = threading.Event()
        self._thread = threading.Thread(target=self._run, name="ao-bake", daemon=True)
        self._thread.start()

    def _run(self) -> None:
        try:
            self.result = ensure_baked(self.scene, self.scene.ray_caster)
        finally:
            self._finished.set()

    @property
    def done(self) -> bool:
        return self._finished.is_set()

    def wait(self, timeout: float | None = None) -> bool:
        """Block until the bake is done (tests, benchmarks); whether it is."""
        return self._finished.wait(timeout)
