"""How much of the sky each vertex sees: the room's occlusion of the sky light, baked with rays.

From each vertex, on each side of its surface (interiors are seen from both sides), rays leave
in cosine-weighted directions of the hemisphere; the share that leaves the model without
hitting anything is the vertex's sky visibility (1 on an open lawn, near 0 in a closed corner,
in between near a window). A cosine-weighted share is what the diffuse light needs: the sky
light reaching the surface is that share times the unoccluded sky irradiance.

The work is capped (``max_rays``): a big interior samples a subset of its vertices, the others
take the value of the nearest sampled vertex facing the same way. The bake runs once per
scene, on a background thread (:class:`VisibilityBake`), and the renderer uploads the result
when it is ready; rays are cast through :class:`app.raycast.RayCaster` (embree).
"""

from __future__ import annotations

import logging
import math
import threading
from collections.abc import Callable

import numpy as np
from scipy.sparse import coo_matrix, identity
from scipy.spatial import cKDTree

from app.raycast import RayCaster
from app.scene import Scene

log = logging.getLogger(__name__)
RAYS_PER_SIDE = 48
SMOOTH_ROUNDS = 2
MAX_RAYS = 2_000_000  # about 3 to 10 s of embree on one core
CHUNK_RAYS = 16384  # rays per embree call: short holds of the interpreter lock
OFFSET_M = 2e-3  # rays start this far off the surface (no self-hits)
NORMAL_WEIGHT_M = 0.25  # nearest-vertex match: a flipped normal counts as 0.5 m away


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


def smooth(values: np.ndarray, indices: np.ndarray, rounds: int = SMOOTH_ROUNDS) -> np.ndarray:
    """Average each vertex with its mesh neighbours ``rounds`` times: the rays' remaining noise
    goes, the fall-off from a window (metres wide) stays."""
    n = values.shape[0]
    tri = np.asarray(indices, np.int64).reshape(-1, 3)
    if n == 0 or tri.size == 0:
        return values
    rows = np.concatenate([tri[:, 0], tri[:, 1], tri[:, 2], tri[:, 1], tri[:, 2], tri[:, 0]])
    cols = np.concatenate([tri[:, 1], tri[:, 2], tri[:, 0], tri[:, 0], tri[:, 1], tri[:, 2]])
    adj = coo_matrix((np.ones(rows.shape[0]), (rows, cols)), shape=(n, n)).tocsr()
    adj.data[:] = 1.0
    adj = adj + identity(n, format="csr")
    weight = np.asarray(adj.sum(axis=1)).ravel()
    out = values.astype(np.float64)
    for _ in range(rounds):
        out = (adj @ out) / weight[:, None]
    return out.astype(np.float32)


def occluders(scene: Scene) -> np.ndarray:
    """The triangles that hide the sky, (T, 3, 3) float32: every mesh but those that cast no
    shadow in the renderer (render/shadows.py ``casts``): a glowing pane that shows the sky
    beyond a window, a lamp's bulb, and blended glass let the sky's light through."""
    parts = []
    for m in scene.meshes:
        mat = scene.materials[m.material] if 0 <= m.material < len(scene.materials) else None
        if mat is not None and (any(mat.emissive) or mat.alpha_mode == "BLEND"):
            continue
        parts.append(np.asarray(m.positions)[np.asarray(m.indices, np.int64)])
    if not parts:
        return np.zeros((0, 3, 3), np.float32)
    return np.concatenate(parts).astype(np.float32)


def sky_visibility(
    scene: Scene,
    caster: RayCaster | None = None,
    rays: int = RAYS_PER_SIDE,
    max_rays: int = MAX_RAYS,
    seed: int = 0,
    cancelled: Callable[[], bool] | None = None,
) -> list[np.ndarray] | None:
    """Per mesh, an (N, 2) float32 array: the share of the sky each vertex sees on the side
    its normal points to and on the other side. None when ``cancelled()`` turned true."""
    rng = np.random.default_rng(seed)
    if caster is None:  # its own: embree builds a shared one lazily, not safely from two threads
        caster = RayCaster(occluders(scene))
    if not scene.meshes:
        return []
    pos = np.concatenate([m.positions for m in scene.meshes]).astype(np.float64)
    nrm = np.concatenate([m.normals for m in scene.meshes]).astype(np.float64)
    length = np.linalg.norm(nrm, axis=1, keepdims=True)
    nrm = np.where(length > 1e-9, nrm / np.maximum(length, 1e-9), [0.0, 1.0, 0.0])
    total = pos.shape[0]
    # Both sides of every vertex: rows 0..V-1 front, V..2V-1 back.
    side_pos = np.concatenate([pos + nrm * OFFSET_M, pos - nrm * OFFSET_M])
    side_nrm = np.concatenate([nrm, -nrm])
    wanted = side_pos.shape[0]
    budget = max(1, max_rays // max(1, rays))
    sampled = np.arange(wanted) if wanted <= budget else np.sort(rng.choice(wanted, budget, False))
    seen = np.zeros(sampled.shape[0], np.float32)
    per_chunk = max(1, CHUNK_RAYS // rays)
    for start in range(0, sampled.shape[0], per_chunk):
        if cancelled is not None and cancelled():
            return None
        rows = sampled[start : start + per_chunk]
        dirs = cosine_directions(side_nrm[rows], rays, rng)
        origins = np.repeat(side_pos[rows], rays, axis=0)
        dist, _ = caster.cast_triangles(origins, dirs.reshape(-1, 3))
        seen[start : start + rows.shape[0]] = (
            np.isinf(dist).reshape(rows.shape[0], rays).mean(axis=1)
        )
    values = np.empty(wanted, np.float32)
    values[sampled] = seen
    if sampled.shape[0] < wanted:
        rest = np.setdiff1d(np.arange(wanted), sampled, assume_unique=True)
        tree = cKDTree(np.hstack([side_pos[sampled], side_nrm[sampled] * NORMAL_WEIGHT_M]))
        _, nearest = tree.query(np.hstack([side_pos[rest], side_nrm[rest] * NORMAL_WEIGHT_M]))
        values[rest] = seen[nearest]
    both = np.stack([values[:total], values[total:]], axis=1)
    out, offset = [], 0
    for m in scene.meshes:
        n = m.positions.shape[0]
        out.append(np.ascontiguousarray(smooth(both[offset : offset + n], m.indices)))
        offset += n
    return out


class VisibilityBake:
    """:func:`sky_visibility` for one scene on a background thread; ``result`` when done."""

    def __init__(self, scene: Scene, **options) -> None:
        self.scene = scene
        self.result: list[np.ndarray] | None = None
        self.error: str | None = None
        self._cancel = threading.Event()
        self._done = threading.Event()
        self._thread = threading.Thread(
            target=self._run, kwargs=options, name="sky-visibility", daemon=True
        )
        self._thread.start()

    def _run(self, **options) -> None:
        try:
            self.result = sky_visibility(self.scene, cancelled=self._cancel.is_set, **options)
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
