"""Per-mesh, per-view frustum culling on index-buffer chunks.

A mesh's triangles are drawn as ranges of its index buffer, each with an axis-aligned world
bounding box. A mesh of up to ``CHUNK_TRIANGLES`` triangles is one range, in its own order (so
its picture is the same as an unchunked draw). A bigger one, as real files often hold (a whole
room's walls in one mesh), is split into spatially coherent chunks: its triangles sorted by the
Morton code of their centroids and cut into a power of two of equal ranges of at most
``CHUNK_TRIANGLES``, so a chunk is a compact piece
of the mesh and its box is tight. The mesh keeps its identity (index, material, object id,
TCR level): only the order of its triangles changes.

Each view tests every range's box against the frustum's side and near planes (Gribb and
Hartmann's extraction from the view-projection matrix; the far plane is left out, a box beyond
it costs only its vertices); neighbouring visible ranges are drawn as one call.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

CHUNK_TRIANGLES = 16384  # meshes above this are split into chunks of at most this many


@dataclass
class Chunks:
    """Ranges of one mesh's index buffer: ``first`` and ``count`` in indices (3 a triangle),
    ``lo`` and ``hi`` the (n, 3) world bounds of each."""

    first: np.ndarray
    count: np.ndarray
    lo: np.ndarray
    hi: np.ndarray


def _morton(q: np.ndarray) -> np.ndarray:
    """Interleaved bits of three 10-bit integer coordinates (n, 3) -> (n,) uint32."""
    code = np.zeros(len(q), np.uint32)
    v = q.astype(np.uint32)
    for bit in range(10):
        for axis in range(3):
            code |= ((v[:, axis] >> bit) & 1) << (3 * bit + axis)
    return code


def chunk_mesh(positions: np.ndarray, indices: np.ndarray) -> tuple[np.ndarray, Chunks | None]:
    """The mesh's (M, 3) triangles in drawing order and their chunks (None: no triangles).
    Non-finite positions are left out of the bounds (the sanitized scene has none)."""
    tris = np.asarray(indices, np.int64).reshape(-1, 3)
    pos = np.asarray(positions, np.float64)
    if len(tris) == 0 or len(pos) == 0:
        return tris, None
    if len(tris) > CHUNK_TRIANGLES:
        centroids = pos[tris].mean(axis=1)
        finite = np.isfinite(centroids).all(axis=1)
        centroids[~finite] = 0.0
        lo, hi = centroids.min(axis=0), centroids.max(axis=0)
        q = np.clip((centroids - lo) / np.maximum(hi - lo, 1e-12) * 1023.0, 0, 1023)
        tris = tris[np.argsort(_morton(q), kind="stable")]
    # A power of two of equal chunks: cuts in Morton order then fall on octree cells.
    parts = 1 << max(0, math.ceil(math.log2(len(tris) / CHUNK_TRIANGLES)))
    size = -(-len(tris) // parts)
    starts = np.arange(0, len(tris), size)
    counts = np.minimum(size, len(tris) - starts)
    los, his = [], []
    for s, c in zip(starts, counts):
        corners = pos[tris[s : s + c].ravel()]
        corners = corners[np.isfinite(corners).all(axis=1)]
        if len(corners) == 0:
            corners = np.zeros((1, 3))
        los.append(corners.min(axis=0))
        his.append(corners.max(axis=0))
    chunks = Chunks(starts * 3, counts * 3, np.array(los), np.array(his))
    return tris, chunks


_planes_cache: tuple[bytes, np.ndarray] | None = None


def frustum_planes(view_projection: np.ndarray) -> np.ndarray:
    """The (5, 4) inward planes (left, right, bottom, top, near) of a GL view-projection
    (clip = VP @ p, visible where -w <= x, y, z <= w); the last matrix's planes are kept."""
    global _planes_cache
    vp = np.asarray(view_projection, np.float64)
    key = vp.tobytes()
    if _planes_cache is not None and _planes_cache[0] == key:
        return _planes_cache[1]
    r = vp
    planes = np.array([r[3] + r[0], r[3] - r[0], r[3] + r[1], r[3] - r[1], r[3] + r[2]])
    _planes_cache = (key, planes)
    return planes


def visible_mask(chunks: Chunks, planes: np.ndarray) -> np.ndarray:
    """Which chunks' boxes are not wholly outside one of the planes (conservative)."""
    n = planes[:, :3]
    # The box corner farthest along each plane's normal (the "positive vertex").
    px = np.where(n[None, :, 0] > 0, chunks.hi[:, None, 0], chunks.lo[:, None, 0])
    py = np.where(n[None, :, 1] > 0, chunks.hi[:, None, 1], chunks.lo[:, None, 1])
    pz = np.where(n[None, :, 2] > 0, chunks.hi[:, None, 2], chunks.lo[:, None, 2])
    d = px * n[None, :, 0] + py * n[None, :, 1] + pz * n[None, :, 2] + planes[None, :, 3]
    return np.asarray((d >= 0).all(axis=1))


def visible_ranges(chunks: Chunks, planes: np.ndarray) -> list[tuple[int, int]]:
    """(first, count) index ranges to draw, neighbouring visible chunks merged."""
    mask = visible_mask(chunks, planes)
    out: list[tuple[int, int]] = []
    for first, count in zip(chunks.first[mask].tolist(), chunks.count[mask].tolist()):
        if out and out[-1][0] + out[-1][1] == first:
            out[-1] = (out[-1][0], out[-1][1] + count)
        else:
            out.append((first, count))
    return out
