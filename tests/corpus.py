"""A corpus of bad model files, generated (never committed), and a worker that renders them.

:func:`build` writes several hundred damaged, hostile or merely unusual glTF/GLB/OBJ/PLY files
into a folder, each in a folder of its own named after its case, and returns the cases.
``python tests/corpus.py worker LIST OUT`` renders every file listed in the JSON file ``LIST``
through the CLI's ``main`` in this one process (a GL context per file, but no interpreter start
per file), and writes one JSON line per file to its stdout: ``{"start": name}`` before, then
the exit status, the stderr the CLI printed, and (when it loaded) the triangle count and the
warnings of :func:`app.loaders.load_scene`. :func:`run_corpus` drives the worker with a timeout
per file and restarts it after a crash or a hang, so every case gets an outcome.
"""

from __future__ import annotations

import base64
import contextlib
import copy
import io
import json
import logging
import os
import queue
import struct
import subprocess
import sys
import threading
import time
import traceback
import zlib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

REPO = Path(__file__).resolve().parents[1]
SIZE = "64x64"


def read_scene(path: Path):
    """The file's scene as read: its own triangles, without the split of long edges the
    loader then makes for the light kept per vertex (tests/test_tessellate.py tests that)."""
    from app.loaders import LoadOptions, load_scene

    return load_scene(path, LoadOptions(split_edges_m=0.0))


LIGHTS_NOTE = "the file has no lights"


@dataclass(frozen=True)
class Case:
    name: str
    path: Path
    family: str  # "gltf" or "objply" (who owns a failure)
    category: str
    base_tris: int | None = None  # triangles of the undamaged file; fewer must be warned about


# ------------------------------------------------------------------------------------------
# the valid files the damage starts from
# ------------------------------------------------------------------------------------------


def png_bytes(size: tuple[int, int] = (4, 4), mode: str = "RGB") -> bytes:
    from PIL import Image

    img = Image.new(mode, size)
    if mode in ("RGB", "RGBA"):
        arr = np.zeros((size[1], size[0], len(mode)), np.uint8)
        arr[..., 0] = np.arange(size[0], dtype=np.uint8)[None, :] * 60
        arr[..., 1] = 200
        img = Image.fromarray(arr, mode)
    buf = io.BytesIO()
    img.save(buf, format="PNG")
    return buf.getvalue()


def _box() -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """A 1 m cube, 4 vertices per face: positions, normals, uvs, uint16 indices (12 triangles)."""
    pos, nrm, uv, idx = [], [], [], []
    for axis in range(3):
        for sign in (-1.0, 1.0):
            n = np.zeros(3)
            n[axis] = sign
            u = np.roll(n, 1)
            v = np.cross(n, u)
            base = len(pos)
            for a, b in ((-1, -1), (1, -1), (1, 1), (-1, 1)):
                pos.append(0.5 * (n + a * u + b * v))
                nrm.append(n)
                uv.append(((a + 1) / 2, (b + 1) / 2))
            idx += [base, base + 1, base + 2, base, base + 2, base + 3]
    return (
        np.array(pos, np.float32),
        np.array(nrm, np.float32),
        np.array(uv, np.float32),
        np.array(idx, np.uint16),
    )


class Doc:
    """A glTF document and its binary buffer, built up view by view."""

    def __init__(self) -> None:
        self.json: dict[str, Any] = {
            "asset": {"version": "2.0", "generator": "vrpreview corpus"},
            "buffers": [{"byteLength": 0}],
            "bufferViews": [],
            "accessors": [],
        }
        self.bin = bytearray()

    def view(self, data: bytes, target: int | None = None) -> int:
        while len(self.bin) % 4:
            self.bin.append(0)
        bv: dict[str, Any] = {"buffer": 0, "byteOffset": len(self.bin), "byteLength": len(data)}
        if target:
            bv["target"] = target
        self.bin += data
        self.json["buffers"][0]["byteLength"] = len(self.bin)
        self.json["bufferViews"].append(bv)
        return len(self.json["bufferViews"]) - 1

    def accessor(self, arr: np.ndarray, kind: str, target: int | None = None) -> int:
        ctype = {np.float32: 5126, np.uint16: 5123, np.uint32: 5125, np.uint8: 5121}[arr.dtype.type]
        acc: dict[str, Any] = {
            "bufferView": self.view(arr.tobytes(), target),
            "componentType": ctype,
            "count": int(len(arr)),
            "type": kind,
        }
        if kind == "VEC3" and arr.dtype == np.float32:
            acc["min"] = [float(x) for x in arr.min(axis=0)]
            acc["max"] = [float(x) for x in arr.max(axis=0)]
        self.json["accessors"].append(acc)
        return len(self.json["accessors"]) - 1


def box_doc(texture: bytes | None = None) -> Doc:
    """The textured cube: accessors 0 indices, 1 POSITION, 2 NORMAL, 3 TEXCOORD_0; image 0."""
    pos, nrm, uv, idx = _box()
    d = Doc()
    i_idx = d.accessor(idx, "SCALAR", 34963)
    i_pos = d.accessor(pos, "VEC3", 34962)
    i_nrm = d.accessor(nrm, "VEC3", 34962)
    i_uv = d.accessor(uv, "VEC2", 34962)
    img_view = d.view(texture if texture is not None else png_bytes())
    d.json.update(
        scene=0,
        scenes=[{"nodes": [0]}],
        nodes=[{"mesh": 0, "name": "box"}],
        meshes=[
            {
                "name": "box",
                "primitives": [
                    {
                        "attributes": {"POSITION": i_pos, "NORMAL": i_nrm, "TEXCOORD_0": i_uv},
                        "indices": i_idx,
                        "material": 0,
                        "mode": 4,
                    }
                ],
            }
        ],
        materials=[
            {
                "name": "paint",
                "pbrMetallicRoughness": {
                    "baseColorFactor": [1.0, 1.0, 1.0, 1.0],
                    "baseColorTexture": {"index": 0},
                    "metallicFactor": 0.0,
                },
            }
        ],
        textures=[{"source": 0, "sampler": 0}],
        samplers=[{"magFilter": 9729, "minFilter": 9987, "wrapS": 10497, "wrapT": 10497}],
        images=[{"bufferView": img_view, "mimeType": "image/png"}],
    )
    return d


BOX_TRIS = 12


def glb_bytes(doc: dict[str, Any] | str | bytes, binary: bytes | None) -> bytes:
    if isinstance(doc, dict):
        doc = json.dumps(doc)
    text = doc.encode("utf-8") if isinstance(doc, str) else doc
    text += b" " * (-len(text) % 4)
    chunks = struct.pack("<II", len(text), 0x4E4F534A) + text
    if binary is not None:
        b = bytes(binary) + b"\0" * (-len(binary) % 4)
        chunks += struct.pack("<II", len(b), 0x004E4942) + b
    return b"glTF" + struct.pack("<II", 2, 12 + len(chunks)) + chunks


# ------------------------------------------------------------------------------------------
# the corpus
# ------------------------------------------------------------------------------------------


class _Writer:
    def __init__(self, root: Path) -> None:
        self.root = root
        self.cases: list[Case] = []

    def add(
        self,
        category: str,
        name: str,
        ext: str,
        data: bytes | str,
        family: str = "gltf",
        base_tris: int | None = None,
        extra: dict[str, bytes | str] | None = None,
        file_name: str | None = None,
    ) -> Path:
        name = f"{category}-{name}"
        folder = self.root / name
        folder.mkdir(parents=True, exist_ok=False)
        path = folder / (file_name or f"{name}{ext}")
        _write(path, data)
        for rel, content in (extra or {}).items():
            target = folder / rel
            target.parent.mkdir(parents=True, exist_ok=True)
            _write(target, content)
        self.cases.append(Case(name, path, family, category, base_tris))
        return path

    def glb(self, category: str, name: str, doc: dict[str, Any], binary: bytes | None, **kw: Any):
        return self.add(category, name, ".glb", glb_bytes(doc, binary), **kw)

    def gltf(self, category: str, name: str, doc: dict[str, Any] | str | bytes, **kw: Any) -> Path:
        text = doc if isinstance(doc, (str, bytes)) else json.dumps(doc)
        return self.add(category, name, ".gltf", text, **kw)


def _write(path: Path, data: bytes | str) -> None:
    if isinstance(data, str):
        path.write_text(data, encoding="utf-8")
    else:
        path.write_bytes(data)


def _set(doc: dict[str, Any], where: str, value: Any) -> dict[str, Any]:
    """A copy of ``doc`` with the field at ``where`` ('a.0.b') set to ``value``."""
    out = copy.deepcopy(doc)
    node: Any = out
    keys = [int(k) if k.isdigit() else k for k in where.split(".")]
    for k in keys[:-1]:
        node = node[k]
    node[keys[-1]] = value
    return out


def _del(doc: dict[str, Any], where: str) -> dict[str, Any]:
    out = copy.deepcopy(doc)
    node: Any = out
    keys = [int(k) if k.isdigit() else k for k in where.split(".")]
    for k in keys[:-1]:
        node = node[k]
    del node[keys[-1]]
    return out


TYPED_FIELDS = (
    "asset",
    "asset.version",
    "scene",
    "scenes",
    "scenes.0.nodes",
    "nodes",
    "nodes.0",
    "nodes.0.mesh",
    "nodes.0.children",
    "nodes.0.matrix",
    "nodes.0.translation",
    "nodes.0.rotation",
    "nodes.0.scale",
    "meshes",
    "meshes.0.primitives",
    "meshes.0.primitives.0",
    "meshes.0.primitives.0.attributes",
    "meshes.0.primitives.0.attributes.POSITION",
    "meshes.0.primitives.0.attributes.TEXCOORD_0",
    "meshes.0.primitives.0.indices",
    "meshes.0.primitives.0.mode",
    "meshes.0.primitives.0.material",
    "accessors",
    "accessors.0.count",
    "accessors.0.componentType",
    "accessors.0.type",
    "accessors.0.bufferView",
    "accessors.1.byteOffset",
    "accessors.1.min",
    "accessors.1.normalized",
    "bufferViews",
    "bufferViews.1.byteLength",
    "bufferViews.1.byteOffset",
    "bufferViews.1.byteStride",
    "bufferViews.1.buffer",
    "buffers",
    "buffers.0.byteLength",
    "materials.0.pbrMetallicRoughness",
    "materials.0.pbrMetallicRoughness.baseColorFactor",
    "materials.0.pbrMetallicRoughness.baseColorTexture",
    "materials.0.pbrMetallicRoughness.baseColorTexture.index",
    "materials.0.pbrMetallicRoughness.baseColorTexture.texCoord",
    "materials.0.alphaMode",
    "materials.0.doubleSided",
    "textures.0.source",
    "textures.0.sampler",
    "samplers.0.wrapS",
    "images.0.bufferView",
    "images.0.mimeType",
    "extensionsUsed",
)
WRONG_VALUES = (("str", "x"), ("obj", {"a": 1}), ("null", None), ("neg", -7))


def build(root: Path) -> list[Case]:
    """Write the corpus under ``root`` (which must not hold it yet); every case, named."""
    w = _Writer(root)
    base = box_doc()
    doc, binary = base.json, bytes(base.bin)
    good = glb_bytes(doc, binary)
    w.add("valid", "box", ".glb", good, base_tris=BOX_TRIS)
    _glb_damage(w, doc, binary, good)
    _gltf_types(w, doc, binary)
    _gltf_counts_and_ranges(w, doc, binary)
    _gltf_numbers(w, doc, binary)
    _gltf_structure(w, doc, binary)
    _gltf_files_and_uris(w, doc, binary)
    _gltf_extensions_and_modes(w, doc, binary)
    _images(w)
    _generic(w)
    _obj(w)
    _ply(w)
    return w.cases


def _glb_damage(w: _Writer, doc: dict[str, Any], binary: bytes, good: bytes) -> None:
    n = len(good)
    json_len = struct.unpack_from("<I", good, 12)[0]
    marks = {0, 1, 4, 8, 11, 12, 16, 19, 20, 21, 20 + json_len - 1, 20 + json_len}
    marks |= {20 + json_len + k for k in (4, 7, 8, 9)}
    for bv in doc["bufferViews"]:
        marks.add(28 + json_len + bv["byteOffset"])
        marks.add(28 + json_len + bv["byteOffset"] + bv["byteLength"] // 2)
    marks |= set(np.linspace(0, n - 1, 40).astype(int).tolist())
    for cut in sorted(m for m in marks if 0 <= m < n):
        w.add("glb-truncated", f"at{cut:05d}", ".glb", good[:cut], base_tris=BOX_TRIS)
    for pos in sorted(set(np.linspace(0, n - 1, 48).astype(int).tolist()) | {5, 9, 13, 17}):
        damaged = bytearray(good)
        damaged[pos] ^= 0xFF
        w.add("glb-flipped", f"at{pos:05d}", ".glb", bytes(damaged), base_tris=BOX_TRIS)
    bin_at = 20 + json_len

    def patch(offset: int, value: int) -> bytes:
        out = bytearray(good)
        struct.pack_into("<I", out, offset, value & 0xFFFFFFFF)
        return bytes(out)

    for label, value in (
        ("plus1", json_len + 1),
        ("minus1", json_len - 1),
        ("zero", 0),
        ("huge", 0xFFFFFFF0),
        ("past-end", n),
    ):
        w.add("glb-chunk-length", f"json-{label}", ".glb", patch(12, value))
    bin_len = struct.unpack_from("<I", good, bin_at)[0]
    for label, value in (
        ("plus4", bin_len + 4),
        ("minus4", bin_len - 4),
        ("zero", 0),
        ("huge", 0xFFFFFFF0),
    ):
        w.add("glb-chunk-length", f"bin-{label}", ".glb", patch(bin_at, value), base_tris=BOX_TRIS)
    for label, value in (("short", n - 8), ("long", n + 100), ("zero", 0), ("huge", 0xFFFFFFFF)):
        w.add("glb-chunk-length", f"total-{label}", ".glb", patch(8, value), base_tris=BOX_TRIS)
    w.add("glb-chunk-length", "bin-type-wrong", ".glb", patch(bin_at + 4, 0x12345678))
    w.add("glb-chunk-length", "json-type-wrong", ".glb", patch(16, 0x004E4942))
    w.add("glb-chunk-length", "version-1", ".glb", patch(4, 1))
    w.add("glb-chunk-length", "version-3", ".glb", patch(4, 3))
    w.add("glb-chunk-length", "no-bin-chunk", ".glb", glb_bytes(doc, None))
    unknown = struct.pack("<II", 8, 0x41414141) + b"ABCDEFGH"
    extra = good + unknown
    extra = extra[:8] + struct.pack("<I", len(extra)) + extra[12:]
    w.add("glb-chunk-length", "unknown-chunk-after", ".glb", extra, base_tris=BOX_TRIS)
    w.add("glb-chunk-length", "json-not-utf8", ".glb", glb_bytes(b'{"asset":"\xff\xfe"}', binary))
    w.add("glb-chunk-length", "json-array", ".glb", glb_bytes("[1, 2, 3]", binary))
    w.add("glb-chunk-length", "json-empty", ".glb", glb_bytes("", binary))


def _gltf_types(w: _Writer, doc: dict[str, Any], binary: bytes) -> None:
    for field in TYPED_FIELDS:
        for label, value in WRONG_VALUES:
            w.glb(
                "gltf-type", f"{field.replace('.', '-')}-{label}", _set(doc, field, value), binary
            )
    for field in ("scenes", "nodes", "meshes", "accessors", "bufferViews", "materials", "images"):
        w.glb("gltf-type", f"{field}-missing", _del(doc, field), binary)
    w.glb("gltf-type", "asset-missing", _del(doc, "asset"), binary)
    w.glb("gltf-type", "count-float", _set(doc, "accessors.1.count", 24.5), binary)
    w.glb("gltf-type", "count-bool", _set(doc, "accessors.1.count", True), binary)
    w.glb("gltf-type", "mode-str-number", _set(doc, "meshes.0.primitives.0.mode", "4"), binary)


def _gltf_counts_and_ranges(w: _Writer, doc: dict[str, Any], binary: bytes) -> None:
    for field, values in {
        "accessors.0.count": (-36, 0, 2**31, 2**53, 10**30),
        "accessors.1.count": (-1, 0, 2**31, 2**32 + 24),
        "accessors.1.byteOffset": (-4, 2**31, 4),
        "bufferViews.1.byteLength": (-1, 0, 2**40),
        "bufferViews.1.byteOffset": (-4, 2**31, 10**6),
        "bufferViews.1.byteStride": (2, 3, 252, 256, 2**31),
        "buffers.0.byteLength": (-1, 0, 1, 2**40),
    }.items():
        for v in values:
            label = f"m{-v}" if v < 0 else str(v)
            w.glb("gltf-count", f"{field.replace('.', '-')}-{label}", _set(doc, field, v), binary)
    for field, v in (
        ("meshes.0.primitives.0.attributes.POSITION", 99),
        ("meshes.0.primitives.0.indices", 99),
        ("meshes.0.primitives.0.material", 99),
        ("accessors.1.bufferView", 99),
        ("bufferViews.1.buffer", 99),
        ("nodes.0.mesh", 99),
        ("scenes.0.nodes", [99]),
        ("scene", 99),
        ("nodes.0.children", [99]),
        ("materials.0.pbrMetallicRoughness.baseColorTexture.index", 99),
        ("textures.0.source", 99),
        ("textures.0.sampler", 99),
        ("images.0.bufferView", 99),
        ("meshes.0.primitives.0.attributes.POSITION", 0),  # the indices as positions
        ("meshes.0.primitives.0.indices", 1),  # floats as indices
    ):
        w.glb("gltf-range", f"{field.replace('.', '-')}-{v}", _set(doc, field, v), binary)
    for label, values in (
        ("past-end", [0, 1, 24]),
        ("huge", [0, 1, 65535]),
        ("all-past-end", [100, 200, 300]),
    ):
        b = bytearray(binary)
        idx = np.frombuffer(bytes(b[:72]), np.uint16).copy()
        idx[: len(values)] = values
        b[:72] = idx.tobytes()
        w.glb("gltf-range", f"index-values-{label}", doc, bytes(b), base_tris=BOX_TRIS)
    u32 = _set(doc, "accessors.0.componentType", 5125)
    u32 = _set(u32, "accessors.0.count", 18)
    w.glb("gltf-range", "indices-reinterpreted-u32", u32, binary)
    w.glb("gltf-range", "indices-float-type", _set(doc, "accessors.0.componentType", 5126), binary)
    w.glb(
        "gltf-range", "componentType-unknown", _set(doc, "accessors.1.componentType", 1234), binary
    )
    w.glb("gltf-range", "type-unknown", _set(doc, "accessors.1.type", "VEC7"), binary)
    w.glb("gltf-range", "type-mat4-positions", _set(doc, "accessors.1.type", "MAT4"), binary)


def _gltf_numbers(w: _Writer, doc: dict[str, Any], binary: bytes) -> None:
    pos_off = doc["bufferViews"][1]["byteOffset"]
    for label, value, which in (
        ("nan-one", np.nan, [0]),
        ("nan-all", np.nan, list(range(72))),
        ("inf-one", np.inf, [3]),
        ("neginf-some", -np.inf, [5, 10, 20]),
        ("huge", 3e38, [0, 4, 8]),
        ("denormal", 1e-42, list(range(72))),
    ):
        b = bytearray(binary)
        arr = np.frombuffer(bytes(b[pos_off : pos_off + 288]), np.float32).copy()
        arr[which] = value
        b[pos_off : pos_off + 288] = arr.tobytes()
        w.glb("gltf-number", f"positions-{label}", doc, bytes(b))
    nan, inf = float("nan"), float("inf")
    ident = [1.0, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]
    for label, field, value in (
        ("matrix-nan", "nodes.0.matrix", [nan] + ident[1:]),
        ("matrix-inf", "nodes.0.matrix", ident[:12] + [inf, 0, 0, 1]),
        ("matrix-zero", "nodes.0.matrix", [0.0] * 16),
        ("matrix-short", "nodes.0.matrix", ident[:9]),
        ("matrix-projective", "nodes.0.matrix", ident[:3] + [5.0] + ident[4:]),
        (
            "matrix-huge",
            "nodes.0.matrix",
            [1e300, 0, 0, 0, 0, 1e300, 0, 0, 0, 0, 1e300, 0, 0, 0, 0, 1],
        ),
        ("translation-nan", "nodes.0.translation", [nan, 0, 0]),
        ("translation-inf", "nodes.0.translation", [0, inf, 0]),
        ("translation-far", "nodes.0.translation", [1e7, 0, 1e7]),
        ("rotation-nan", "nodes.0.rotation", [nan, 0, 0, 1]),
        ("rotation-zero", "nodes.0.rotation", [0, 0, 0, 0]),
        ("rotation-unnormalized", "nodes.0.rotation", [0, 0, 3, 4]),
        ("scale-zero", "nodes.0.scale", [0, 0, 0]),
        ("scale-negative", "nodes.0.scale", [-1, 1, 1]),
        ("scale-inf", "nodes.0.scale", [inf, 1, 1]),
        ("scale-huge", "nodes.0.scale", [1e30, 1e30, 1e30]),
        ("color-nan", "materials.0.pbrMetallicRoughness.baseColorFactor", [nan, 0, 0, 1]),
        ("color-out-of-range", "materials.0.pbrMetallicRoughness.baseColorFactor", [9, -3, 0, 7]),
    ):
        w.glb("gltf-number", label, _set(doc, field, value), binary)


def _deep(depth: int, inner: str = "1") -> str:
    return '{"a":' * depth + inner + "}" * depth


def _gltf_structure(w: _Writer, doc: dict[str, Any], binary: bytes) -> None:
    cyc = _set(doc, "nodes", [{"mesh": 0, "children": [1]}, {"mesh": 0, "children": [0]}])
    w.glb("gltf-structure", "node-cycle", cyc, binary)
    w.glb("gltf-structure", "node-self-child", _set(doc, "nodes.0.children", [0]), binary)
    dag = _set(doc, "nodes", [{"children": [1, 1]}, {"mesh": 0}])
    w.glb("gltf-structure", "node-child-twice", dag, binary)
    shared = _set(doc, "nodes", [{"children": [2]}, {"children": [2]}, {"mesh": 0}])
    w.glb("gltf-structure", "node-two-parents", _set(shared, "scenes.0.nodes", [0, 1]), binary)
    for depth in (1000, 10000):
        chain = [{"children": [i + 1], "translation": [0.0, 0.0, 0.0]} for i in range(depth)]
        chain.append({"mesh": 0})
        w.glb("gltf-structure", f"node-chain-{depth}", _set(doc, "nodes", chain), binary)
    wide = [{"children": list(range(1, 10001))}] + [{"mesh": 0}] * 10000
    w.glb("gltf-structure", "node-10000-children", _set(doc, "nodes", wide), binary)
    for depth in (1000, 10000):
        text = json.dumps(_set(doc, "extras", "@@")).replace('"@@"', _deep(depth))
        w.glb("gltf-structure", f"extras-nested-{depth}", text, binary)  # type: ignore[arg-type]
        text = json.dumps(_set(doc, "extras", "@@")).replace('"@@"', "[" * depth + "]" * depth)
        w.glb("gltf-structure", f"extras-arrays-{depth}", text, binary)  # type: ignore[arg-type]
    node_extras = json.dumps(_set(doc, "nodes.0.extras", "@@")).replace('"@@"', _deep(10000))
    w.glb("gltf-structure", "node-extras-nested-10000", node_extras, binary)  # type: ignore[arg-type]
    w.glb("gltf-structure", "scenes-empty", _set(doc, "scenes", []), binary)
    w.glb("gltf-structure", "scene-no-nodes", _set(doc, "scenes.0.nodes", []), binary)
    w.glb("gltf-structure", "no-scene-field", _del(doc, "scene"), binary, base_tris=BOX_TRIS)
    w.glb("gltf-structure", "primitives-empty", _set(doc, "meshes.0.primitives", []), binary)
    w.glb(
        "gltf-structure",
        "attributes-empty",
        _set(doc, "meshes.0.primitives.0.attributes", {}),
        binary,
    )
    many = _set(doc, "meshes.0.primitives", doc["meshes"][0]["primitives"] * 2000)
    w.glb("gltf-structure", "primitives-2000", many, binary)
    w.glb(
        "gltf-structure",
        "duplicate-keys",
        json.dumps(doc)[:-1] + ', "asset": {"version": "2.0"}}',
        binary,
    )  # type: ignore[arg-type]
    w.glb("gltf-structure", "json-bom", "\ufeff" + json.dumps(doc), binary)  # type: ignore[arg-type]
    w.glb("gltf-structure", "json-nan-literal", json.dumps(doc)[:-1] + ', "extras": NaN}', binary)  # type: ignore[arg-type]
    w.glb("gltf-structure", "json-long-string", _set(doc, "nodes.0.name", "n" * 5_000_000), binary)


def _separate(doc: dict[str, Any], buffer_uri: str, image_uri: str) -> dict[str, Any]:
    """The GLB document as a .gltf one: the buffer and the image in files of their own."""
    out = _set(doc, "buffers.0.uri", buffer_uri)
    out["images"] = [{"uri": image_uri}]
    return out


def _gltf_files_and_uris(w: _Writer, doc: dict[str, Any], binary: bytes) -> None:
    png = png_bytes()
    files: dict[str, bytes | str] = {"Box.bin": binary, "tex.png": png}
    w.gltf(
        "gltf-file",
        "separate-valid",
        _separate(doc, "Box.bin", "tex.png"),
        extra=files,
        base_tris=BOX_TRIS,
    )
    w.gltf("gltf-file", "buffer-missing", _separate(doc, "gone.bin", "tex.png"), extra=files)
    w.gltf("gltf-file", "image-missing", _separate(doc, "Box.bin", "gone.png"), extra=files)
    w.gltf(
        "gltf-file",
        "buffer-no-uri",
        _del(_separate(doc, "Box.bin", "tex.png"), "buffers.0.uri"),
        extra=files,
    )
    w.gltf(
        "gltf-file",
        "buffer-short",
        _separate(doc, "short.bin", "tex.png"),
        extra={"short.bin": binary[:100], "tex.png": png},
    )
    w.gltf(
        "gltf-file",
        "buffer-empty",
        _separate(doc, "empty.bin", "tex.png"),
        extra={"empty.bin": b"", "tex.png": png},
    )
    w.gltf(
        "gltf-file",
        "buffer-is-folder",
        _separate(doc, "sub", "tex.png"),
        extra={"sub/x": b"", "tex.png": png},
    )
    w.gltf(
        "gltf-file",
        "image-garbage",
        _separate(doc, "Box.bin", "bad.png"),
        extra={"Box.bin": binary, "bad.png": b"\x89PNG garbage" * 10},
    )
    w.gltf(
        "gltf-file",
        "image-is-obj",
        _separate(doc, "Box.bin", "x.obj"),
        extra={"Box.bin": binary, "x.obj": "v 0 0 0\n"},
    )
    w.gltf(
        "gltf-file",
        "json-truncated",
        json.dumps(_separate(doc, "Box.bin", "tex.png"))[:300],
        extra=files,
    )
    w.gltf(
        "gltf-file",
        "json-latin1",
        json.dumps(_set(_separate(doc, "Box.bin", "tex.png"), "nodes.0.name", "@@"))
        .encode()
        .replace(b"@@", b"caf\xe9"),
        extra=files,
    )
    w.gltf(
        "gltf-file",
        "json-utf16",
        json.dumps(_separate(doc, "Box.bin", "tex.png")).encode("utf-16"),
        extra=files,
    )
    for label, uri in (
        ("dotdot", "../x.bin"),
        ("dotdot-deep", "../../../../../../../../etc/passwd"),
        ("etc-passwd", "/etc/passwd"),
        ("file-url", "file:///etc/hosts"),
        ("http", "http://example.com/x.bin"),
        ("https-ip", "https://10.255.255.1/x.bin"),
        ("unc", "\\\\server\\share\\x.bin"),
        ("windows-drive", "C:\\x.bin"),
        ("dev-zero", "/dev/zero"),
        ("dev-urandom", "/dev/urandom"),
        ("proc-self", "/proc/self/mem"),
        ("empty", ""),
        ("space-only", " "),
        ("nul-byte", "Box\u0000.bin"),
        ("very-long", "a" * 5000 + ".bin"),
        ("query", "Box.bin?x=1"),
    ):
        w.gltf("gltf-uri", f"buffer-{label}", _separate(doc, uri, "tex.png"), extra=files)
    (w.root / "x.bin").write_bytes(binary)
    for label, uri in (
        ("dotdot", "../tex.png"),
        ("etc-passwd", "/etc/passwd"),
        ("file-url", "file:///etc/hosts"),
        ("http", "http://example.com/x.png"),
        ("dev-zero", "/dev/zero"),
    ):
        w.gltf("gltf-uri", f"image-{label}", _separate(doc, "Box.bin", uri), extra=files)
    b64 = base64.b64encode(binary).decode()
    for label, uri in (
        ("valid", "data:application/octet-stream;base64," + b64),
        ("no-comma", "data:application/octet-stream;base64"),
        ("bad-chars", "data:application/octet-stream;base64,!!!!" + b64[4:]),
        ("bad-padding", "data:application/octet-stream;base64," + b64[:-3]),
        ("not-base64", "data:application/octet-stream," + "%00" * 10),
        ("empty", "data:application/octet-stream;base64,"),
        ("wrong-mime", "data:text/plain;base64," + b64),
        ("short", "data:application/octet-stream;base64," + base64.b64encode(binary[:50]).decode()),
        ("bare", "data:"),
    ):
        extra = {"tex.png": png}
        w.gltf(
            "gltf-data-uri",
            f"buffer-{label}",
            _separate(doc, uri, "tex.png"),
            extra=extra,
            base_tris=BOX_TRIS if label == "valid" else None,
        )
    for label, uri in (
        ("valid", "data:image/png;base64," + base64.b64encode(png).decode()),
        ("garbage", "data:image/png;base64," + base64.b64encode(b"garbage").decode()),
        ("bad-chars", "data:image/png;base64,@@@@"),
        ("no-comma", "data:image/png"),
    ):
        w.gltf("gltf-data-uri", f"image-{label}", _separate(doc, "Box.bin", uri), extra=files)
    pct = {"Box .bin": binary, "tex ure.png": png}
    w.gltf(
        "gltf-uri",
        "percent-encoded",
        _separate(doc, "Box%20.bin", "tex%20ure.png"),
        extra=pct,
        base_tris=BOX_TRIS,
    )
    w.gltf("gltf-uri", "percent-bad", _separate(doc, "Box%zz.bin", "tex.png"), extra=files)
    w.gltf(
        "gltf-uri",
        "unicode-name",
        _separate(doc, "K%C3%B6rper.bin", "tex.png"),
        extra={"Körper.bin": binary, "tex.png": png},
    )


def _sparse_doc(doc: dict[str, Any], binary: bytes, idx: list[int], count: int | None = None):
    d = box_doc()
    i_view = d.view(np.array(idx, np.uint16).tobytes())
    # each moved vertex keeps its x and z and rises by 1.5 m (vertex 0, a top corner, to y = 2;
    # no triangle collapses)
    pos = _box()[0]
    values = np.asarray(pos, np.float32)[np.clip(idx, 0, len(pos) - 1)].copy()
    values[:, 1] += 1.5
    v_view = d.view(values.tobytes())
    d.json["accessors"][1]["sparse"] = {
        "count": len(idx) if count is None else count,
        "indices": {"bufferView": i_view, "componentType": 5123},
        "values": {"bufferView": v_view},
    }
    return d.json, bytes(d.bin)


def _strip_doc(mode: int) -> tuple[dict[str, Any], bytes]:
    """Six vertices drawn as a strip (a zig-zag band) or a fan (a hexagon): 4 triangles."""
    if mode == 5:
        pts = [(x * 0.5, y, 0.0) for x in range(3) for y in (0.0, 1.0)]
    else:
        ang = np.linspace(0, 2 * np.pi, 7)[:6]
        pts = [(float(np.cos(a)), float(np.sin(a)), 0.0) for a in ang]
    d = Doc()
    i_pos = d.accessor(np.array(pts, np.float32), "VEC3", 34962)
    d.json.update(
        scene=0,
        scenes=[{"nodes": [0]}],
        nodes=[{"mesh": 0}],
        meshes=[{"primitives": [{"attributes": {"POSITION": i_pos}, "mode": mode}]}],
    )
    return d.json, bytes(d.bin)


def _gltf_extensions_and_modes(w: _Writer, doc: dict[str, Any], binary: bytes) -> None:
    for label, ext in (
        ("unknown", "EXT_made_up"),
        ("draco", "KHR_draco_mesh_compression"),
        ("meshopt", "EXT_meshopt_compression"),
        ("basisu", "KHR_texture_basisu"),
        ("quantization", "KHR_mesh_quantization"),
        ("transform", "KHR_texture_transform"),
    ):
        req = _set(doc, "extensionsRequired", [ext])
        req["extensionsUsed"] = [ext]
        w.glb("gltf-ext", f"required-{label}", req, binary)
        w.glb(
            "gltf-ext",
            f"used-{label}",
            _set(doc, "extensionsUsed", [ext]),
            binary,
            base_tris=BOX_TRIS,
        )
    draco = _set(doc, "extensionsRequired", ["KHR_draco_mesh_compression"])
    draco["extensionsUsed"] = ["KHR_draco_mesh_compression"]
    draco["meshes"][0]["primitives"][0]["extensions"] = {
        "KHR_draco_mesh_compression": {"bufferView": 4, "attributes": {"POSITION": 0}}
    }
    w.glb("gltf-ext", "draco-garbage-data", draco, binary)
    fallback = _del(draco, "extensionsRequired")
    w.glb("gltf-ext", "draco-with-fallback", fallback, binary, base_tris=BOX_TRIS)
    mo = _set(doc, "extensionsUsed", ["EXT_meshopt_compression"])
    mo["bufferViews"][1]["extensions"] = {
        "EXT_meshopt_compression": {
            "buffer": 0,
            "byteOffset": 0,
            "byteLength": 10,
            "byteStride": 12,
            "mode": "ATTRIBUTES",
            "count": 24,
        }
    }
    w.glb("gltf-ext", "meshopt-with-fallback", mo, binary, base_tris=BOX_TRIS)
    w.glb(
        "gltf-ext",
        "extensionsRequired-string",
        _set(doc, "extensionsRequired", "EXT_made_up"),
        binary,
    )
    w.glb("gltf-ext", "min-version-2-1", _set(doc, "asset.minVersion", "2.1"), binary)
    w.glb(
        "gltf-ext",
        "min-version-2-0",
        _set(doc, "asset.minVersion", "2.0"),
        binary,
        base_tris=BOX_TRIS,
    )
    w.glb("gltf-ext", "version-3-0", _set(doc, "asset.version", "3.0"), binary)
    w.glb("gltf-ext", "version-1-0", _set(doc, "asset.version", "1.0"), binary)
    w.glb("gltf-ext", "version-2-5", _set(doc, "asset.version", "2.5"), binary)
    for label, idx, count in (
        ("valid", [0, 1], None),
        ("index-past-end", [0, 999], None),
        ("count-huge", [0, 1], 2**31),
        ("count-negative", [0, 1], -1),
    ):
        sdoc, sbin = _sparse_doc(doc, binary, idx, count)
        w.glb("gltf-sparse", label, sdoc, sbin, base_tris=BOX_TRIS if label == "valid" else None)
    sdoc, sbin = _sparse_doc(doc, binary, [0, 1])
    del sdoc["accessors"][1]["bufferView"]  # sparse on zeros
    w.glb("gltf-sparse", "no-bufferView", sdoc, sbin)
    for mode, label in ((5, "strip"), (6, "fan")):
        sdoc, sbin = _strip_doc(mode)
        w.glb("gltf-mode", label, sdoc, sbin, base_tris=4)
        sdoc["meshes"][0]["primitives"][0]["mode"] = 4
        w.glb("gltf-mode", f"{label}-as-triangles", sdoc, sbin)  # 6 vertices: 2 triangles
    for mode, label in (
        (0, "points"),
        (1, "lines"),
        (2, "line-loop"),
        (3, "line-strip"),
        (7, "seven"),
        (-1, "negative"),
    ):
        w.glb("gltf-mode", label, _set(doc, "meshes.0.primitives.0.mode", mode), binary)
    w.glb("gltf-mode", "indices-not-multiple-of-3", _set(doc, "accessors.0.count", 35), binary)
    w.glb("gltf-mode", "no-indices", _del(doc, "meshes.0.primitives.0.indices"), binary)


def _png_chunk(kind: bytes, data: bytes) -> bytes:
    return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))


def _png_header_bomb(width: int, height: int) -> bytes:
    ihdr = struct.pack(">IIBBBBB", width, height, 8, 6, 0, 0, 0)
    idat = zlib.compress(b"\0" * 1024)
    return (
        b"\x89PNG\r\n\x1a\n"
        + _png_chunk(b"IHDR", ihdr)
        + _png_chunk(b"IDAT", idat)
        + _png_chunk(b"IEND", b"")
    )


def _png_zlib_bomb(side: int) -> bytes:
    """A real PNG of side x side zero pixels: a few KB that inflate to side*side*4 bytes."""
    ihdr = struct.pack(">IIBBBBB", side, side, 8, 6, 0, 0, 0)
    comp = zlib.compressobj(9)
    row = b"\0" * (side * 4 + 1)
    data = b"".join(comp.compress(row) for _ in range(side)) + comp.flush()
    return (
        b"\x89PNG\r\n\x1a\n"
        + _png_chunk(b"IHDR", ihdr)
        + _png_chunk(b"IDAT", data)
        + _png_chunk(b"IEND", b"")
    )


def _jpeg_header_bomb(width: int, height: int) -> bytes:
    sof = struct.pack(">BHHB", 8, height, width, 3) + b"\x01\x11\x00\x02\x11\x00\x03\x11\x00"
    return b"\xff\xd8" + b"\xff\xc0" + struct.pack(">H", len(sof) + 2) + sof + b"\xff\xd9"


def _image(mode: str, size: tuple[int, int], fmt: str = "PNG", **kw: Any) -> bytes:
    from PIL import Image

    img = Image.new(mode, size)
    buf = io.BytesIO()
    img.save(buf, format=fmt, **kw)
    return buf.getvalue()


def _images(w: _Writer) -> None:
    png = png_bytes()
    for label, data, mime in (
        ("png-header-bomb-100000", _png_header_bomb(100000, 100000), "image/png"),
        ("png-header-bomb-12000", _png_header_bomb(12000, 12000), "image/png"),
        ("png-header-bomb-wide", _png_header_bomb(2**31 - 1, 1), "image/png"),
        ("png-zlib-bomb-6000", _png_zlib_bomb(6000), "image/png"),
        ("jpeg-header-bomb-65500", _jpeg_header_bomb(65500, 65500), "image/jpeg"),
        ("jpeg-header-bomb-12000", _jpeg_header_bomb(12000, 12000), "image/jpeg"),
        ("png-1x1", png_bytes((1, 1)), "image/png"),
        ("png-16bit", _image("I;16", (4, 4)), "image/png"),
        ("png-palette", _image("P", (4, 4), transparency=0), "image/png"),
        ("png-grey-alpha", _image("LA", (4, 4)), "image/png"),
        ("png-1bit", _image("1", (5, 3)), "image/png"),
        ("png-rgba", png_bytes((4, 4), "RGBA"), "image/png"),
        ("jpeg-cmyk", _image("CMYK", (4, 4), "JPEG"), "image/jpeg"),
        ("jpeg-grey", _image("L", (4, 4), "JPEG"), "image/jpeg"),
        ("jpeg-progressive", _image("RGB", (16, 16), "JPEG", progressive=True), "image/jpeg"),
        ("gif-as-png", _image("P", (4, 4), "GIF"), "image/png"),
        ("png-as-jpeg", png, "image/jpeg"),
        ("png-truncated", png[: len(png) // 2], "image/png"),
        ("png-crc-wrong", png[:-5] + b"\0" + png[-4:], "image/png"),
        ("garbage", b"\x00\x01garbage" * 20, "image/png"),
        ("empty", b"", "image/png"),
        ("ktx2-mime", b"\xabKTX 20\xbb\r\n\x1a\n" + b"\0" * 64, "image/ktx2"),
        ("webp", _image("RGB", (4, 4), "WEBP"), "image/webp"),
    ):
        d = box_doc(data)
        d.json["images"][0]["mimeType"] = mime
        w.glb("image", label, d.json, bytes(d.bin), base_tris=BOX_TRIS)


def _generic(w: _Writer) -> None:
    rng = np.random.default_rng(12)
    for ext in (".glb", ".gltf", ".obj", ".ply"):
        family = "gltf" if ext in (".glb", ".gltf") else "objply"
        tag = ext.lstrip(".")
        w.add("generic", f"{tag}-empty", ext, b"", family)
        w.add("generic", f"{tag}-one-byte", ext, b"\0", family)
        w.add(
            "generic",
            f"{tag}-garbage",
            ext,
            rng.integers(0, 256, 4096, dtype=np.uint8).tobytes(),
            family,
        )
        w.add("generic", f"{tag}-zeros", ext, b"\0" * 4096, family)
        w.add("generic", f"{tag}-text", ext, "hello, this is not a model\n", family)
        w.add("generic", f"{tag}-png", ext, png_bytes(), family)
    tri = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"
    box = glb_bytes(box_doc().json, bytes(box_doc().bin))
    for label, file_name in (
        ("latin1", os.fsdecode(b"caf\xe9 cr\xe8me")),
        ("unicode-spaces", "Körper Ü 模型"),
        ("leading-dash", "-x"),
    ):
        w.add(
            "name", f"obj-{label}", ".obj", tri, "objply", file_name=file_name + ".obj", base_tris=1
        )
        ply = _ply_header("ascii", 3, 1) + b"0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n"
        w.add(
            "name", f"ply-{label}", ".ply", ply, "objply", file_name=file_name + ".ply", base_tris=1
        )
        w.add("name", f"glb-{label}", ".glb", box, file_name=file_name + ".glb", base_tris=BOX_TRIS)
    w.add("generic", "gltf-number-json", ".gltf", "42")
    w.add("generic", "gltf-empty-object", ".gltf", "{}")
    w.add("generic", "gltf-null", ".gltf", "null")
    w.add("generic", "glb-magic-only", ".glb", b"glTF")
    w.add(
        "generic",
        "GLB-upper-ext",
        ".GLB",
        glb_bytes(box_doc().json, bytes(box_doc().bin)),
        base_tris=BOX_TRIS,
    )
    w.add("generic", "obj-named-glb", ".glb", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    w.add(
        "generic",
        "glb-named-obj",
        ".obj",
        glb_bytes(box_doc().json, bytes(box_doc().bin)),
        "objply",
    )


TRI = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\n"


def _obj(w: _Writer) -> None:
    def obj(
        name: str,
        text: str | bytes,
        extra: dict[str, bytes | str] | None = None,
        base_tris: int | None = None,
    ) -> None:
        w.add("obj", name, ".obj", text, "objply", base_tris=base_tris, extra=extra)

    obj("valid", TRI + "f 1 2 3\nf 1 2 4\n", base_tris=2)
    obj("vertex-one-number", "v 0 0 0\nv 1\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 4\nf 1 3 5\n")
    obj("vertex-two-numbers", "v 0 0 0\nv 1 2\nv 1 0 0\nv 0 1 0\nf 1 3 4\nf 2 3 4\n")
    obj("vertex-empty", "v\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 2 3 4\n")
    obj("vertex-words", "v a b c\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 2 3 4\n")
    obj("vertex-nan-inf", "v nan 0 0\nv inf 0 0\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 3 4 5\nf 1 2 3\n")
    obj("vertex-huge", "v 1e300 0 0\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 2 3 4\nf 1 2 3\n")
    obj("vertex-colors", "v 0 0 0 1 0 0\nv 1 0 0 0 1 0\nv 0 1 0 0 0 1\nf 1 2 3\n", base_tris=1)
    obj("vertex-mixed-lengths", "v 0 0 0 1 0 0\nv 1 0 0\nv 0 1 0 0 0 1 1\nf 1 2 3\n")
    obj("face-missing-vertex", TRI + "f 1 2 3\nf 1 2 9\n")
    obj("face-all-missing", TRI + "f 7 8 9\n")
    obj("face-huge-index", TRI + "f 1 2 3\nf 1 2 99999999999\n")
    obj("face-huge-index-64bit", TRI + "f 1 2 3\nf 1 2 99999999999999999999999\n")
    obj("face-negative-relative", TRI + "f -4 -3 -2\nf -4 -3 -1\n", base_tris=2)
    obj("face-negative-too-far", TRI + "f 1 2 3\nf -100 -3 -2\n")
    obj("face-zero-index", TRI + "f 1 2 3\nf 0 1 2\n")
    obj("face-two-vertices", TRI + "f 1 2 3\nf 1 2\n")
    obj("face-one-vertex", TRI + "f 1\n")
    obj("face-words", TRI + "f 1 2 3\nf a b c\n")
    obj("face-polygon", TRI + "v 1 1 0\nf 1 2 5 3\n", base_tris=2)
    obj("face-uv-missing", TRI + "vt 0 0\nf 1/1 2/2 3/9\n")
    obj("face-normal-missing", TRI + "vn 0 0 1\nf 1//1 2//1 3//7\n")
    obj("face-slashes-only", TRI + "f 1/ 2// 3///\n")
    obj("only-vt-vn", "vt 0 0\nvn 0 0 1\n")
    obj("only-vertices", TRI)
    obj("lines-only", TRI + "l 1 2 3\n")
    obj("points-only", TRI + "p 1 2 3\n")
    obj("crlf", (TRI + "f 1 2 3\n").replace("\n", "\r\n"), base_tris=1)
    obj("cr-only", (TRI + "f 1 2 3\n").replace("\n", "\r"))
    obj("bom", "\ufeff" + TRI + "f 1 2 3\n", base_tris=1)
    obj("nul-bytes", TRI.encode() + b"f 1 2 3\n\0\0\0\n")
    obj("long-line", TRI + "# " + "x" * 2_000_000 + "\nf 1 2 3\n", base_tris=1)
    obj("utf16", (TRI + "f 1 2 3\n").encode("utf-16"))
    mtl_l1 = b"# Mat\xe9riaux\nnewmtl peinture_\xe9t\xe9\nKd 0.8 0.1 0.1\nmap_Kd caf\xe9.png\n"
    obj_l1 = (
        b"# export\xe9 par Windows\nmtllib mat\xe9riaux.mtl\n"
        + TRI.encode()
        + b"vt 0 0\nvt 1 0\nvt 0 1\nusemtl peinture_\xe9t\xe9\nf 1/1 2/2 3/3\n"
    )
    obj("latin1-comment", b"# caf\xe9 cr\xe8me\n" + TRI.encode() + b"f 1 2 3\n", base_tris=1)
    obj(
        "latin1-mtl-utf8-names",
        obj_l1,
        extra={"matériaux.mtl": mtl_l1, "café.png": png_bytes()},
        base_tris=1,
    )
    legacy = {os.fsdecode(b"mat\xe9riaux.mtl"): mtl_l1, os.fsdecode(b"caf\xe9.png"): png_bytes()}
    obj("latin1-mtl-latin1-names", obj_l1, extra=legacy, base_tris=1)
    obj("cp1252-quotes", b"# \x93quoted\x94 \x80\n" + TRI.encode() + b"f 1 2 3\n", base_tris=1)
    obj("mtl-missing", "mtllib gone.mtl\nusemtl x\n" + TRI + "f 1 2 3\n", base_tris=1)
    obj(
        "mtl-hostile-path",
        "mtllib ../../../../../../etc/passwd\nusemtl x\n" + TRI + "f 1 2 3\n",
        base_tris=1,
    )
    obj("mtl-absolute", "mtllib /etc/passwd\n" + TRI + "f 1 2 3\n", base_tris=1)
    obj("mtl-dev-zero", "mtllib /dev/zero\n" + TRI + "f 1 2 3\n", base_tris=1)
    obj(
        "mtl-garbage",
        "mtllib m.mtl\nusemtl a\n" + TRI + "f 1 2 3\n",
        extra={"m.mtl": b"\0\xff" * 500},
        base_tris=1,
    )
    obj(
        "mtl-bad-numbers",
        "mtllib m.mtl\nusemtl a\n" + TRI + "f 1 2 3\n",
        extra={"m.mtl": "newmtl a\nKd x y\nd nan\nNs -1\nmap_Kd\n"},
        base_tris=1,
    )
    obj(
        "mtl-texture-hostile",
        "mtllib m.mtl\nusemtl a\n" + TRI + "vt 0 0\nf 1/1 2/1 3/1\n",
        extra={"m.mtl": "newmtl a\nmap_Kd /etc/passwd\n"},
        base_tris=1,
    )
    obj(
        "mtl-texture-bomb",
        "mtllib m.mtl\nusemtl a\n" + TRI + "vt 0 0\nf 1/1 2/1 3/1\n",
        extra={
            "m.mtl": "newmtl a\nmap_Kd bomb.png\n",
            "bomb.png": _png_header_bomb(100000, 100000),
        },
        base_tris=1,
    )
    obj("usemtl-undefined", "usemtl nothing\n" + TRI + "f 1 2 3\n", base_tris=1)
    obj(
        "many-groups",
        "".join(f"o g{i}\nv 0 0 {i}\nv 1 0 {i}\nv 0 1 {i}\nf -3 -2 -1\n" for i in range(2000)),
        base_tris=2000,
    )


def _ply_header(fmt: str, nv: int | str, nf: int | str | None, comment: bytes = b"") -> bytes:
    h = b"ply\nformat " + fmt.encode() + b" 1.0\n" + comment
    h += (
        b"element vertex "
        + str(nv).encode()
        + b"\nproperty float x\nproperty float y\nproperty float z\n"
    )
    if nf is not None:
        h += b"element face " + str(nf).encode() + b"\nproperty list uchar int vertex_indices\n"
    return h + b"end_header\n"


def _ply_binary(
    order: str, verts: list[tuple[float, float, float]], faces: list[list[int]]
) -> bytes:
    f = "<" if order == "<" else ">"
    body = b"".join(struct.pack(f + "3f", *v) for v in verts)
    body += b"".join(
        struct.pack(f + "B", len(face)) + struct.pack(f + f"{len(face)}i", *face) for face in faces
    )
    return body


def _ply(w: _Writer) -> None:
    def ply(name: str, data: bytes, base_tris: int | None = None) -> None:
        w.add("ply", name, ".ply", data, "objply", base_tris=base_tris)

    verts = [(0.0, 0.0, 0.0), (1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0)]
    faces = [[0, 1, 2], [0, 1, 3]]
    ascii_body = b"".join(b"%g %g %g\n" % v for v in verts) + b"".join(
        b"3 %d %d %d\n" % tuple(f) for f in faces
    )
    le, be = "binary_little_endian", "binary_big_endian"
    ply("ascii-valid", _ply_header("ascii", 4, 2) + ascii_body, base_tris=2)
    ply("binary-valid", _ply_header(le, 4, 2) + _ply_binary("<", verts, faces), base_tris=2)
    ply("binary-be-valid", _ply_header(be, 4, 2) + _ply_binary(">", verts, faces), base_tris=2)
    ply("wrong-byte-order-le-data", _ply_header(be, 4, 2) + _ply_binary("<", verts, faces))
    ply("wrong-byte-order-be-data", _ply_header(le, 4, 2) + _ply_binary(">", verts, faces))
    ply(
        "face-index-out-of-range",
        _ply_header("ascii", 4, 2) + ascii_body.replace(b"3 0 1 3", b"3 0 1 7"),
    )
    ply(
        "face-index-negative",
        _ply_header("ascii", 4, 2) + ascii_body.replace(b"3 0 1 3", b"3 0 -5 3"),
    )
    ply(
        "face-index-huge-binary",
        _ply_header(le, 4, 2) + _ply_binary("<", verts, [[0, 1, 2], [0, 2**31 - 1, 3]]),
    )
    ply(
        "face-all-out-of-range",
        _ply_header(le, 4, 2) + _ply_binary("<", verts, [[9, 10, 11], [12, 13, 14]]),
    )
    ply("ascii-count-too-high", _ply_header("ascii", 40, 2) + ascii_body)
    ply("ascii-face-count-too-high", _ply_header("ascii", 4, 20) + ascii_body)
    ply("ascii-count-too-low", _ply_header("ascii", 3, 2) + ascii_body)
    ply("ascii-count-negative", _ply_header("ascii", -4, 2) + ascii_body)
    ply("ascii-count-words", _ply_header("ascii", "four", 2) + ascii_body)
    ply(
        "ascii-short-vertex-line",
        _ply_header("ascii", 4, 2) + ascii_body.replace(b"1 0 0\n", b"1\n", 1),
    )
    ply("ascii-words", _ply_header("ascii", 4, 2) + ascii_body.replace(b"0 1 0", b"a b c"))
    ply("ascii-nan", _ply_header("ascii", 4, 2) + ascii_body.replace(b"0 1 0", b"nan 1 0"))
    ply("binary-truncated", (_ply_header(le, 4, 2) + _ply_binary("<", verts, faces))[:-7])
    ply("binary-2e31-vertices", _ply_header(le, 2**31, None) + b"\0" * 800)
    ply("binary-2e31-faces", _ply_header(le, 4, 2**31) + _ply_binary("<", verts, faces))
    ply("ascii-2e31-vertices", _ply_header("ascii", 2**31, 2) + ascii_body)
    ply("binary-2e62-vertices", _ply_header(le, 2**62, 2) + _ply_binary("<", verts, faces))
    ply(
        "latin1-comment-ascii",
        _ply_header("ascii", 4, 2, b"comment export\xe9 par caf\xe9\n") + ascii_body,
        base_tris=2,
    )
    ply(
        "latin1-comment-binary",
        _ply_header(le, 4, 2, b"comment caf\xe9\nobj_info \xa9 2020\n")
        + _ply_binary("<", verts, faces),
        base_tris=2,
    )
    ply("no-end-header", _ply_header("ascii", 4, 2).replace(b"end_header\n", b"") + ascii_body)
    ply("unknown-format", _ply_header("binary_middle_endian", 4, 2) + ascii_body)
    ply(
        "unknown-property-type",
        _ply_header("ascii", 4, 2).replace(b"property float z", b"property quad z") + ascii_body,
    )
    ply(
        "list-count-huge",
        _ply_header(le, 4, 1) + _ply_binary("<", verts, []) + bytes([255]) + b"\0" * 12,
    )
    uint_list = _ply_header(le, 3, 2).replace(b"list uchar int", b"list uint int")
    tri3 = b"".join(struct.pack("<3f", *v) for v in verts[:3])
    three = struct.pack("<I3i", 3, 0, 1, 2)
    ply(
        "list-count-uint-max-second",
        uint_list + tri3 + three + struct.pack("<I", 2**32 - 1) + b"\0" * 16,
    )
    ply(
        "list-count-int-max-first",
        uint_list + tri3 + struct.pack("<I", 2**31 - 1) + b"\0" * 12 + three,
    )
    ply("points-only", _ply_header("ascii", 4, None) + ascii_body.split(b"3 0")[0])
    ply("header-only", _ply_header("ascii", 0, 0))
    ply(
        "quads",
        _ply_header("ascii", 4, 1) + ascii_body.split(b"3 0")[0] + b"4 0 1 3 2\n",
        base_tris=2,
    )
    ply("crlf", (_ply_header("ascii", 4, 2) + ascii_body).replace(b"\n", b"\r\n"))


# ------------------------------------------------------------------------------------------
# the worker: many files through the CLI in one process
# ------------------------------------------------------------------------------------------


class _CurrentStderr(logging.StreamHandler):  # type: ignore[type-arg]
    """A log handler writing to whatever ``sys.stderr`` is now (each file's capture)."""

    @property  # type: ignore[override]
    def stream(self) -> Any:
        return sys.stderr

    @stream.setter
    def stream(self, _value: Any) -> None:
        pass


def _worker(list_file: str, out_dir: str) -> int:
    import faulthandler

    proto = os.fdopen(os.dup(1), "w", buffering=1)
    os.dup2(2, 1)  # C libraries' stdout noise goes to stderr, not into the protocol
    faulthandler.enable(sys.__stderr__)
    root = logging.getLogger()
    handler = _CurrentStderr()
    handler.setFormatter(logging.Formatter("%(levelname)s %(name)s: %(message)s"))
    root.addHandler(handler)
    root.setLevel(logging.INFO)
    from app.lab import cli

    # Test hook for the runner itself: {"case name": "crash" | "hang"}.
    faults = json.loads(os.environ.get("VRPREVIEW_CORPUS_FAULTS", "{}"))
    for item in json.loads(Path(list_file).read_text()):
        name, path = item["name"], item["path"]
        print(json.dumps({"start": name}), file=proto, flush=True)
        if faults.get(name) == "crash":
            os.abort()
        if faults.get(name) == "hang":
            time.sleep(3600)
        out = Path(out_dir) / f"{name}.png"
        err, std = io.StringIO(), io.StringIO()
        start = time.perf_counter()
        result: dict[str, Any] = {"name": name}
        with contextlib.redirect_stderr(err), contextlib.redirect_stdout(std):
            try:
                rc = cli.main(["render", "--scene", path, "--out", str(out), "--size", SIZE])
            except SystemExit as exc:
                rc = exc.code if isinstance(exc.code, int) else 1
            except BaseException:  # noqa: BLE001 - what escapes main is the finding
                traceback.print_exc()
                rc = 1
            if rc == 0:
                try:
                    scene = read_scene(path)
                    result["tris"] = scene.triangle_count
                    result["warnings"] = list(scene.warnings)
                except Exception as exc:  # noqa: BLE001
                    result["reload_error"] = f"{type(exc).__name__}: {exc}"
        result.update(
            rc=rc,
            stderr=err.getvalue(),
            png=out.is_file() and out.stat().st_size > 0,
            seconds=round(time.perf_counter() - start, 3),
        )
        print(json.dumps(result), file=proto, flush=True)
        with contextlib.suppress(OSError):
            out.unlink()
    return 0


def worker_env() -> dict[str, str]:
    env = dict(os.environ)
    env["PYTHONPATH"] = str(REPO) + os.pathsep + env.get("PYTHONPATH", "")
    env.setdefault("PYTHONFAULTHANDLER", "1")
    return env


def run_corpus(
    cases: list[Case], work: Path, timeout_s: float = 60.0, workers: int = 1
) -> dict[str, dict[str, Any]]:
    """Every case's raw result (``outcome`` 'hang' or 'crash' when the worker did not answer)."""
    chunks = [cases[i::workers] for i in range(workers)]
    results: dict[str, dict[str, Any]] = {}
    lock = threading.Lock()

    def drive(k: int, todo: list[Case]) -> None:
        n = 0
        while todo:
            n += 1
            got = _run_worker(todo, work, f"{k}-{n}", timeout_s)
            with lock:
                results.update(got)
            todo = [c for c in todo if c.name not in got]

    threads = [threading.Thread(target=drive, args=(k, c)) for k, c in enumerate(chunks) if c]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    return results


def _run_worker(
    todo: list[Case], work: Path, tag: str, timeout_s: float
) -> dict[str, dict[str, Any]]:
    list_file = work / f"list-{tag}.json"
    list_file.write_text(json.dumps([{"name": c.name, "path": str(c.path)} for c in todo]))
    out_dir = work / "png"
    out_dir.mkdir(exist_ok=True)
    err_path = work / f"worker-{tag}.stderr"
    with open(err_path, "wb") as err_file:
        proc = subprocess.Popen(
            [sys.executable, str(Path(__file__).resolve()), "worker", str(list_file), str(out_dir)],
            stdout=subprocess.PIPE,
            stderr=err_file,
            env=worker_env(),
            cwd=work,
        )
        lines: queue.Queue[bytes | None] = queue.Queue()

        def read() -> None:
            assert proc.stdout is not None
            for line in proc.stdout:
                lines.put(line)
            lines.put(None)

        threading.Thread(target=read, daemon=True).start()
        got: dict[str, dict[str, Any]] = {}
        current: str | None = None
        while True:
            try:
                line = lines.get(timeout=timeout_s)
            except queue.Empty:
                proc.kill()
                proc.wait()
                if current is not None:
                    got[current] = {"name": current, "outcome": "hang", "stderr": ""}
                break
            if line is None:
                rc = proc.wait()
                if current is not None:
                    tail = err_path.read_bytes()[-3000:].decode("utf-8", "replace")
                    got[current] = {"name": current, "outcome": "crash", "rc": rc, "stderr": tail}
                break
            msg = json.loads(line)
            if "start" in msg:
                current = msg["start"]
            else:
                got[msg["name"]] = msg
                current = None
        if not got and not todo:
            return got
        if not got:  # the worker died before its first file: blame that file
            got[todo[0].name] = {
                "name": todo[0].name,
                "outcome": "crash",
                "rc": proc.returncode,
                "stderr": err_path.read_bytes()[-3000:].decode("utf-8", "replace"),
            }
    return got


def classify(case: Case, res: dict[str, Any]) -> tuple[str, str]:
    """(outcome, detail): loaded, refused, traceback, crash, hang, bad-exit or wrong-geometry."""
    if res.get("outcome") in ("hang", "crash"):
        return res["outcome"], str(res.get("stderr", ""))[-500:]
    stderr = str(res.get("stderr", ""))
    lines = [ln for ln in stderr.strip().splitlines() if ln.strip()]
    last = lines[-1] if lines else ""
    if "Traceback" in stderr:
        return "traceback", last
    rc = res.get("rc")
    if rc == 0 and res.get("png"):
        notes = [w for w in res.get("warnings", []) if LIGHTS_NOTE not in w]
        warned = bool(notes) or "WARNING" in stderr
        tris = res.get("tris")
        if "reload_error" in res:
            return "bad-exit", f"rendered, but load_scene then failed: {res['reload_error']}"
        if case.base_tris is not None and tris is not None and tris < case.base_tris and not warned:
            return "wrong-geometry", f"{tris} of {case.base_tris} triangles, no warning"
        return "loaded", "; ".join(notes)
    if rc == 2 and last.startswith("vrpreview: error:") and case.path.name in last:
        return "refused", last
    return "bad-exit", f"exit {rc}: {last}"


def main(argv: list[str]) -> int:
    if len(argv) == 3 and argv[0] == "worker":
        return _worker(argv[1], argv[2])
    if len(argv) == 2 and argv[0] == "build":
        cases = build(Path(argv[1]))
        print(f"{len(cases)} cases in {argv[1]}")
        return 0
    print("usage: corpus.py build FOLDER | corpus.py worker LIST OUT_DIR", file=sys.stderr)
    return 2


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
