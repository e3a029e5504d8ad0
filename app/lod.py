"""Chunks and geometry levels of detail of a mesh, built at load and cached on disk.

A mesh's triangles are drawn as ranges of its index buffer, each with an axis-aligned world
bounding box (render.culling tests them against each eye's frustum). A mesh of up to
``CHUNK_TRIANGLES`` triangles is one range, in its own order (its picture is the same as an
unchunked draw). A bigger one, as real files often hold (a whole room's walls in one mesh), is
split into spatially coherent chunks: its triangles sorted by the Morton code of their
centroids and cut into a power of two of equal ranges, so a chunk is a compact piece of the
mesh. The mesh keeps its identity (index, material, object id, TCR level).

Levels of detail: each chunk of a mesh of at least ``LOD_MIN_TRIANGLES`` triangles is
simplified by meshoptimizer (edge collapse under Garland and Heckbert's quadrics, seams of UVs
and normals collapsed together) to ``LOD_FRACTIONS`` of its triangles, keeping its border (no
cracks between chunks drawn at different levels). A simplified level is an index buffer of the
mesh's own vertices, one more range of the same buffer: normals, UVs, tangents and the mesh's
other per-vertex data stay valid. Each level records its geometric error (meshoptimizer's
absolute error, in metres); the renderer draws the coarsest level whose error, projected to the eye,
stays within ``render.lod_bias`` pixels. Results are cached by content hash under
``$VRPREVIEW_CACHE/lod`` (default ``$XDG_CACHE_HOME/vrpreview/lod``, ``~/.cache/...``).
"""

from __future__ import annotations

import hashlib
import logging
import math
import os
import tempfile
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

log = logging.getLogger(__name__)
CHUNK_TRIANGLES = 16384  # meshes above this are split into chunks of at most this many
LOD_MIN_TRIANGLES = 128  # smaller meshes are always drawn in full (real rooms: many small ones)
LOD_FRACTIONS = (0.5, 0.25, 0.1, 0.03)  # the simplified levels' share of a chunk's triangles
CACHE_VERSION = 4


@dataclass
class Chunks:
    """Ranges of one mesh's index buffer. ``first``, ``count``: (levels, n) in indices (3 a
    triangle), level 0 the full mesh; ``error``: (levels, n) metres each level may stray
    from the full surface; ``lo``, ``hi``: (n, 3) world bounds of each chunk."""

    first: np.ndarray
    count: np.ndarray
    error: np.ndarray
    lo: np.ndarray
    hi: np.ndarray

    @property
    def levels(self) -> int:
        return int(self.first.shape[0])


def _morton(q: np.ndarray) -> np.ndarray:
    """Interleaved bits of three 10-bit integer coordinates (n, 3) -> (n,) uint32."""
    code = np.zeros(len(q), np.uint32)
    v = q.astype(np.uint32)
    for bit in range(10):
        for axis in range(3):
            code |= ((v[:, axis] >> bit) & 1) << np.uint32(3 * bit + axis)
    return code


def chunk_mesh(positions: np.ndarray, indices: np.ndarray) -> tuple[np.ndarray, Chunks | None]:
    """The mesh's (M, 3) triangles in drawing order and their chunks (one level; None: no
    triangles). Non-finite positions are left out of the bounds."""
    tris = np.asarray(indices, np.int64).reshape(-1, 3)
    pos = np.asarray(positions, np.float64)
    if len(tris) == 0 or len(pos) == 0:
        return tris, None
    if len(tris) > CHUNK_TRIANGLES:
        centroids = pos[tris].mean(axis=1)
        centroids[~np.isfinite(centroids).all(axis=1)] = 0.0
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
    first, count = (starts * 3)[None], (counts * 3)[None]
    return tris, Chunks(first, count, np.zeros(first.shape), np.array(los), np.array(his))


def _meshopt(
    points: np.ndarray, tris: np.ndarray, fraction: float, keep_border: bool
) -> tuple[np.ndarray, float]:
    """meshoptimizer's simplification of (k, 3) ``tris`` over ``points`` towards ``fraction``
    of them: the triangles (of the same points) and the absolute error."""
    import meshoptimizer

    lo = points.min(axis=0)
    relative = np.ascontiguousarray(points - lo, np.float32)  # float32 stays precise near 0
    source = np.ascontiguousarray(tris.reshape(-1), np.uint32)
    out = np.zeros_like(source)
    error = np.zeros(1, np.float32)
    options = meshoptimizer.SIMPLIFY_ERROR_ABSOLUTE
    if keep_border:
        options |= meshoptimizer.SIMPLIFY_LOCK_BORDER
    reach = float(np.linalg.norm(relative.max(axis=0))) + 1.0  # no error limit: the count rules
    count = meshoptimizer.simplify(
        out,
        source,
        relative,
        target_index_count=max(3, int(source.size * fraction) // 3 * 3),
        target_error=reach,
        options=options,
        result_error=error,
    )
    return out[:count].reshape(-1, 3).astype(np.int64), float(error[0])


def _welded(
    points: np.ndarray,
    tris: np.ndarray,
    fraction: float,
    keep_border: bool,
    normals: np.ndarray | None,
) -> tuple[np.ndarray, float] | None:
    """The simplification of a mesh whose triangles do not share vertices (flat-shaded
    exports: every corner its own vertex, which meshoptimizer must keep): simplified with the
    corners welded by position, each corner of a kept triangle then given back the vertex of
    that position whose normal is closest to the triangle's (its facet's own, on a flat-shaded
    mesh). None where welding joins nothing."""
    unique, weld = np.unique(points, axis=0, return_inverse=True)
    weld = weld.reshape(-1)
    if len(unique) > 0.75 * len(points):
        return None
    wt = weld[tris]
    keep = (wt[:, 0] != wt[:, 1]) & (wt[:, 1] != wt[:, 2]) & (wt[:, 0] != wt[:, 2])
    out, error = _meshopt(unique, wt[keep], fraction, keep_border)
    if len(out) == 0:
        return None
    # Each welded position's vertices, in runs of the sorted order.
    order = np.argsort(weld, kind="stable")
    start = np.searchsorted(weld[order], np.arange(len(unique)))
    count = np.bincount(weld, minlength=len(unique))
    corner = out.reshape(-1)
    best = order[start[corner]]
    if normals is not None and np.isfinite(normals).all():
        p = unique[out]
        face = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
        face = np.repeat(
            face / np.maximum(np.linalg.norm(face, axis=1, keepdims=True), 1e-30), 3, 0
        )
        score = np.sum(normals[best] * face, axis=1)
        for k in range(1, int(count[corner].max())):
            has = count[corner] > k
            cand = order[start[corner[has]] + k]
            s = np.sum(normals[cand] * face[has], axis=1)
            better = s > score[has]
            idx = np.flatnonzero(has)[better]
            best[idx], score[idx] = cand[better], s[better]
    return best.reshape(-1, 3), error


def simplify_chunk(
    pos: np.ndarray,
    tris: np.ndarray,
    fraction: float,
    normals: np.ndarray | None = None,
    keep_border: bool = True,
) -> tuple[np.ndarray, float] | None:
    """``tris`` (k, 3) of the mesh's vertices ``pos`` simplified to about ``fraction`` of its
    triangles, as triangles of the same vertices, and its error in metres (meshoptimizer's
    absolute error: how far the simplified surface strays from the full one); None when it
    cannot be (too few triangles, broken positions, no real reduction). ``keep_border``: the
    chunk's open edges stay (where neighbouring chunks meet it); a whole mesh lets them move
    too (its error counts how far). Vertices that share a position along a seam of UVs or
    normals are collapsed together; a mesh whose triangles share no vertices at all is
    simplified welded (:func:`_welded`, ``normals`` choose each corner's vertex)."""
    used, local = np.unique(tris, return_inverse=True)
    local = local.reshape(-1, 3)
    points = pos[used]
    if len(tris) < 8 or not np.isfinite(points).all():
        return None
    target = max(1, int(len(tris) * fraction))
    out, error = _meshopt(points, local, fraction, keep_border)
    if len(out) > 1.5 * target:  # stuck: corners that share a position but not a vertex
        own = None if normals is None else np.asarray(normals, np.float64)[used]
        welded = _welded(points, local, fraction, keep_border, own)
        if welded is not None and len(welded[0]) < len(out):
            out, error = welded
    if len(out) == 0 or len(out) > 0.9 * len(tris):
        return None
    return used[out], error


def build_lod(
    positions: np.ndarray, indices: np.ndarray, normals: np.ndarray | None = None
) -> tuple[np.ndarray, Chunks | None]:
    """The mesh's index buffer (chunk-ordered full level, then the simplified levels) as
    (K, 3) triangles, and its chunks with every level (only level 0 for a small mesh)."""
    tris, chunks = chunk_mesh(positions, indices)
    if chunks is None or len(tris) < LOD_MIN_TRIANGLES:
        return tris, chunks
    pos = np.asarray(positions, np.float64)
    n = chunks.first.shape[1]
    levels = 1 + len(LOD_FRACTIONS)
    first = np.zeros((levels, n), np.int64)
    count = np.zeros((levels, n), np.int64)
    error = np.zeros((levels, n))
    first[0], count[0] = chunks.first[0], chunks.count[0]
    parts = [tris]
    end = len(tris) * 3
    for c in range(n):
        src = tris[chunks.first[0, c] // 3 : (chunks.first[0, c] + chunks.count[0, c]) // 3]
        for level, fraction in enumerate(LOD_FRACTIONS, start=1):
            result = simplify_chunk(pos, src, fraction, normals, keep_border=n > 1)
            if result is None:  # no coarser level: the previous one stands in
                first[level, c], count[level, c] = first[level - 1, c], count[level - 1, c]
                error[level, c] = error[level - 1, c]
                continue
            simplified, moved = result
            first[level, c], count[level, c] = end, simplified.size
            error[level, c] = max(moved, error[level - 1, c])
            parts.append(simplified)
            end += simplified.size
    return np.concatenate(parts), Chunks(first, count, error, chunks.lo, chunks.hi)


def cache_dir() -> Path:
    """Where levels of detail are kept: ``$VRPREVIEW_CACHE/lod``, else the user cache."""
    root = os.environ.get("VRPREVIEW_CACHE")
    if root:
        return Path(root) / "lod"
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "vrpreview" / "lod"


def content_key(
    positions: np.ndarray, indices: np.ndarray, normals: np.ndarray | None = None
) -> str:
    """The cache's name for a mesh's levels: its geometry, normals (they choose the corners
    of a welded simplification) and the build's parameters."""
    h = hashlib.sha256()
    h.update(f"v{CACHE_VERSION} {CHUNK_TRIANGLES} {LOD_FRACTIONS}".encode())
    h.update(np.ascontiguousarray(positions, np.float32).tobytes())
    h.update(np.ascontiguousarray(indices, np.int64).tobytes())
    if normals is not None:
        h.update(np.ascontiguousarray(normals, np.float32).tobytes())
    return h.hexdigest()


@dataclass
class MeshLod:
    """A mesh's index buffer (triangles, every level) and its chunks (``Mesh.lod``)."""

    triangles: np.ndarray
    chunks: Chunks
    source_triangles: int  # the mesh's triangle count it was built from (a check at upload)


def cached_lod(
    positions: np.ndarray, indices: np.ndarray, normals: np.ndarray | None = None
) -> tuple[MeshLod | None, bool]:
    """The mesh's levels from the cache or built (and cached); True when it was a cache hit.
    None (with a warning) when the mesh cannot be simplified: it is drawn in full."""
    key = content_key(positions, indices, normals)
    path = cache_dir() / f"{key}.npz"
    n = int(np.asarray(indices).reshape(-1, 3).shape[0])
    if path.exists():
        try:
            with np.load(path) as f:
                stored = Chunks(f["first"], f["count"], f["error"], f["lo"], f["hi"])
                return MeshLod(f["triangles"], stored, n), True
        except (OSError, ValueError, KeyError):
            log.warning("the cached levels of detail %s are damaged; building them again", path)
    try:
        tris, chunks = build_lod(positions, indices, normals)
    except Exception:  # noqa: BLE001 - broken geometry: drawn in full, not a failed load
        log.warning("a mesh could not be simplified; it is drawn in full detail", exc_info=True)
        return None, False
    if chunks is None:
        return None, False
    lod = MeshLod(tris, chunks, n)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=path.parent, suffix=".npz")
        with os.fdopen(fd, "wb") as out:
            np.savez(
                out,
                triangles=tris,
                first=chunks.first,
                count=chunks.count,
                error=chunks.error,
                lo=chunks.lo,
                hi=chunks.hi,
            )
        os.replace(tmp, path)
    except OSError:
        log.warning("could not cache levels of detail in %s", path.parent, exc_info=True)
    return lod, False


def attach_lods(meshes: list, progress: Callable[[float, str], None] | None = None) -> int:
    """Give every mesh with enough triangles its levels (``mesh.lod``); returns how many were
    cache hits. ``progress(fraction, text)`` is told as it goes."""
    hits = 0
    big = [m for m in meshes if m.triangle_count >= LOD_MIN_TRIANGLES]
    for k, mesh in enumerate(big):
        if progress is not None:
            progress(k / max(len(big), 1), f"Simplifying distant geometry ({k + 1}/{len(big)})")
        lod, hit = cached_lod(mesh.positions, mesh.indices, mesh.normals)
        mesh.lod = lod
        hits += int(hit)
    return hits
