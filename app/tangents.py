"""Per-vertex tangent frames for normal mapping, from positions, normals and texture coordinates.

Close to MikkTSpace for ordinary meshes (each corner adds its triangle's unit tangent weighted by
the corner's angle, then the sum is made orthogonal to the vertex normal), but without
MikkTSpace's vertex splitting: vertices shared across a UV mirror seam get one frame. A vertex
whose triangles all have degenerate texture coordinates (zero UV area) gets a tangent
orthogonal to its normal, so its normal map still tilts the normal in some consistent frame.

Convention (as glTF's TANGENT attribute): ``xyz`` points along +u, the bitangent is
``w * cross(normal, xyz)`` and points along +v of the OpenGL-oriented ``Mesh.uvs`` (v up in the
image), which is the direction a normal map's green channel (+Y) means.
"""

from __future__ import annotations

import numpy as np


def generate_tangents(
    positions: np.ndarray, normals: np.ndarray, uvs: np.ndarray, indices: np.ndarray
) -> np.ndarray:
    """(N, 4) float32 tangents (unit xyz, w = +-1) for an indexed triangle mesh."""
    pos = np.asarray(positions, np.float64).reshape(-1, 3)
    nrm = np.asarray(normals, np.float64).reshape(-1, 3)
    uv = np.asarray(uvs, np.float64).reshape(-1, 2)
    idx = np.asarray(indices, np.int64).reshape(-1, 3)
    n = pos.shape[0]
    tangent_sum = np.zeros((n, 3))
    bitangent_sum = np.zeros((n, 3))
    if idx.shape[0]:
        p = pos[idx]  # (T, 3, 3)
        t = uv[idx]  # (T, 3, 2)
        e1, e2 = p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]
        d1, d2 = t[:, 1] - t[:, 0], t[:, 2] - t[:, 0]
        r = d1[:, 0] * d2[:, 1] - d2[:, 0] * d1[:, 1]
        ok = np.abs(r) > 1e-14
        safe_r = np.where(ok, r, 1.0)[:, None]
        face_t = (e1 * d2[:, 1:2] - e2 * d1[:, 1:2]) / safe_r
        face_b = (e2 * d1[:, 0:1] - e1 * d2[:, 0:1]) / safe_r
        face_t = _unit(face_t) * ok[:, None]
        face_b = _unit(face_b) * ok[:, None]
        for k in range(3):
            a = p[:, (k + 1) % 3] - p[:, k]
            b = p[:, (k + 2) % 3] - p[:, k]
            cos = np.einsum("ij,ij->i", _unit(a), _unit(b))
            angle = np.arccos(np.clip(cos, -1.0, 1.0))[:, None]
            np.add.at(tangent_sum, idx[:, k], face_t * angle)
            np.add.at(bitangent_sum, idx[:, k], face_b * angle)
    nrm = _unit(nrm, fallback=np.array([0.0, 1.0, 0.0]))
    tangent = tangent_sum - nrm * np.einsum("ij,ij->i", nrm, tangent_sum)[:, None]
    length = np.linalg.norm(tangent, axis=1)
    bad = length < 1e-10
    if bad.any():
        tangent[bad] = orthogonal(nrm[bad])
    tangent = _unit(tangent)
    handed = np.einsum("ij,ij->i", np.cross(nrm, tangent), bitangent_sum)
    w = np.where(handed < 0.0, -1.0, 1.0)
    return np.hstack([tangent, w[:, None]]).astype(np.float32)


def orthogonal(normals: np.ndarray) -> np.ndarray:
    """A unit vector orthogonal to each (unit) normal: its cross product with the axis it is
    least aligned with."""
    n = np.asarray(normals, np.float64).reshape(-1, 3)
    axis = np.zeros_like(n)
    axis[np.arange(len(n)), np.argmin(np.abs(n), axis=1)] = 1.0
    return _unit(np.cross(n, axis))


def transform_tangents(tangents: np.ndarray, rotation: np.ndarray) -> np.ndarray:
    """Tangents through a node's 3x3 matrix: xyz as directions, w flipped by a mirroring one
    (the bitangent is a cross product, which a reflection turns around)."""
    t = np.asarray(tangents, np.float64).reshape(-1, 4)
    rot = np.asarray(rotation, np.float64)
    xyz = _unit(t[:, :3] @ rot.T)
    det = float(np.linalg.det(rot))
    w = np.where(t[:, 3] < 0.0, -1.0, 1.0) * (-1.0 if det < 0.0 else 1.0)
    return np.hstack([xyz, w[:, None]]).astype(np.float32)


def _unit(v: np.ndarray, fallback: np.ndarray | None = None) -> np.ndarray:
    length = np.linalg.norm(v, axis=1, keepdims=True)
    out = v / np.maximum(length, 1e-30)
    if fallback is not None:
        out = np.where(length > 1e-20, out, fallback)
    return np.where(np.isfinite(out), out, 0.0)
