"""Per-mesh, per-view frustum culling and level-of-detail choice on index-buffer chunks
(built by ``app.lod``: spatially coherent chunks of big meshes, simplified levels).

Each view tests every chunk's box against the frustum's side and near planes (Gribb and
Hartmann's extraction from the view-projection matrix; the far plane is left out, a box beyond
it costs only its vertices), picks each visible chunk's level from its projected error, and
draws neighbouring ranges as one call. A whole small object (a mesh of one chunk, under
``WHOLE_MESH_TRIANGLES``) that would cover no more than the allowed error on screen is left
out (Funkhouser and Séquin's detail elision): real rooms hold hundreds of screws, knobs and
handles of a centimetre or two, whose triangles cost the vertex stage as much as a wall's.
"""

from __future__ import annotations

import numpy as np

from app.camera import EyeView
from app.lod import Chunks, chunk_mesh

__all__ = [
    "Chunks",
    "chunk_mesh",
    "frustum_planes",
    "indirect_commands",
    "lod_levels",
    "merge_chunks",
    "triangles_by_error",
    "visible_ranges",
]

_planes_cache: tuple[bytes, np.ndarray] | None = None
#: A chunk of fewer triangles at its full level is a whole mesh: a split mesh's chunks hold
#: at least about half of app.lod.CHUNK_TRIANGLES each, so a hole is never cut in a surface.
WHOLE_MESH_TRIANGLES = 4096
#: The level :func:`lod_levels` gives a chunk left out (:func:`visible_ranges` skips it).
LEFT_OUT = -1


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


def lod_levels(
    chunks: Chunks,
    eye: np.ndarray,
    pixels_per_radian: float,
    max_error_px: float,
    keep: np.ndarray | None = None,
) -> np.ndarray:
    """Per chunk, the coarsest level whose error, seen from ``eye`` at its nearest point of
    the chunk's box, is at most ``max_error_px`` pixels (0: always the full level 0), or
    :data:`LEFT_OUT` for a whole small mesh whose box's diagonal is within that error (its
    whole surface moves no farther than that when it is not drawn) unless ``keep`` says so
    (per chunk: a glowing lamp's bulb stays, however small)."""
    n = chunks.first.shape[1]
    if max_error_px <= 0:
        return np.zeros(n, np.int64)
    nearest = np.clip(np.asarray(eye, np.float64), chunks.lo, chunks.hi)
    dist = np.maximum(np.linalg.norm(nearest - np.asarray(eye, np.float64), axis=1), 1e-3)
    if chunks.levels == 1:
        levels = np.zeros(n, np.int64)
    else:
        error_px = chunks.error * pixels_per_radian / dist[None, :]
        ok = error_px <= max_error_px  # level 0 always (error 0)
        levels = (ok.shape[0] - 1 - np.argmax(ok[::-1], axis=0)).astype(np.int64)
    size_px = np.linalg.norm(chunks.hi - chunks.lo, axis=1) * pixels_per_radian / dist
    whole = chunks.count[0] < 3 * WHOLE_MESH_TRIANGLES
    if keep is not None:
        whole &= ~np.asarray(keep, bool)
    levels[whole & (size_px <= max_error_px)] = LEFT_OUT
    return levels


def merge_chunks(per_mesh: list[Chunks | None]) -> tuple[Chunks, np.ndarray]:
    """All meshes' chunks as one table (a mesh with fewer levels repeats its coarsest) and
    the mesh each row belongs to."""
    present = [(i, c) for i, c in enumerate(per_mesh) if c is not None]
    if not present:
        z = np.zeros((1, 0), np.int64)
        return Chunks(z, z, np.zeros((1, 0)), np.zeros((0, 3)), np.zeros((0, 3))), z[0]
    levels = max(c.levels for _, c in present)

    def padded(a: np.ndarray) -> np.ndarray:
        return np.concatenate([a, np.repeat(a[-1:], levels - a.shape[0], axis=0)])

    owner = np.concatenate([np.full(c.first.shape[1], i, np.int64) for i, c in present])
    table = Chunks(
        np.concatenate([padded(c.first) for _, c in present], axis=1),
        np.concatenate([padded(c.count) for _, c in present], axis=1),
        np.concatenate([padded(c.error) for _, c in present], axis=1),
        np.concatenate([c.lo for _, c in present]),
        np.concatenate([c.hi for _, c in present]),
    )
    return table, owner


def visible_ranges(
    chunks: Chunks,
    planes: np.ndarray,
    levels: np.ndarray | None = None,
    owner: np.ndarray | None = None,
) -> dict[int, list[tuple[int, int]]]:
    """Per mesh (``owner`` of each chunk; default all one mesh, 0), the (first, count)
    index ranges to draw, each chunk at ``levels`` (default full), neighbours merged."""
    n = chunks.first.shape[1]
    mask = visible_mask(chunks, planes)
    lv = np.zeros(n, np.int64) if levels is None else levels
    mask &= lv != LEFT_OUT
    lv = np.maximum(lv, 0)
    firsts = chunks.first[lv, np.arange(n)][mask]
    counts = chunks.count[lv, np.arange(n)][mask]
    owners = np.zeros(n, np.int64)[mask] if owner is None else owner[mask]
    out: dict[int, list[tuple[int, int]]] = {}
    for mesh, first, count in zip(owners.tolist(), firsts.tolist(), counts.tolist()):
        ranges = out.setdefault(mesh, [])
        if ranges and ranges[-1][0] + ranges[-1][1] == first:
            ranges[-1] = (ranges[-1][0], ranges[-1][1] + count)
        else:
            ranges.append((first, count))
    return out


def triangles_by_error(
    chunks: Chunks, eye: EyeView, errors: tuple[float, ...], keep: np.ndarray | None = None
) -> dict[float, int]:
    """Per allowed error (pixels of ``eye``'s size, as ``render.lod_bias``), the triangles
    the eye would draw: its visible chunks at their levels, the small ones left out. The
    governor prices its level-of-detail steps with it (a real room's coarse levels hold a
    tenth of its triangles, a showroom's nearly all)."""
    n = chunks.first.shape[1]
    if n == 0:
        return dict.fromkeys((float(e) for e in errors), 0)
    visible = visible_mask(chunks, frustum_planes(eye.view_projection))
    pixels_per_radian = float(eye.projection[1, 1]) * eye.height * 0.5
    columns = np.arange(n)
    out = {}
    for e in errors:
        levels = lod_levels(chunks, eye.position, pixels_per_radian, float(e), keep)
        drawn = visible & (levels != LEFT_OUT)
        out[float(e)] = int(chunks.count[np.maximum(levels, 0), columns][drawn].sum()) // 3
    return out


def indirect_commands(
    every: dict[int, list[tuple[int, int]]],
) -> tuple[np.ndarray, dict[int, tuple[int, int]]]:
    """One view's ranges of every group as indirect draw commands (count, instances, first
    index, base vertex, base instance; (K, 5) uint32), and where each group's are (first
    command, how many)."""
    rows: list[tuple[int, int, int, int, int]] = []
    offsets = {}
    for g, ranges in every.items():
        offsets[g] = (len(rows), len(ranges))
        rows += [(count, 1, first, 0, 0) for first, count in ranges]
    return np.asarray(rows, np.uint32).reshape(-1, 5), offsets
