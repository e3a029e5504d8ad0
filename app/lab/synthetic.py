"""A synthetic interior of any size as a GLB, for load benchmarks: an 8 x 3 x 10 m room whose
floor holds a grid of tessellated spheres (one mesh and material each, some textured).

Written with numpy and json only, so the file is the same on every machine for a given size.
"""

from __future__ import annotations

import io
import json
import math
import struct
from pathlib import Path

import numpy as np

ROOM = (8.0, 3.0, 10.0)  # width (x), height (y), depth (z), metres; floor at y = 0


def sphere(rings: int, segments: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Unit UV sphere: positions, normals, uvs (float32) and uint32 triangle indices."""
    theta = np.linspace(0.0, math.pi, rings + 1)
    phi = np.linspace(0.0, 2.0 * math.pi, segments + 1)
    t, p = np.meshgrid(theta, phi, indexing="ij")
    pos = np.stack([np.sin(t) * np.cos(p), np.cos(t), np.sin(t) * np.sin(p)], -1).reshape(-1, 3)
    uv = np.stack([p / (2 * math.pi), 1.0 - t / math.pi], -1).reshape(-1, 2)
    r, s = np.meshgrid(np.arange(rings), np.arange(segments), indexing="ij")
    a = r * (segments + 1) + s
    b = a + segments + 1
    quads = np.stack([a, a + 1, b, a + 1, b + 1, b], -1).reshape(-1, 3)
    return (
        pos.astype(np.float32),
        pos.astype(np.float32),
        uv.astype(np.float32),
        quads.astype(np.uint32),
    )


def _room() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Floor, ceiling and four walls facing inwards: positions, normals, indices."""
    w, h, d = ROOM
    x0, x1, z0, z1 = -w / 2, w / 2, -d / 2, d / 2
    Corner = tuple[float, float, float]
    quads: list[tuple[list[Corner], Corner]] = [  # corners anticlockwise from inside; normal
        ([(x0, 0, z0), (x0, 0, z1), (x1, 0, z1), (x1, 0, z0)], (0, 1, 0)),
        ([(x0, h, z0), (x1, h, z0), (x1, h, z1), (x0, h, z1)], (0, -1, 0)),
        ([(x0, 0, z0), (x1, 0, z0), (x1, h, z0), (x0, h, z0)], (0, 0, 1)),
        ([(x0, 0, z1), (x0, h, z1), (x1, h, z1), (x1, 0, z1)], (0, 0, -1)),
        ([(x0, 0, z0), (x0, h, z0), (x0, h, z1), (x0, 0, z1)], (1, 0, 0)),
        ([(x1, 0, z0), (x1, 0, z1), (x1, h, z1), (x1, h, z0)], (-1, 0, 0)),
    ]
    pos = np.array([c for q, _n in quads for c in q], np.float32)
    nrm = np.array([n for _q, n in quads for _ in range(4)], np.float32)
    idx = np.array([[4 * i, 4 * i + 1, 4 * i + 2, 4 * i, 4 * i + 2, 4 * i + 3] for i in range(6)])
    return pos, nrm, idx.reshape(-1, 3).astype(np.uint32)


def _jpeg(size: int, seed: int) -> bytes:
    from PIL import Image

    rng = np.random.default_rng(seed)
    y, x = np.mgrid[0:size, 0:size]
    tile = ((x // max(size // 8, 1) + y // max(size // 8, 1)) % 2).astype(np.float32)
    rgb = (tile[..., None] * rng.uniform(80, 220, 3) + (1 - tile[..., None]) * 40).astype(np.uint8)
    buf = io.BytesIO()
    Image.fromarray(rgb).save(buf, "JPEG", quality=85)
    return buf.getvalue()


def write_synthetic_room(
    path: str | Path, triangles: int = 1_000_000, textures: int = 4, texture_px: int = 1024
) -> Path:
    """Write the room with about ``triangles`` triangles in spheres of ~2,500 each."""
    rings, segments = 25, 50  # 2 * 25 * 50 = 2,500 triangles per sphere
    count = max(1, round(triangles / (2 * rings * segments)))
    s_pos, s_nrm, s_uv, s_idx = sphere(rings, segments)
    side = math.ceil(math.sqrt(count))
    blob = bytearray()
    views: list[dict] = []
    accessors: list[dict] = []

    def add(array: np.ndarray, kind: str, component: int, target: int | None) -> int:
        while len(blob) % 4:
            blob.append(0)
        data = np.ascontiguousarray(array).tobytes()
        view = {"buffer": 0, "byteOffset": len(blob), "byteLength": len(data)}
        if target is not None:
            view["target"] = target
        views.append(view)
        blob.extend(data)
        acc = {
            "bufferView": len(views) - 1,
            "componentType": component,
            "count": int(array.shape[0]) if kind != "SCALAR" else int(array.size),
            "type": kind,
        }
        if kind == "VEC3" and component == 5126:
            acc["min"] = array.min(axis=0).tolist()
            acc["max"] = array.max(axis=0).tolist()
        accessors.append(acc)
        return len(accessors) - 1

    images, gl_textures = [], []
    for t in range(textures):
        data = _jpeg(texture_px, t)
        while len(blob) % 4:
            blob.append(0)
        views.append({"buffer": 0, "byteOffset": len(blob), "byteLength": len(data)})
        blob.extend(data)
        images.append({"bufferView": len(views) - 1, "mimeType": "image/jpeg"})
        gl_textures.append({"source": t})

    # every sphere its own geometry (jittered, so nothing can be shared), as exporters write rooms
    jitter = np.random.default_rng(7)
    r_pos, r_nrm, r_idx = _room()
    meshes = [
        {
            "name": "room",
            "primitives": [
                {
                    "attributes": {
                        "POSITION": add(r_pos, "VEC3", 5126, 34962),
                        "NORMAL": add(r_nrm, "VEC3", 5126, 34962),
                    },
                    "indices": add(r_idx.reshape(-1), "SCALAR", 5125, 34963),
                    "material": 0,
                }
            ],
        }
    ]
    materials: list[dict] = [{"name": "plaster", "pbrMetallicRoughness": {"metallicFactor": 0.0}}]
    nodes: list[dict] = [{"mesh": 0, "name": "room"}]
    w, _h, d = ROOM
    rng = np.random.default_rng(1)
    for i in range(count):
        gx, gz = i % side, i // side
        radius = 0.12
        x = -w / 2 + 0.5 + (w - 1.0) * (gx + 0.5) / side
        z = -d / 2 + 0.5 + (d - 1.0) * (gz + 0.5) / side
        pbr: dict = {"metallicFactor": 0.0, "roughnessFactor": float(rng.uniform(0.3, 0.9))}
        if textures and i % 3 == 0:
            pbr["baseColorTexture"] = {"index": i % textures}
        else:
            pbr["baseColorFactor"] = [*rng.uniform(0.1, 0.9, 3).tolist(), 1.0]
        materials.append({"name": f"ball {i}", "pbrMetallicRoughness": pbr})
        bumpy = s_pos * jitter.uniform(0.97, 1.03, (len(s_pos), 1)).astype(np.float32)
        prim = {
            "attributes": {
                "POSITION": add(bumpy, "VEC3", 5126, 34962),
                "NORMAL": add(s_nrm, "VEC3", 5126, 34962),
                "TEXCOORD_0": add(s_uv, "VEC2", 5126, 34962),
            },
            "indices": add(s_idx.reshape(-1), "SCALAR", 5125, 34963),
            "material": len(materials) - 1,
        }
        meshes.append({"name": f"ball {i}", "primitives": [prim]})
        nodes.append(
            {
                "mesh": len(meshes) - 1,
                "name": f"ball {i}",
                "translation": [x, radius, z],
                "scale": [radius, radius, radius],
            }
        )
    doc = {
        "asset": {"version": "2.0", "generator": "vrpreview synthetic room"},
        "scene": 0,
        "scenes": [{"nodes": list(range(len(nodes)))}],
        "nodes": nodes,
        "meshes": meshes,
        "materials": materials,
        "accessors": accessors,
        "bufferViews": views,
        "buffers": [{"byteLength": len(blob)}],
    }
    if images:
        doc["images"] = images
        doc["textures"] = gl_textures
    text = json.dumps(doc, separators=(",", ":")).encode()
    text += b" " * (-len(text) % 4)
    while len(blob) % 4:
        blob.append(0)
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    with open(out, "wb") as fh:
        total = 12 + 8 + len(text) + 8 + len(blob)
        fh.write(struct.pack("<4sII", b"glTF", 2, total))
        fh.write(struct.pack("<I4s", len(text), b"JSON") + text)
        fh.write(struct.pack("<I4s", len(blob), b"BIN\x00") + bytes(blob))
    return out
