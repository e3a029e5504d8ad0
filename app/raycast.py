"""Ray casting against a triangle soup, for spawning, walking collision and the gazed object.

Embree (through ``embreex``) answers a batch of rays in microseconds; where it is
unavailable a vectorised numpy Möller-Trumbore over every triangle gives the same answers, slower.
"""

from __future__ import annotations

import copy
import logging
import math
from typing import Any

import numpy as np

log = logging.getLogger(__name__)


class RayCaster:
    def __init__(self, triangles: np.ndarray, owners: np.ndarray | None = None) -> None:
        tri = np.asarray(triangles).reshape(-1, 3, 3)
        finite = np.isfinite(tri).all(axis=(1, 2))
        # float32 as the scene holds it (re-centred by app.placement, so precise enough);
        # :attr:`tri` gives float64 to the callers that do geometry with it.
        self._tri32 = np.ascontiguousarray(tri[finite], np.float32)
        self._tri64: np.ndarray | None = None
        # Index of each kept triangle in the input: callers map cast_triangles() answers back.
        self.source_index = np.flatnonzero(finite)
        self._dropped = int(tri.shape[0] - self.source_index.shape[0])
        self.owner = (
            np.asarray(owners)[finite] if owners is not None else np.arange(self._tri32.shape[0])
        )
        self._embree: Any = None
        if self._tri32.shape[0]:
            try:
                from embreex import rtcore_scene
                from embreex.mesh_construction import TriangleMesh

                # A triangle soup straight to embree: no trimesh mesh (its float64 vertices
                # and int64 faces), and embree builds a soup about twice as fast as an
                # indexed mesh. The hierarchy itself is built on the first query.
                self._embree = rtcore_scene.EmbreeScene()
                TriangleMesh(self._embree, self._tri32)
            except Exception as exc:  # noqa: BLE001 - any import/build failure: use numpy
                self._embree = None
                log.info("embree unavailable (%s); using numpy ray casting", exc)

    @property
    def tri(self) -> np.ndarray:
        """The kept triangles, (T, 3, 3) float64."""
        if self._tri64 is None:
            self._tri64 = self._tri32.astype(np.float64)
        return self._tri64

    def with_owners(self, owners: np.ndarray) -> RayCaster:
        """The same built caster answering with other owner ids (one per input triangle):
        building embree's hierarchy takes seconds for a million triangles, so the load's caster
        (owners: triangle indices) serves the session (owners: mesh indices) too."""
        owners = np.asarray(owners)
        if owners.shape[0] != self.source_index.shape[0] + self._dropped:
            raise ValueError("one owner per input triangle is needed")
        twin = copy.copy(self)
        twin.owner = owners[self.source_index]
        return twin

    def cast_many(
        self, origins, directions, t_max: float = math.inf
    ) -> tuple[np.ndarray, np.ndarray]:
        """Distances (inf on a miss) and owner ids (-1 on a miss) for each ray."""
        dist, tri = self.cast_triangles(origins, directions, t_max)
        who = np.where(tri >= 0, self.owner[np.maximum(tri, 0)] if len(self.owner) else -1, -1)
        return dist, who.astype(np.int64)

    def cast_triangles(
        self, origins, directions, t_max: float = math.inf
    ) -> tuple[np.ndarray, np.ndarray]:
        """Distances (inf on a miss) and hit triangle indices into ``self.tri`` (-1 on a miss).

        One batched call for many rays (photon tracing); ``self.source_index`` maps a triangle
        index back to the input array, whose non-finite triangles were dropped.
        """
        o = np.asarray(origins, np.float64).reshape(-1, 3)
        d = np.asarray(directions, np.float64).reshape(-1, 3)
        n = o.shape[0]
        dist = np.full(n, np.inf)
        tri = np.full(n, -1, np.int64)
        norm = np.linalg.norm(d, axis=1)
        valid = np.isfinite(o).all(axis=1) & np.isfinite(d).all(axis=1) & (norm > 1e-12)
        valid &= np.abs(o).max(axis=1, initial=0.0) < 1e15
        if not valid.any() or self._tri32.shape[0] == 0:
            return dist, tri
        idx = np.flatnonzero(valid)
        ov, dv = o[idx], d[idx] / norm[idx, None]
        if self._embree is not None:
            # One embree query for the batch, no per-hit location refinement.
            res = self._embree.run(
                np.ascontiguousarray(ov, np.float32), np.ascontiguousarray(dv, np.float32), output=1
            )
            prim = np.asarray(res["primID"], np.int64)
            t = np.asarray(res["tfar"], np.float64)
            hit = (prim >= 0) & (prim < self._tri32.shape[0]) & np.isfinite(t) & (t >= 0.0)
            dist[idx[hit]] = t[hit]
            tri[idx[hit]] = prim[hit]
        else:
            v0 = self.tri[:, 0]
            e1 = self.tri[:, 1] - v0
            e2 = self.tri[:, 2] - v0
            for k, i in enumerate(idx):
                t = _intersect(ov[k], dv[k], v0, e1, e2)
                j = int(np.argmin(t))
                if math.isfinite(t[j]):
                    dist[i], tri[i] = t[j], j
        far = dist > t_max
        dist[far], tri[far] = np.inf, -1
        return dist, tri

    def cast(self, origin, direction, t_max: float = math.inf) -> tuple[float, int]:
        """Nearest hit distance along the ray and the owner id, or (inf, -1)."""
        dist, who = self.cast_many([origin], [direction], t_max)
        return float(dist[0]), int(who[0])


def _intersect(
    o: np.ndarray, d: np.ndarray, v0: np.ndarray, e1: np.ndarray, e2: np.ndarray
) -> np.ndarray:
    """Möller-Trumbore for one ray against many triangles; inf where there is no hit."""
    p = np.cross(d[None, :], e2)
    det = np.einsum("ij,ij->i", e1, p)
    ok = np.abs(det) > 1e-14
    inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)
    s = o[None, :] - v0
    u = np.einsum("ij,ij->i", s, p) * inv
    q = np.cross(s, e1)
    v = (q @ d) * inv
    t = np.einsum("ij,ij->i", e2, q) * inv
    hit = ok & (u >= 0) & (v >= 0) & (u + v <= 1) & (t > 1e-6)
    return np.where(hit, t, np.inf)
