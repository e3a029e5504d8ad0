"""Long edges split at load, so that what the renderer keeps per vertex has vertices to keep.

The sky's light through a window (``app.sky_light``) and the baked occlusion (``app.ao_bake``)
are found per vertex and interpolated across each triangle. A floor, wall or ceiling exported
as one quad (SketchUp, a modelling tool's box, the showroom's own floor: 8 x 6 m in two
triangles) has four vertices: the window's pool of light on the floor and the daylit wall
beside it fall between them and are lost. Splitting the long edges gives such faces a vertex
about every half metre (``MAX_EDGE_M``), a few hundred triangles per wall, and leaves the rest
(a real room's furniture, already finely modelled) as it is.

Each round splits every triangle's longest edge where it is longer than ``MAX_EDGE_M`` and the
triangle is no sliver (of less area than half a square of that edge: a skirting board's or a
blind's slat, which would take most of the triangles for little of the surface); that is
longest-edge bisection, made conforming: an edge is split in every triangle that has it (its
two vertex indices), so no T-junction opens a crack; the copies of a vertex along a seam (its
UVs or normals differ either side) have equal positions, so both sides split alike and the
seam stays closed. A triangle with one split edge becomes two, with two three (the quad left
cut along its shorter diagonal), with three four. Vertex attributes are interpolated at the
midpoints (normals and tangents renormalised). Rounds go over every mesh at once until no edge
is to be split or the scene's triangle budget (``MAX_ADDED_SHARE`` of its triangles, at least
``MIN_ADDED``) would be passed; each round is whole, so the result stays conforming.

Not a library's: trimesh's ``subdivide_to_size`` splits a face's every edge and leaves its
neighbours as they were (T-junctions), and meshoptimizer and fast-simplification only reduce.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np

from app.scene import Mesh, Scene

#: The longest edge kept as it is (metres): the sky's light through a window changes over
#: about this distance on the floor.
MAX_EDGE_M = 0.5
#: The triangles splitting may add, as a share of the scene's (at least MIN_ADDED): a real
#: room of 400k triangles draws at most 5 % more.
MAX_ADDED_SHARE = 0.05
MIN_ADDED = 20_000
MAX_ROUNDS = 16

# The sub-triangles of a triangle (v0, v1, v2) with midpoints (m0 on v0-v1, m1 on v1-v2,
# m2 on v2-v0), as indices into [v0, v1, v2, m0, m1, m2], for one split edge (edge 0), two
# (edges 0 and 1; the quad v0-m0-m1-v2 cut along v0-m1 or m0-v2, whichever is shorter) and
# all three.
_ONE = ((0, 3, 2), (3, 1, 2))
_TWO_A = ((3, 1, 4), (0, 3, 4), (0, 4, 2))  # the quad cut along v0-m1
_TWO_B = ((3, 1, 4), (0, 3, 2), (3, 4, 2))  # the quad cut along m0-v2
_THREE = ((0, 3, 5), (3, 1, 4), (5, 4, 2), (3, 4, 5))


def split_round(
    positions: np.ndarray, tri: np.ndarray, attributes: dict[str, np.ndarray], max_edge: float
) -> tuple[np.ndarray, np.ndarray, dict[str, np.ndarray]] | None:
    """One round: every edge longer than ``max_edge`` split at its midpoint, in every
    triangle that has it. None when no edge is that long."""
    v = positions.shape[0]
    a = tri
    b = np.roll(tri, -1, axis=1)  # edge k runs from vertex k to vertex k + 1
    length = np.linalg.norm(positions[a] - positions[b], axis=2)
    # Each triangle's longest edge, where too long, is split (longest-edge bisection: a
    # sliver of a skirting board is cut across, not fanned out), in every triangle that has it.
    # Slivers of less area than half a max_edge square (a skirting board's, a blind's slat)
    # are left: what they would add is most of the triangles and little of the surface.
    longest = length.argmax(axis=1)
    p = positions[tri]
    area = 0.5 * np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), axis=1)
    marked = (length[np.arange(len(tri)), longest] > max_edge) & (area > 0.5 * max_edge**2)
    if not marked.any():
        return None
    keys = np.minimum(a, b) * v + np.maximum(a, b)
    unique = np.unique(keys[marked, longest[marked]])
    at = np.minimum(np.searchsorted(unique, keys), len(unique) - 1)
    long = unique[at] == keys
    ua, ub = unique // v, unique % v
    mids = np.full(tri.shape, -1, np.int64)
    mids[long] = v + at[long]
    pos = np.concatenate([positions, 0.5 * (positions[ua] + positions[ub])])
    attrs = {k: np.concatenate([x, _midpoint(k, x[ua], x[ub])]) for k, x in attributes.items()}

    mask = long[:, 0] * 1 + long[:, 1] * 2 + long[:, 2] * 4
    parts = [tri[mask == 0]]
    corners = np.concatenate([tri, mids], axis=1)  # (T, 6): v0 v1 v2 m0 m1 m2
    for r in range(3):  # rotate so that the split edge is edge 0, or the unsplit one edge 2
        rot = corners[:, [r, (r + 1) % 3, (r + 2) % 3, 3 + r, 3 + (r + 1) % 3, 3 + (r + 2) % 3]]
        one = rot[mask == (1 << r)]
        parts += [one[:, list(t)] for t in _ONE]
        two = rot[mask == (7 - (1 << ((r + 2) % 3)))]
        if len(two):
            d_a = np.linalg.norm(pos[two[:, 0]] - pos[two[:, 4]], axis=1)
            d_b = np.linalg.norm(pos[two[:, 3]] - pos[two[:, 2]], axis=1)
            for cut, pick in ((_TWO_A, d_a <= d_b), (_TWO_B, d_a > d_b)):
                parts += [two[pick][:, list(t)] for t in cut]
    three = corners[mask == 7]
    parts += [three[:, list(t)] for t in _THREE]
    return pos, np.concatenate(parts).astype(np.int64), attrs


def _midpoint(name: str, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    m = 0.5 * (a + b)
    if name == "normals":
        return _unit(m, a)
    if name == "tangents":
        xyz = _unit(m[:, :3], a[:, :3])
        return np.concatenate([xyz, np.where(a[:, 3:] < 0.0, -1.0, 1.0)], axis=1)
    return m


def _unit(v: np.ndarray, fallback: np.ndarray) -> np.ndarray:
    n = np.linalg.norm(v, axis=1, keepdims=True)
    return np.where(n > 1e-6, v / np.maximum(n, 1e-12), fallback)


_ATTRIBUTES = ("normals", "uvs", "colors", "tangents", "ao")


def _state(mesh: Mesh) -> tuple[np.ndarray, np.ndarray, dict[str, np.ndarray]]:
    names = [k for k in _ATTRIBUTES if getattr(mesh, k) is not None]
    return (
        np.asarray(mesh.positions, np.float64),
        np.asarray(mesh.indices, np.int64).reshape(-1, 3),
        {k: np.asarray(getattr(mesh, k), np.float64) for k in names},
    )


def _mesh_of(mesh: Mesh, state: tuple[np.ndarray, np.ndarray, dict[str, np.ndarray]]) -> Mesh:
    pos, tri, attrs = state
    fields: dict[str, Any] = {k: v.astype(np.float32) for k, v in attrs.items()}
    return dataclasses.replace(
        mesh,
        positions=pos.astype(np.float32),
        indices=tri.astype(np.uint32),
        lod=None,  # of the triangles before
        **fields,
    )


def split_long_edges(
    mesh: Mesh, max_edge: float = MAX_EDGE_M, max_triangles: int | None = None
) -> Mesh:
    """``mesh`` with its edges longer than ``max_edge`` split (the same mesh when none is);
    rounds stop before the triangles would pass ``max_triangles``."""
    out = _split_all([mesh], max_edge, max_triangles)
    return out[0]


def _split_all(meshes: list[Mesh], max_edge: float, max_triangles: int | None) -> list[Mesh]:
    """Round by round over every mesh at once (each round halves the long edges of all of
    them, so the budget leaves every surface at the same fineness), stopping before the
    round that would pass ``max_triangles`` in all."""
    states: list = [None] * len(meshes)  # None: as it is
    active = list(range(len(meshes)))
    total = sum(m.triangle_count for m in meshes)
    for _ in range(MAX_ROUNDS):
        step = {}
        for i in active:
            pos, tri, attrs = states[i] or _state(meshes[i])
            out = split_round(pos, tri, attrs, max_edge)
            if out is not None:
                step[i] = out
        if not step:
            break
        grown = sum(
            len(out[1]) - len(states[i][1] if states[i] else meshes[i].indices)
            for i, out in step.items()
        )
        if max_triangles is not None and total + grown > max_triangles:
            break
        total += grown
        for i, out in step.items():
            states[i] = out
        active = list(step)
    return [m if st is None else _mesh_of(m, st) for m, st in zip(meshes, states, strict=True)]


def refine_scene(scene: Scene, max_edge: float = MAX_EDGE_M) -> Scene:
    """``scene`` with its long edges split (:func:`split_long_edges`), all meshes round by
    round while the scene's triangles stay within the budget. The same scene when nothing
    is long."""
    total = sum(m.triangle_count for m in scene.meshes)
    budget = total + max(MIN_ADDED, int(MAX_ADDED_SHARE * total))
    meshes = _split_all(list(scene.meshes), max_edge, budget)
    if all(a is b for a, b in zip(meshes, scene.meshes, strict=True)):
        return scene
    return dataclasses.replace(
        scene,
        meshes=meshes,
        ray_caster=None,
        ambient_probe=None,
        model_triangles=scene.model_triangle_count,
    )


def _area(mesh: Mesh) -> float:
    p = np.asarray(mesh.positions, np.float64)
    t = np.asarray(mesh.indices, np.int64).reshape(-1, 3)
    if not len(t):
        return 0.0
    cross = np.cross(p[t[:, 1]] - p[t[:, 0]], p[t[:, 2]] - p[t[:, 0]])
    return float(0.5 * np.linalg.norm(cross, axis=1).sum())
