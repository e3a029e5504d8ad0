"""The glTF reader's rules, each on a small file written here (numpy + json, no binaries kept).

Every test asserts what the person opening the file sees: the geometry that loaded, the warning
naming what was dropped, or the refusal naming the file and the problem.
"""

from __future__ import annotations

import base64
import dataclasses
import io
import json
import struct
import time
import zlib
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from PIL import Image

from app import loaders
from app.loaders import LoadOptions, SceneLoadError
from app.progress import LoadCancelled, Progress
from app.scene import Scene

QUAD = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], np.float32)
QUAD_IDX = np.array([0, 1, 2, 0, 2, 3], np.uint16)
QUAD_UV = np.array([[0, 1], [1, 1], [1, 0], [0, 0]], np.float32)  # glTF: v = 0 at the top

_COMPONENT = {
    np.dtype(np.int8): 5120,
    np.dtype(np.uint8): 5121,
    np.dtype(np.int16): 5122,
    np.dtype(np.uint16): 5123,
    np.dtype(np.uint32): 5125,
    np.dtype(np.float32): 5126,
}
_TYPE = {1: "SCALAR", 2: "VEC2", 3: "VEC3", 4: "VEC4"}


def load_scene(path, options: LoadOptions | None = None, progress=None):
    """The file's scene with its own triangles, as read (the loader's split of long edges
    for the light kept per vertex left out: tests/test_tessellate.py tests it)."""
    return loaders.load_scene(
        path, dataclasses.replace(options or LoadOptions(), split_edges_m=0.0), progress
    )


class Gltf:
    """A glTF document under construction, with one binary buffer (buffer 0)."""

    def __init__(self) -> None:
        self.doc: dict[str, Any] = {
            "asset": {"version": "2.0"},
            "scene": 0,
            "scenes": [{"nodes": []}],
            "nodes": [],
            "meshes": [],
            "accessors": [],
            "bufferViews": [],
            "buffers": [{"byteLength": 0}],
        }
        self.bin = bytearray()

    def view(self, data: bytes, buffer: int = 0, stride: int | None = None) -> int:
        self.bin += b"\0" * (-len(self.bin) % 4)
        view: dict[str, Any] = {
            "buffer": buffer,
            "byteOffset": len(self.bin),
            "byteLength": len(data),
        }
        if stride is not None:
            view["byteStride"] = stride
        self.bin += data
        self.doc["buffers"][0]["byteLength"] = len(self.bin)
        self.doc["bufferViews"].append(view)
        return len(self.doc["bufferViews"]) - 1

    def accessor(self, array: np.ndarray, normalized: bool = False, **extra: Any) -> int:
        a = np.ascontiguousarray(array)
        a2 = a.reshape(len(a), -1)
        spec: dict[str, Any] = {
            "bufferView": self.view(a.tobytes()),
            "componentType": _COMPONENT[a.dtype],
            "count": len(a2),
            "type": _TYPE[a2.shape[1]],
        }
        if normalized:
            spec["normalized"] = True
        spec.update(extra)
        self.doc["accessors"].append(spec)
        return len(self.doc["accessors"]) - 1

    def mesh(
        self,
        positions: np.ndarray = QUAD,
        indices: np.ndarray | None = QUAD_IDX,
        name: str | None = "quad",
        mode: int | None = None,
        material: int | None = None,
        **attributes: int,
    ) -> int:
        prim: dict[str, Any] = {"attributes": {"POSITION": self.accessor(positions), **attributes}}
        if indices is not None:
            prim["indices"] = self.accessor(indices)
        if mode is not None:
            prim["mode"] = mode
        if material is not None:
            prim["material"] = material
        mesh: dict[str, Any] = {"primitives": [prim]}
        if name is not None:
            mesh["name"] = name
        self.doc["meshes"].append(mesh)
        return len(self.doc["meshes"]) - 1

    def node(self, mesh: int | None = None, root: bool = True, **extra: Any) -> int:
        node: dict[str, Any] = dict(extra)
        if mesh is not None:
            node["mesh"] = mesh
        self.doc["nodes"].append(node)
        index = len(self.doc["nodes"]) - 1
        if root:
            self.doc["scenes"][0]["nodes"].append(index)
        return index

    def textured_material(self, image: bytes, mime: str = "image/png", **info: Any) -> int:
        self.doc.setdefault("images", []).append({"bufferView": self.view(image), "mimeType": mime})
        self.doc.setdefault("textures", []).append({"source": len(self.doc["images"]) - 1})
        self.doc.setdefault("materials", []).append(
            {
                "name": f"mat{len(self.doc['materials'])}",
                "pbrMetallicRoughness": {
                    "baseColorTexture": {"index": len(self.doc["textures"]) - 1, **info},
                    "baseColorFactor": [0.5, 0.25, 1.0, 1.0],
                },
            }
        )
        return len(self.doc["materials"]) - 1

    def write_gltf(self, folder: Path, name: str = "scene.gltf", uri: str = "scene.bin") -> Path:
        folder.mkdir(parents=True, exist_ok=True)
        self.doc["buffers"][0]["uri"] = uri
        (folder / name).write_text(json.dumps(self.doc))
        return folder / name

    def write_bin(self, path: Path) -> None:
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(bytes(self.bin))

    def write(self, folder: Path, name: str = "scene.gltf") -> Path:
        path = self.write_gltf(folder, name)
        self.write_bin(folder / "scene.bin")
        return path

    def glb_bytes(self) -> bytes:
        self.doc["buffers"][0].pop("uri", None)
        text = json.dumps(self.doc).encode()
        text += b" " * (-len(text) % 4)
        binary = bytes(self.bin) + b"\0" * (-len(self.bin) % 4)
        total = 12 + 8 + len(text) + 8 + len(binary)
        return (
            struct.pack("<4sII", b"glTF", 2, total)
            + struct.pack("<II", len(text), 0x4E4F534A)
            + text
            + struct.pack("<II", len(binary), 0x004E4942)
            + binary
        )

    def write_glb(self, folder: Path, name: str = "scene.glb") -> Path:
        folder.mkdir(parents=True, exist_ok=True)
        (folder / name).write_bytes(self.glb_bytes())
        return folder / name


def _quad_scene() -> Gltf:
    g = Gltf()
    g.node(g.mesh())
    return g


def _png(image: Image.Image) -> bytes:
    out = io.BytesIO()
    image.save(out, "PNG")
    return out.getvalue()


def _positions(scene: Scene) -> np.ndarray:
    return np.concatenate([m.positions for m in scene.meshes])


# ------------------------------------------------------------------------------------------
# 1, 2: URIs
# ------------------------------------------------------------------------------------------


def test_percent_encoded_uri_finds_the_file(tmp_path: Path) -> None:
    g = _quad_scene()
    path = g.write_gltf(tmp_path, uri="Box%20.bin")
    g.write_bin(tmp_path / "Box .bin")
    scene = load_scene(path)
    assert scene.triangle_count == 2


def test_data_uri_buffer(tmp_path: Path) -> None:
    g = _quad_scene()
    uri = "data:application/octet-stream;base64," + base64.b64encode(bytes(g.bin)).decode()
    scene = load_scene(g.write_gltf(tmp_path, uri=uri))
    assert scene.triangle_count == 2


def test_malformed_data_uri_is_named(tmp_path: Path) -> None:
    g = _quad_scene()
    path = g.write_gltf(tmp_path, uri="data:application/octet-stream;base64,@@not base64@@")
    with pytest.raises(SceneLoadError, match="data: URI") as err:
        load_scene(path)
    assert "scene.gltf" in str(err.value)


def _hostile(kind: str, tmp_path: Path) -> str:
    outside = tmp_path / "outside.bin"
    if kind == "parent":
        return "../outside.bin"
    if kind == "absolute":
        return str(outside)
    if kind == "file":
        return outside.as_uri()
    return "https://example.com/outside.bin"


@pytest.mark.parametrize("kind", ["parent", "absolute", "file", "http"])
def test_hostile_buffer_uri_is_not_read(tmp_path: Path, kind: str) -> None:
    g = Gltf()
    g.node(g.mesh(name="inside"))
    second = Gltf()
    second.mesh(QUAD + 5.0)
    # The second mesh's data lives in buffer 1, which points outside the scene's folder.
    start = len(g.doc["bufferViews"])
    for view in second.doc["bufferViews"]:
        g.doc["bufferViews"].append({**view, "buffer": 1})
    for acc in second.doc["accessors"]:
        g.doc["accessors"].append({**acc, "bufferView": acc["bufferView"] + start})
    base = len(g.doc["accessors"]) - 2
    g.doc["meshes"].append(
        {"name": "outside", "primitives": [{"attributes": {"POSITION": base}, "indices": base + 1}]}
    )
    g.node(1)
    uri = _hostile(kind, tmp_path)
    g.doc["buffers"].append({"uri": uri, "byteLength": len(second.bin)})
    second.write_bin(tmp_path / "outside.bin")
    scene = load_scene(g.write(tmp_path / "scene"))
    assert [m.name for m in scene.meshes] == ["inside"]
    assert any(uri in w and "not read" in w for w in scene.warnings), scene.warnings
    assert any("outside" in w and "dropped" in w for w in scene.warnings), scene.warnings


def test_only_hostile_buffers_refuse_the_file(tmp_path: Path) -> None:
    g = _quad_scene()
    (tmp_path / "outside.bin").write_bytes(bytes(g.bin))
    path = g.write_gltf(tmp_path / "scene", uri="../outside.bin")
    with pytest.raises(SceneLoadError, match=r"scene\.gltf.*\.\./outside\.bin"):
        load_scene(path)


def test_hostile_image_uri_keeps_the_colour(tmp_path: Path) -> None:
    g = _quad_scene()
    Image.new("RGB", (2, 2), "red").save(tmp_path / "secret.png")
    g.doc["images"] = [{"uri": "../secret.png"}]
    g.doc["textures"] = [{"source": 0}]
    g.doc["materials"] = [
        {
            "name": "paint",
            "pbrMetallicRoughness": {
                "baseColorTexture": {"index": 0},
                "baseColorFactor": [0.5, 0.25, 1.0, 1.0],
            },
        }
    ]
    g.doc["meshes"][0]["primitives"][0]["material"] = 0
    scene = load_scene(g.write(tmp_path / "scene"))
    mat = scene.materials[scene.meshes[0].material]
    assert mat.texture is None and mat.base_color[:3] == pytest.approx((0.5, 0.25, 1.0))
    assert any("../secret.png" in w and "outside" in w for w in scene.warnings), scene.warnings


# ------------------------------------------------------------------------------------------
# 3, 4: extensions and versions
# ------------------------------------------------------------------------------------------


@pytest.mark.parametrize("ext", ["KHR_texture_basisu", "EXT_made_up"])
def test_unsupported_required_extension_is_refused_by_name(tmp_path: Path, ext: str) -> None:
    g = _quad_scene()
    g.doc["extensionsUsed"] = g.doc["extensionsRequired"] = [ext]
    with pytest.raises(SceneLoadError) as err:
        load_scene(g.write_glb(tmp_path, "x.glb"))
    assert str(err.value) == (
        f"Cannot open 'x.glb': it requires the glTF extension {ext}, which this viewer cannot read."
    )


def test_webp_only_textures_as_blender_writes_them_are_read(tmp_path: Path) -> None:
    """Blender's exporter with Image Format "WebP" names each image in the texture's
    EXT_texture_webp, with no PNG fallback, and marks the extension required: such a file was
    refused by name. Its texture is read."""
    g = _quad_scene()
    out = io.BytesIO()
    Image.new("RGB", (8, 8), (200, 40, 40)).save(out, "WEBP", lossless=True)
    mat = g.textured_material(out.getvalue(), "image/webp")
    texture = g.doc["textures"][-1]
    texture["extensions"] = {"EXT_texture_webp": {"source": texture.pop("source")}}
    g.doc["extensionsUsed"] = g.doc["extensionsRequired"] = ["EXT_texture_webp"]
    g.doc["meshes"][0]["primitives"][0]["material"] = mat
    scene = load_scene(g.write_glb(tmp_path))
    material = scene.materials[scene.meshes[0].material]
    assert material.texture is not None
    rgba = scene.textures[material.texture].rgba
    assert tuple(rgba[4, 4, :3]) == (200, 40, 40)


def _meshopt_grid(broken: bool = False) -> tuple[Gltf, np.ndarray, np.ndarray]:
    """A 12 x 12 grid as gltfpack writes it: positions and indices compressed with
    EXT_meshopt_compression (required), the views' own buffer a fallback with no data."""
    import meshoptimizer

    s = np.linspace(0.0, 2.0, 12, dtype=np.float32)
    xx, zz = np.meshgrid(s, s)
    pos = np.column_stack([xx.ravel(), np.zeros(xx.size, np.float32), zz.ravel()])
    quads = [(i * 12 + j, i * 12 + j + 1, (i + 1) * 12 + j) for i in range(11) for j in range(11)]
    idx = np.array([[a, c, b, b, c, c + 1] for a, b, c in quads], np.uint32).reshape(-1)
    g = Gltf()
    packed = [
        (meshoptimizer.encode_vertex_buffer(pos), len(pos), 12, "ATTRIBUTES", 5126, "VEC3"),
        (
            meshoptimizer.encode_index_buffer(idx, len(idx), len(pos)),
            len(idx),
            4,
            "TRIANGLES",
            5125,
            "SCALAR",
        ),
    ]
    g.doc["buffers"].append(
        {"byteLength": 4096, "extensions": {"EXT_meshopt_compression": {"fallback": True}}}
    )
    accessors = []
    for data, count, stride, mode, component, kind in packed:
        source = g.doc["bufferViews"][g.view(b"\x55" * len(data) if broken else data)]
        view = {
            "buffer": 1,
            "byteLength": count * stride,
            "extensions": {
                "EXT_meshopt_compression": {
                    "buffer": 0,
                    "byteOffset": source["byteOffset"],
                    "byteLength": source["byteLength"],
                    "byteStride": stride,
                    "mode": mode,
                    "count": count,
                }
            },
        }
        if mode == "ATTRIBUTES":
            view["byteStride"] = stride
        g.doc["bufferViews"].append(view)
        g.doc["accessors"].append(
            {
                "bufferView": len(g.doc["bufferViews"]) - 1,
                "componentType": component,
                "count": count,
                "type": kind,
                **(
                    {"min": pos.min(0).tolist(), "max": pos.max(0).tolist()}
                    if kind == "VEC3"
                    else {}
                ),
            }
        )
        accessors.append(len(g.doc["accessors"]) - 1)
    g.doc["meshes"].append(
        {"primitives": [{"attributes": {"POSITION": accessors[0]}, "indices": accessors[1]}]}
    )
    g.node(len(g.doc["meshes"]) - 1)
    g.doc["extensionsUsed"] = g.doc["extensionsRequired"] = ["EXT_meshopt_compression"]
    return g, pos, idx


def test_meshopt_compressed_files_as_gltfpack_writes_them_open(tmp_path: Path) -> None:
    """gltfpack and glTF-Transform compress geometry with EXT_meshopt_compression and mark it
    required: such a file was refused by name. It is decoded with meshoptimizer (the library
    the levels of detail use) and shows the same triangles."""
    g, pos, idx = _meshopt_grid()
    scene = load_scene(g.write_glb(tmp_path))
    assert scene.triangle_count == len(idx) // 3 == 242
    got = np.concatenate([m.positions for m in scene.meshes])
    assert np.allclose(np.sort(got, axis=0), np.sort(pos, axis=0), atol=1e-6)


def test_broken_meshopt_data_is_a_clear_error_not_a_crash(tmp_path: Path) -> None:
    g, _, _ = _meshopt_grid(broken=True)
    with pytest.raises(SceneLoadError) as err:
        load_scene(g.write_glb(tmp_path))
    assert "'scene.glb'" in str(err.value) and "meshopt-compressed data cannot be decoded" in str(
        err.value
    )


def test_meshopt_used_with_fallback_reads_the_fallback(tmp_path: Path) -> None:
    g = _quad_scene()
    g.doc["extensionsUsed"] = ["EXT_meshopt_compression"]
    g.doc["buffers"].append(
        {"byteLength": 64, "extensions": {"EXT_meshopt_compression": {"fallback": True}}}
    )
    for view in g.doc["bufferViews"]:
        view["extensions"] = {
            "EXT_meshopt_compression": {
                "buffer": 1,
                "byteLength": 8,
                "byteStride": 4,
                "count": 2,
                "mode": "ATTRIBUTES",
            }
        }
    scene = load_scene(g.write_glb(tmp_path))
    assert scene.triangle_count == 2


def test_mesh_quantization_normalized_positions_and_uvs(tmp_path: Path) -> None:
    g = Gltf()
    pos = g.accessor((QUAD * 32767).astype(np.int16), normalized=True)
    uv = g.accessor((QUAD_UV * 65535).astype(np.uint16), normalized=True)
    idx = g.accessor(QUAD_IDX)
    g.doc["meshes"].append(
        {"primitives": [{"attributes": {"POSITION": pos, "TEXCOORD_0": uv}, "indices": idx}]}
    )
    g.node(0, scale=[2.0, 2.0, 2.0])
    g.doc["extensionsUsed"] = g.doc["extensionsRequired"] = ["KHR_mesh_quantization"]
    scene = load_scene(g.write_glb(tmp_path))
    mesh = scene.meshes[0]
    np.testing.assert_allclose(mesh.positions, QUAD * 2.0, atol=1e-4)
    np.testing.assert_allclose(mesh.uvs[:, 1], 1.0 - QUAD_UV[:, 1], atol=1e-4)


def test_draco_compressed_primitive(tmp_path: Path) -> None:
    import DracoPy

    grid = np.stack(np.meshgrid(np.arange(5.0), np.arange(4.0)), axis=-1).reshape(-1, 2)
    pos = np.column_stack([grid, np.zeros(len(grid))]).astype(np.float32)
    faces = []
    for y in range(3):
        for x in range(4):
            a = y * 5 + x
            faces += [[a, a + 1, a + 6], [a, a + 6, a + 5]]
    payload = DracoPy.encode(pos, np.array(faces, np.uint32), preserve_order=True)
    uid = next(
        a["unique_id"] for a in DracoPy.decode(payload).attributes if a["attribute_type"] == 0
    )
    g = Gltf()
    view = g.view(payload)
    g.doc["accessors"] = [
        {"componentType": 5126, "count": len(pos), "type": "VEC3"},
        {"componentType": 5125, "count": 3 * len(faces), "type": "SCALAR"},
    ]
    g.doc["meshes"].append(
        {
            "name": "draco",
            "primitives": [
                {
                    "attributes": {"POSITION": 0},
                    "indices": 1,
                    "extensions": {
                        "KHR_draco_mesh_compression": {
                            "bufferView": view,
                            "attributes": {"POSITION": uid},
                        }
                    },
                }
            ],
        }
    )
    g.node(0)
    g.doc["extensionsUsed"] = g.doc["extensionsRequired"] = ["KHR_draco_mesh_compression"]
    scene = load_scene(g.write_glb(tmp_path))
    assert scene.triangle_count == len(faces)
    lo, hi = scene.bounds()
    np.testing.assert_allclose(lo, [0, 0, 0], atol=1e-3)
    np.testing.assert_allclose(hi, [4, 3, 0], atol=1e-3)


@pytest.mark.parametrize(
    ("asset", "message"),
    [
        ({"version": "2.0", "minVersion": "2.1"}, "needs glTF 2.1"),
        ({"version": "3.0"}, "only glTF 2.0 is supported"),
    ],
)
def test_newer_gltf_versions_are_refused(
    tmp_path: Path, asset: dict[str, str], message: str
) -> None:
    g = _quad_scene()
    g.doc["asset"] = asset
    with pytest.raises(SceneLoadError, match=message) as err:
        load_scene(g.write_glb(tmp_path))
    assert "scene.glb" in str(err.value)


def test_gltf_2_1_without_min_version_loads(tmp_path: Path) -> None:
    g = _quad_scene()
    g.doc["asset"] = {"version": "2.1"}
    assert load_scene(g.write_glb(tmp_path)).triangle_count == 2


# ------------------------------------------------------------------------------------------
# 5: sparse accessors
# ------------------------------------------------------------------------------------------


def test_sparse_accessor_over_base_and_over_zeros(tmp_path: Path) -> None:
    g = Gltf()

    def sparse(where: list[int], values: np.ndarray) -> dict[str, Any]:
        return {
            "count": len(where),
            "indices": {
                "bufferView": g.view(np.array(where, np.uint8).tobytes()),
                "componentType": 5121,
            },
            "values": {"bufferView": g.view(values.astype(np.float32).tobytes())},
        }

    moved = np.array([[1, 2, 0]], np.float32)
    over_base = g.accessor(QUAD, sparse=sparse([2], moved))
    over_zeros = len(g.doc["accessors"])
    g.doc["accessors"].append(
        {"componentType": 5126, "count": 4, "type": "VEC3", "sparse": sparse([1, 2, 3], QUAD[1:])}
    )
    idx = g.accessor(QUAD_IDX)
    for name, acc in (("base", over_base), ("zeros", over_zeros)):
        g.doc["meshes"].append(
            {"name": name, "primitives": [{"attributes": {"POSITION": acc}, "indices": idx}]}
        )
        g.node(len(g.doc["meshes"]) - 1)
    scene = load_scene(g.write(tmp_path))
    by_name = {m.name: m for m in scene.meshes}
    expected = QUAD.copy()
    expected[2] = moved[0]
    np.testing.assert_allclose(by_name["base"].positions, expected)
    np.testing.assert_allclose(by_name["zeros"].positions, QUAD)


# ------------------------------------------------------------------------------------------
# 6: validation before allocation
# ------------------------------------------------------------------------------------------


def test_accessor_past_its_view_is_refused(tmp_path: Path) -> None:
    g = _quad_scene()
    g.doc["accessors"][0]["count"] = 1_000_000
    with pytest.raises(SceneLoadError) as err:
        load_scene(g.write_glb(tmp_path, "x.glb"))
    assert str(err.value) == "Cannot read 'x.glb': accessor 0 reads past the end of buffer view 0."


def test_huge_claims_in_a_tiny_file_are_refused_without_allocating(tmp_path: Path) -> None:
    g = _quad_scene()
    g.doc["accessors"][0] = {"componentType": 5126, "count": 2_000_000_000, "type": "VEC3"}
    path = g.write_glb(tmp_path, "bomb.glb")
    assert path.stat().st_size < 2048
    start = time.perf_counter()
    with pytest.raises(SceneLoadError, match=r"bomb\.glb.*needs about \d+\.\d GB") as err:
        load_scene(path)
    assert time.perf_counter() - start < 2.0
    assert "scene.max_memory_mb" in str(err.value)


def test_memory_limit_counts_geometry_and_textures(tmp_path: Path) -> None:
    g = Gltf()
    mat = g.textured_material(_png(Image.new("RGB", (1024, 1024))))
    g.node(g.mesh(material=mat, TEXCOORD_0=g.accessor(QUAD_UV)))
    path = g.write_glb(tmp_path)
    assert load_scene(path, LoadOptions(max_memory_mb=8)).triangle_count == 2
    with pytest.raises(SceneLoadError, match=r"needs about 4\.\d MB.*limit of 3\.0 MB"):
        load_scene(path, LoadOptions(max_memory_mb=3))


@pytest.mark.parametrize(
    ("damage", "message"),
    [
        (lambda d: d["bufferViews"][0].update(byteLength=10_000), "buffer view 0 reaches past"),
        (lambda d: d["bufferViews"][0].update(byteStride=4), "byteStride 4"),
        (lambda d: d["accessors"][0].update(componentType=9999), "unknown componentType"),
        (lambda d: d["accessors"][1].update(type="VEC7"), "unknown type"),
        (lambda d: d["accessors"][1].update(count=-3), "impossible count"),
        (lambda d: d["bufferViews"][0].update(buffer=4), "buffer 4, which does not exist"),
    ],
)
def test_damaged_layout_is_refused_with_the_problem(
    tmp_path: Path, damage: Any, message: str
) -> None:
    g = _quad_scene()
    damage(g.doc)
    with pytest.raises(SceneLoadError) as err:
        load_scene(g.write_glb(tmp_path, "x.glb"))
    text = str(err.value)
    assert text.startswith("Cannot read 'x.glb': ") and message in text, text


def test_indices_beyond_the_vertices_drop_those_triangles(tmp_path: Path) -> None:
    g = Gltf()
    g.node(g.mesh(indices=np.array([0, 1, 2, 0, 2, 3, 0, 3, 99], np.uint16)))
    scene = load_scene(g.write(tmp_path))
    assert scene.triangle_count == 2
    assert any("1 triangle referring to vertices that do not exist" in w for w in scene.warnings)


def test_glb_chunk_lengths_are_checked(tmp_path: Path) -> None:
    data = bytearray(_quad_scene().glb_bytes())
    json_len = struct.unpack_from("<I", data, 12)[0]
    struct.pack_into("<I", data, 20 + json_len, 1_000_000)  # BIN chunk claims 1 MB
    (tmp_path / "cut.glb").write_bytes(bytes(data))
    with pytest.raises(SceneLoadError, match=r"'cut\.glb'.*truncated"):
        load_scene(tmp_path / "cut.glb")


def test_accessor_min_max_are_not_trusted(tmp_path: Path) -> None:
    g = _quad_scene()
    g.doc["accessors"][0].update(min=[0, 0, 0], max=[0.1, 0.1, 0.1])
    scene = load_scene(g.write_glb(tmp_path))
    np.testing.assert_allclose(scene.bounds()[1], [1, 1, 0])


# ------------------------------------------------------------------------------------------
# 7: primitive modes
# ------------------------------------------------------------------------------------------


def _facing(scene: Scene) -> np.ndarray:
    m = scene.meshes[0]
    tri = m.positions[m.indices].astype(np.float64)
    return np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])[:, 2]


def test_triangle_strip_keeps_one_winding(tmp_path: Path) -> None:
    strip = np.array([[0, 0, 0], [0, 1, 0], [1, 0, 0], [1, 1, 0], [2, 0, 0], [2, 1, 0]], np.float32)
    g = Gltf()
    g.node(g.mesh(strip, indices=None, mode=5))
    scene = load_scene(g.write(tmp_path))
    assert scene.triangle_count == 4
    facing = _facing(scene)
    assert (facing < 0).all() or (facing > 0).all(), facing


def test_triangle_fan(tmp_path: Path) -> None:
    fan = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [-1, 1, 0]], np.float32)
    g = Gltf()
    g.node(g.mesh(fan, indices=None, mode=6))
    scene = load_scene(g.write(tmp_path))
    assert scene.triangle_count == 3
    assert (_facing(scene) > 0).all()


def test_lines_and_points_ignored_with_one_warning(tmp_path: Path) -> None:
    g = _quad_scene()
    g.node(g.mesh(indices=None, mode=1, name="wire"))
    g.node(g.mesh(indices=None, mode=0, name="dots"))
    g.node(g.mesh(indices=None, mode=3, name="loop"))
    scene = load_scene(g.write(tmp_path))
    assert [m.name for m in scene.meshes] == ["quad"]
    assert sum("line primitives" in w for w in scene.warnings) == 1, scene.warnings
    assert sum("point primitive" in w for w in scene.warnings) == 1, scene.warnings


def test_only_lines_means_no_triangles(tmp_path: Path) -> None:
    g = Gltf()
    g.node(g.mesh(indices=None, mode=1))
    with pytest.raises(SceneLoadError, match="no triangles"):
        load_scene(g.write(tmp_path))


# ------------------------------------------------------------------------------------------
# 8: broken positions
# ------------------------------------------------------------------------------------------


@pytest.mark.parametrize("position", [-1, 99])
def test_missing_position_accessor_drops_the_primitive(tmp_path: Path, position: int) -> None:
    g = _quad_scene()
    g.node(g.mesh(name="broken"))
    g.doc["meshes"][1]["primitives"][0]["attributes"]["POSITION"] = position
    scene = load_scene(g.write(tmp_path))
    assert [m.name for m in scene.meshes] == ["quad"]
    assert any("'broken'" in w and "POSITION" in w and "dropped" in w for w in scene.warnings)


def test_nan_and_inf_positions_do_not_crash(tmp_path: Path) -> None:
    pos = np.vstack([QUAD, [[np.nan, 0, 0], [np.inf, 1, 0]]]).astype(np.float32)
    g = Gltf()
    g.node(g.mesh(pos, indices=np.array([0, 1, 2, 0, 2, 3, 0, 4, 5], np.uint16)))
    scene = load_scene(g.write(tmp_path))
    assert scene.triangle_count == 2
    assert np.isfinite(_positions(scene)).all()


# ------------------------------------------------------------------------------------------
# 9: node graphs
# ------------------------------------------------------------------------------------------


def test_node_cycle_is_cut(tmp_path: Path) -> None:
    g = Gltf()
    mesh = g.mesh()
    g.node(mesh, children=[1])
    g.node(mesh, root=False, children=[0], translation=[3, 0, 0])
    scene = load_scene(g.write(tmp_path))
    assert scene.triangle_count == 4
    assert any("cycle" in w for w in scene.warnings), scene.warnings


def test_ten_thousand_deep_hierarchy(tmp_path: Path) -> None:
    g = Gltf()
    mesh = g.mesh()
    depth = 10_000
    for i in range(depth):
        g.node(mesh if i == depth - 1 else None, root=i == 0, translation=[0.001, 0, 0])
        if i:
            g.doc["nodes"][i - 1]["children"] = [i]
    scene = load_scene(g.write(tmp_path))
    assert scene.bounds()[0][0] == pytest.approx(10.0, abs=1e-3)


def test_json_nested_too_deeply_is_refused(tmp_path: Path) -> None:
    g = _quad_scene()
    path = g.write(tmp_path, "deep.gltf")
    text = path.read_text()
    path.write_text(text[:-1] + ', "extras": ' + "[" * 100_000 + "]" * 100_000 + "}")
    with pytest.raises(SceneLoadError, match=r"'deep\.gltf'.*nested too deeply"):
        load_scene(path)


@pytest.mark.parametrize("scenes", ["missing", "bad-index", "not-a-list"])
def test_without_a_valid_scene_all_root_nodes_show(tmp_path: Path, scenes: str) -> None:
    g = Gltf()
    mesh = g.mesh()
    g.node(mesh, root=False, children=[1])
    g.node(mesh, root=False, translation=[2, 0, 0])
    g.node(mesh, root=False, translation=[5, 0, 0])
    if scenes == "missing":
        del g.doc["scenes"], g.doc["scene"]
    elif scenes == "bad-index":
        g.doc["scene"] = 7
    else:
        g.doc["scenes"] = {"nodes": [0]}
    scene = load_scene(g.write(tmp_path))
    assert scene.triangle_count == 6


def test_instanced_mesh_gives_two_meshes(tmp_path: Path) -> None:
    g = Gltf()
    mesh = g.mesh()
    g.node(mesh)
    g.node(mesh, translation=[3, 0, 0], scale=[-1, 1, 1])  # mirrored: winding flipped
    scene = load_scene(g.write(tmp_path))
    assert [m.name for m in scene.meshes] == ["quad", "quad#2"]
    a, b = scene.meshes
    np.testing.assert_allclose(b.positions[:, 0], 3.0 - a.positions[:, 0])
    for m in scene.meshes:
        tri = m.positions[m.indices].astype(np.float64)
        face = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        assert (np.einsum("ij,ij->i", face, m.normals[m.indices[:, 0]]) > 0).all()


# ------------------------------------------------------------------------------------------
# 10: images
# ------------------------------------------------------------------------------------------


def _textured(tmp_path: Path, image: bytes, mime: str = "image/png", **opts: Any) -> Scene:
    g = Gltf()
    mat = g.textured_material(image, mime)
    g.node(g.mesh(material=mat, TEXCOORD_0=g.accessor(QUAD_UV)))
    return load_scene(g.write_glb(tmp_path), LoadOptions(**opts))


def _cmyk_jpeg() -> bytes:
    out = io.BytesIO()
    Image.new("CMYK", (3, 2), (0, 255, 255, 0)).save(out, "JPEG", quality=100)
    return out.getvalue()


def _palette_png() -> bytes:
    im = Image.new("P", (2, 1))
    im.putpalette([255, 0, 0, 0, 255, 0])
    im.putdata([0, 1])
    out = io.BytesIO()
    im.save(out, "PNG", transparency=1)
    return out.getvalue()


@pytest.mark.parametrize(
    ("image", "pixel"),
    [
        (_png(Image.new("RGB", (1, 1), (10, 20, 30))), (10, 20, 30, 255)),
        (_png(Image.fromarray(np.full((2, 2), 65535, np.uint16))), (255, 255, 255, 255)),
        (_palette_png(), (255, 0, 0, 255)),
        (_png(Image.new("LA", (2, 2), (128, 64))), (128, 128, 128, 64)),
        (_cmyk_jpeg(), None),
    ],
    ids=["1x1", "16-bit", "palette-transparency", "LA", "CMYK"],
)
def test_image_modes_become_rgba8(
    tmp_path: Path, image: bytes, pixel: tuple[int, ...] | None
) -> None:
    g = Gltf()
    mat = g.textured_material(image)
    g.doc["materials"][mat]["alphaMode"] = "BLEND"  # keep the alpha channel
    g.node(g.mesh(material=mat, TEXCOORD_0=g.accessor(QUAD_UV)))
    scene = load_scene(g.write_glb(tmp_path))
    tex = scene.textures[scene.materials[scene.meshes[0].material].texture or 0].rgba
    assert tex.dtype == np.uint8 and tex.ndim == 3 and tex.shape[2] == 4
    if pixel is not None:
        assert tuple(tex[0, 0]) == pixel
    else:  # CMYK cyan-free red: red dominates
        assert tex[0, 0, 0] > 200 and tex[0, 0, 1] < 60 and tex[0, 0, 3] == 255


def test_palette_transparency_is_kept(tmp_path: Path) -> None:
    g = Gltf()
    mat = g.textured_material(_palette_png())
    g.doc["materials"][mat]["alphaMode"] = "MASK"
    g.node(g.mesh(material=mat, TEXCOORD_0=g.accessor(QUAD_UV)))
    scene = load_scene(g.write_glb(tmp_path))
    tex = scene.textures[0].rgba
    assert tuple(tex[0, 1]) == (0, 255, 0, 0)


def _png_claiming(width: int, height: int) -> bytes:
    """A PNG header for a huge image with no real pixel data (a decompression bomb's shape)."""

    def chunk(kind: bytes, data: bytes) -> bytes:
        return (
            struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))
        )

    ihdr = struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0)
    return (
        b"\x89PNG\r\n\x1a\n"
        + chunk(b"IHDR", ihdr)
        + chunk(b"IDAT", zlib.compress(b"\0" * 64))
        + chunk(b"IEND", b"")
    )


@pytest.mark.parametrize("side", [21_000, 30_000])  # over the limit (warning) and over 2x (error)
def test_decompression_bomb_drops_the_texture(tmp_path: Path, side: int) -> None:
    scene = _textured(tmp_path, _png_claiming(side, side), max_memory_mb=100_000)
    mat = scene.materials[scene.meshes[0].material]
    assert mat.texture is None and mat.base_color[:3] == pytest.approx((0.5, 0.25, 1.0))
    assert any("too large to decode safely" in w for w in scene.warnings), scene.warnings


def test_large_jpeg_is_downscaled_at_load(tmp_path: Path) -> None:
    out = io.BytesIO()
    Image.new("RGB", (3000, 2000), (200, 100, 50)).save(out, "JPEG")
    scene = _textured(tmp_path, out.getvalue(), "image/jpeg", max_texture_px=512)
    tex = scene.textures[0]
    assert tex.size == (512, 341)
    assert any("downscaled from 3000 x 2000 to 512 x 341" in w for w in scene.warnings)
    assert abs(int(tex.rgba[100, 100, 0]) - 200) < 8


@pytest.mark.parametrize("kind", ["missing", "garbage"])
def test_unreadable_image_keeps_the_colour(tmp_path: Path, kind: str) -> None:
    g = _quad_scene()
    g.doc["images"] = [{"uri": "paint.png"}]
    g.doc["textures"] = [{"source": 0}]
    g.doc["materials"] = [
        {"name": "paint", "pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}
    ]
    g.doc["meshes"][0]["primitives"][0]["material"] = 0
    if kind == "garbage":
        (tmp_path / "paint.png").write_bytes(b"\x89PNG not really")
    scene = load_scene(g.write(tmp_path))
    assert scene.materials[scene.meshes[0].material].texture is None
    assert any("paint.png" in w and "colour only" in w for w in scene.warnings), scene.warnings


# ------------------------------------------------------------------------------------------
# materials and progress
# ------------------------------------------------------------------------------------------


def test_material_factors_and_extensions(tmp_path: Path) -> None:
    g = Gltf()
    red = _png(Image.new("RGB", (2, 2), (255, 0, 0)))
    mat = g.textured_material(red, extensions={"KHR_texture_transform": {"scale": [2, 2]}})
    g.doc["materials"][mat].update(
        emissiveFactor=[1.0, 0.5, 0.0],
        extensions={"KHR_materials_emissive_strength": {"emissiveStrength": 4.0}},
    )
    g.doc["materials"].append(
        {
            "name": "specgloss",
            "extensions": {
                "KHR_materials_pbrSpecularGlossiness": {
                    "diffuseFactor": [0.1, 0.2, 0.3, 1.0],
                    "glossinessFactor": 0.75,
                }
            },
        }
    )
    g.doc["samplers"] = [{"wrapS": 33071, "wrapT": 33071}]
    g.doc["textures"][0]["sampler"] = 0
    uv = g.accessor(QUAD_UV)
    g.node(g.mesh(material=0, TEXCOORD_0=uv))
    g.node(g.mesh(material=0, TEXCOORD_0=uv, name="again"))  # same texture: shared
    g.node(g.mesh(material=1, name="sg"))
    scene = load_scene(g.write(tmp_path))
    by_name = {m.name: m for m in scene.materials}
    mat0 = by_name["mat0"]
    assert mat0.emissive == pytest.approx((4.0, 2.0, 0.0))
    assert len(scene.textures) == 1 and scene.textures[0].repeat is False
    assert tuple(scene.textures[0].rgba[0, 0]) == (255, 0, 0, 255)
    assert not any("transform" in w for w in scene.warnings)  # baked into the uvs
    quad = next(m for m in scene.meshes if m.name.startswith("quad") or m.material == 0)
    # KHR_texture_transform scale 2: the glTF uvs doubled (then v flipped for OpenGL)
    assert sorted(map(tuple, quad.uvs.round(3).tolist())) == [(0, -1), (0, 1), (2, -1), (2, 1)]
    sg = by_name["specgloss"]
    assert sg.base_color[:3] == pytest.approx((0.1, 0.2, 0.3))
    assert sg.roughness == pytest.approx(0.25) and sg.metallic == 0.0


def test_progress_reports_and_cancels(tmp_path: Path) -> None:
    g = _quad_scene()
    for _ in range(4):
        g.node(g.mesh())
    path = g.write(tmp_path)
    seen: list[str] = []
    load_scene(path, progress=Progress(lambda f, text: seen.append(text)))
    assert sum(text.startswith("Mesh quad") for text in seen) == 5

    progress = Progress()

    def cancel(fraction: float, text: str) -> None:
        if text.startswith("Mesh"):
            progress.cancel.set()

    progress = Progress(cancel)
    with pytest.raises(LoadCancelled):
        load_scene(path, progress=progress)


# ------------------------------------------------------------------------------------------
# the file's camera: where the viewer starts
# ------------------------------------------------------------------------------------------

FLOOR = np.array([[-3, 0, 3], [3, 0, 3], [3, 0, -3], [-3, 0, -3]], np.float32)  # faces up


def _quat(axis: tuple[float, float, float], degrees: float) -> np.ndarray:
    h = np.radians(degrees) / 2.0
    return np.array([*(np.sin(h) * np.asarray(axis, float)), np.cos(h)])


def _qmul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    (ax, ay, az, aw), (bx, by, bz, bw) = a, b
    return np.array(
        [
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
            aw * bw - ax * bx - ay * by - az * bz,
        ]
    )


def _room_with_camera(**camera_node: Any) -> Gltf:
    g = Gltf()
    g.node(g.mesh(FLOOR, name="floor"))
    g.doc["cameras"] = [{"type": "perspective", "perspective": {"yfov": 0.8, "znear": 0.05}}]
    g.node(camera=0, **camera_node)
    return g


def test_the_viewer_starts_at_the_files_camera(tmp_path: Path) -> None:
    """A designer who saved a view in Blender (a glTF camera: turned 90 degrees left, looking
    20 degrees down, 1.2 m above the floor) starts there, upright, the floor under it known."""
    turn = _qmul(_quat((0, 1, 0), 90.0), _quat((1, 0, 0), -20.0))
    g = _room_with_camera(translation=[1.0, 1.2, 2.0], rotation=turn.tolist())
    scene = load_scene(g.write(tmp_path))
    assert scene.spawn.position == pytest.approx((1.0, 1.2, 2.0), abs=1e-6)
    assert scene.spawn.yaw_deg == pytest.approx(90.0, abs=1e-4)
    assert scene.spawn.pitch_deg == pytest.approx(-20.0, abs=1e-4)
    assert scene.floor_y == pytest.approx(0.0, abs=1e-6)
    # in centimetres the camera moves with the model
    options = LoadOptions(unit_scale=0.01)
    scaled = load_scene(g.write(tmp_path / "cm"), options)
    assert scaled.spawn.position == pytest.approx((0.01, 0.012, 0.02), abs=1e-6)


def test_every_camera_in_the_file_is_a_viewpoint(tmp_path: Path) -> None:
    """A designer's file with several saved views keeps them all, by name, in the file's
    order (View > Viewpoints lists them); the first is where the viewer starts."""
    g = _room_with_camera(translation=[1.0, 1.6, 2.0], name="Entrance")
    g.doc["cameras"].append({"type": "perspective", "name": "Kitchen cam", "perspective": {}})
    g.node(camera=1, translation=[-2.0, 1.5, -1.0], rotation=_quat((0, 1, 0), 180.0).tolist())
    scene = load_scene(g.write(tmp_path))
    assert [name for name, _ in scene.cameras] == ["Entrance", "Kitchen cam"]
    kitchen = scene.cameras[1][1]
    assert kitchen.position == pytest.approx((-2.0, 1.5, -1.0), abs=1e-6)
    assert abs(kitchen.yaw_deg) == pytest.approx(180.0, abs=1e-4)
    assert scene.spawn == scene.cameras[0][1]


def test_a_camera_far_away_or_broken_is_not_used(tmp_path: Path) -> None:
    """A camera 500 m from a 6 m room (an exporter's default camera, a stray node) and one
    whose matrix is NaN leave the viewer where the spawn search puts it, with a note."""
    g = Gltf()
    g.node(g.mesh(FLOOR, name="floor"))
    searched = load_scene(g.write(tmp_path / "floor"))
    far = load_scene(_room_with_camera(translation=[500.0, 1.6, 0.0]).write(tmp_path / "far"))
    assert far.spawn == searched.spawn
    assert any("camera is far" in w for w in far.warnings)
    broken = load_scene(_room_with_camera(matrix=[float("nan")] * 16).write(tmp_path / "nan"))
    assert broken.spawn == searched.spawn
    assert any("has no usable position" in w for w in broken.warnings)
