"""glTF 2.0 / GLB -> :class:`~app.scene.Scene`: our own reader, numpy from JSON and buffers.

One :class:`~app.scene.Mesh` per primitive per node that instances it, in world space (float64
positions, node transforms baked, normals by the inverse transpose, winding flipped under a
mirroring transform) and uvs in OpenGL's bottom-left convention (``v = 1 - v_gltf``, see
:mod:`app.loaders`). Strips and fans become triangle lists; points and lines are ignored.

The order of work keeps hostile files cheap: the whole file's memory need is estimated from the
JSON and image headers and checked against ``scene.max_memory_mb`` before any geometry is
decoded, and every accessor is validated before it is read (:mod:`app.gltf_accessors`).
A primitive whose data cannot be had (a missing or refused buffer, a bad POSITION) is dropped
with a warning; a file left with nothing, or with a broken binary layout, is refused.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from app.errors import SceneLoadError
from app.gltf import (
    gltf_camera_views,
    gltf_lights,
    gltf_node_walk,
    gltf_wants_indirect,
    read_gltf_file,
)
from app.gltf_accessors import (
    Accessors,
    Blob,
    Buffers,
    BufferUnavailable,
    GltfDataError,
    UriResolver,
    as_dict,
    as_list,
    is_int,
    to_float,
)
from app.gltf_materials import GltfImages, GltfMaterials
from app.progress import Progress
from app.scene import Mesh, Scene, vertex_normals
from app.tangents import generate_tangents, transform_tangents

_TRIANGLES, _STRIP, _FAN = 4, 5, 6
_LINE_MODES = {0: "point", 1: "line", 2: "line", 3: "line"}
# Bytes per vertex and per index our meshes take (float64 positions; float32 normals, uvs,
# colours; plus the decode's temporaries), for the memory estimate.
_BYTES_PER_VERTEX = 24 + 12 + 8 + 12 + 48
_BYTES_PER_INDEX = 4 + 8


class _Dropped(Exception):
    """This primitive cannot be shown; the message is the warning."""


def read_gltf(path: Path, max_texture_px: int, max_memory_mb: int, progress: Progress) -> Scene:
    """The file as a Scene in world space, not yet placed or repaired."""
    doc, glb_bin = read_gltf_file(path)
    warnings: list[str] = []
    reader = _Reader(path, doc, glb_bin, max_texture_px, warnings, progress)
    try:
        instances = reader.instances()
        reader.check_memory(instances, max_memory_mb)
        meshes = reader.meshes(instances)
    except GltfDataError as exc:
        raise SceneLoadError(f"Cannot read '{path.name}': {exc}.") from exc
    return Scene(
        name=path.stem,
        meshes=meshes,
        materials=reader.materials.materials,
        textures=reader.materials.textures,
        lights=gltf_lights(doc, warnings),
        source=str(path),
        warnings=warnings,
        indirect=gltf_wants_indirect(doc),
        cameras=gltf_camera_views(doc, warnings),
    )


class _Reader:
    def __init__(
        self,
        path: Path,
        doc: dict[str, Any],
        glb_bin: Blob | None,
        max_texture_px: int,
        warnings: list[str],
        progress: Progress,
    ) -> None:
        self.path = path
        self.doc = doc
        self.warnings = warnings
        self.progress = progress
        resolver = UriResolver(path.parent, warnings)
        self.accessors = Accessors(doc, Buffers(doc, glb_bin, resolver))
        self.images = GltfImages(doc, self.accessors, resolver, max_texture_px)
        self.materials = GltfMaterials(doc, self.images, warnings, progress, self._tick)
        self._done = 0
        self._total = 1
        self._names: dict[str, int] = {}
        self._skipped_modes: dict[str, int] = {}
        self._dropped: list[str] = []
        required = doc.get("extensionsRequired")
        self._draco_required = isinstance(required, list) and (
            "KHR_draco_mesh_compression" in required
        )

    def _tick(self, text: str) -> None:
        self._done += 1
        self.progress.report(min(self._done / self._total, 1.0), text)

    # ---- what to build ------------------------------------------------------------------

    def instances(self) -> list[tuple[int, dict[str, Any], np.ndarray]]:
        """(mesh index, mesh, world matrix) per node that shows a mesh, in node order."""
        meshes = as_list(self.doc.get("meshes"))
        nodes = as_list(self.doc.get("nodes"))
        out = []
        for node, matrix in gltf_node_walk(self.doc, self.warnings):
            ref = as_dict(nodes[node]).get("mesh")
            if ref is None:
                continue
            if not is_int(ref) or not 0 <= ref < len(meshes) or not isinstance(meshes[ref], dict):
                self.warnings.append(f"node {node}: refers to mesh {ref}, which does not exist")
                continue
            out.append((ref, meshes[ref], matrix))
        return out

    def check_memory(
        self, instances: list[tuple[int, dict[str, Any], np.ndarray]], max_memory_mb: int
    ) -> None:
        """Refuse before decoding when geometry plus decoded textures would exceed the limit.

        Counts come from the JSON (validated as counts, not trusted as small), image sizes from
        their headers, so a 1 KB file claiming a billion vertices costs nothing to refuse.
        """
        total = 0
        materials: set[int] = set()
        primitives = 0
        for _, mesh, _ in instances:
            for prim in _primitives(mesh):
                primitives += 1
                attrs = as_dict(prim.get("attributes"))
                try:
                    vertices = self.accessors.count(attrs.get("POSITION"))
                except GltfDataError:
                    continue  # dropped with a warning when it is built
                indices = vertices
                if prim.get("indices") is not None:
                    try:
                        indices = self.accessors.count(prim["indices"])
                    except GltfDataError:
                        pass
                total += vertices * _BYTES_PER_VERTEX + indices * _BYTES_PER_INDEX
                if is_int(prim.get("material")):
                    materials.add(prim["material"])
        images = self.materials.used_images(materials)
        total += sum(self.images.decoded_bytes(i) for i in images)
        self._total = max(primitives + len(images), 1)
        limit = int(max_memory_mb) * 2**20
        if total > limit:
            raise SceneLoadError(
                f"Cannot open '{self.path.name}': it needs about {_size(total)} of memory for "
                f"its geometry and textures, more than the limit of {_size(limit)} "
                "(the scene.max_memory_mb setting)."
            )

    # ---- building -----------------------------------------------------------------------

    def meshes(self, instances: list[tuple[int, dict[str, Any], np.ndarray]]) -> list[Mesh]:
        out: list[Mesh] = []
        attempted = 0
        for index, mesh, matrix in instances:
            base = str(mesh.get("name") or f"mesh {index}")
            for prim in _primitives(mesh):
                mode = prim.get("mode", _TRIANGLES)
                if is_int(mode) and mode in _LINE_MODES:
                    kind = _LINE_MODES[mode]
                    self._skipped_modes[kind] = self._skipped_modes.get(kind, 0) + 1
                    self._tick(f"Mesh {base}")
                    continue
                attempted += 1
                name = self._unique(base)
                try:
                    out.append(self._primitive(name, prim, matrix))
                except _Dropped as exc:
                    self.warnings.append(f"mesh '{name}': {exc}, dropped")
                    self._dropped.append(str(exc))
                except BufferUnavailable as exc:
                    self.warnings.append(f"mesh '{name}': its data is unavailable ({exc}), dropped")
                    self._dropped.append(str(exc))
                self._tick(f"Mesh {name}")
        if attempted and not out:
            raise SceneLoadError(
                f"Cannot read '{self.path.name}': none of its meshes could be read "
                f"({self._dropped[0]})."
            )
        if out:
            for kind, count in self._skipped_modes.items():
                self.warnings.append(
                    f"{count} {kind} primitive{'s' if count != 1 else ''} (no triangles) ignored"
                )
        return out

    def _unique(self, name: str) -> str:
        """Geometry names as authored; a second primitive or instance of one is ``name#2``."""
        self._names[name] = self._names.get(name, 0) + 1
        uses = self._names[name]
        return name if uses == 1 else f"{name}#{uses}"

    def _primitive(self, name: str, prim: dict[str, Any], matrix: np.ndarray) -> Mesh:
        attrs = prim.get("attributes")
        if not isinstance(attrs, dict):
            raise _Dropped("a primitive without attributes")
        mode = prim.get("mode", _TRIANGLES)
        if mode not in (_TRIANGLES, _STRIP, _FAN):
            raise _Dropped(f"unknown primitive mode {mode!r}")
        draco = as_dict(prim.get("extensions")).get("KHR_draco_mesh_compression")
        decoded = None
        if isinstance(draco, dict):
            try:
                decoded = self._draco(name, attrs, draco)
            except _Dropped as exc:
                # Draco is optional here when the file does not require it and the primitive
                # keeps plain accessors (a fallback for viewers without Draco): use those.
                if self._draco_required or attrs.get("POSITION") is None:
                    raise
                self.warnings.append(f"mesh '{name}': {exc}; its uncompressed copy is shown")
        tangents = None
        if decoded is not None:
            pos, normals, uvs, colors, flat = decoded
        else:
            pos = self._positions(attrs)
            normals = self._optional(name, attrs, "NORMAL", ("VEC3",), len(pos))
            uvs = self._optional(name, attrs, "TEXCOORD_0", ("VEC2",), len(pos))
            colors = self._optional(name, attrs, "COLOR_0", ("VEC3", "VEC4"), len(pos))
            flat = self._indices(prim, len(pos))
        tris = _triangles(flat, mode)
        tris = self._valid_triangles(name, tris, len(pos))
        has_colors = colors is not None
        material = self.materials.index(prim.get("material"), has_colors)
        uv_matrix = self.materials.uv_transform(prim.get("material"))
        if uv_matrix is not None and uvs is not None:  # KHR_texture_transform, baked
            uvs = np.asarray(uvs, np.float64) @ uv_matrix[:2, :2].T + uv_matrix[:2, 2]
        mesh = _world_mesh(name, pos, normals, uvs, colors, tris, material, matrix)
        if self.materials.materials[material].normal_texture is not None:
            # Only a normal-mapped material needs a tangent frame: the file's when it has one
            # that fits (and normals to go with it) and no transform turned its uvs, else one
            # made from the UVs.
            turned = uv_matrix is not None and not (
                uv_matrix[0, 1] == 0.0 == uv_matrix[1, 0] and (np.diag(uv_matrix)[:2] > 0).all()
            )
            if decoded is None and normals is not None and not turned:
                tangents = self._optional(name, attrs, "TANGENT", ("VEC4",), len(pos))
            if tangents is not None:
                mesh.tangents = transform_tangents(tangents, matrix[:3, :3])
            else:
                mesh.tangents = generate_tangents(
                    mesh.positions, mesh.normals, mesh.uvs, mesh.indices
                )
        return mesh

    def _positions(self, attrs: dict[str, Any]) -> np.ndarray:
        index = attrs.get("POSITION")
        try:
            if self.accessors.element_type(index) != "VEC3":
                raise _Dropped(f"its POSITION accessor {index} is not VEC3")
        except GltfDataError as exc:
            raise _Dropped(f"its POSITION is unusable ({exc})") from exc
        return self.accessors.read_float(index)

    def _optional(
        self, name: str, attrs: dict[str, Any], key: str, types: tuple[str, ...], n: int
    ) -> np.ndarray | None:
        """An optional attribute, or None (with a warning) when it does not fit the positions."""
        index = attrs.get(key)
        if index is None:
            return None
        try:
            kind = self.accessors.element_type(index)
            count = self.accessors.count(index)
        except GltfDataError as exc:
            self.warnings.append(f"mesh '{name}': {key} ignored ({exc})")
            return None
        if kind not in types or count != n:
            self.warnings.append(
                f"mesh '{name}': {key} ignored ({kind} x {count} for {n} vertices)"
            )
            return None
        return self.accessors.read_float(index)

    def _indices(self, prim: dict[str, Any], n: int) -> np.ndarray:
        index = prim.get("indices")
        if index is None:
            return np.arange(n, dtype=np.int64)
        try:
            count, dtype, ncomp = self.accessors.layout(index)
        except GltfDataError as exc:
            raise _Dropped(f"its indices are unusable ({exc})") from exc
        if ncomp != 1 or dtype.kind != "u":
            raise _Dropped(f"its indices accessor {index} is not unsigned SCALAR")
        return self.accessors.read(index)[:, 0].astype(np.int64)

    def _valid_triangles(self, name: str, tris: np.ndarray, n: int) -> np.ndarray:
        """Triangles whose three indices name existing vertices (the rest dropped, noted)."""
        ok = (tris < n).all(axis=1)
        bad = int(tris.shape[0] - np.count_nonzero(ok))
        if bad:
            self.warnings.append(
                f"mesh '{name}': {bad} triangle{'s' if bad != 1 else ''} referring to vertices "
                "that do not exist dropped"
            )
            tris = tris[ok]
        return tris

    def _draco(
        self, name: str, attrs: dict[str, Any], ext: dict[str, Any]
    ) -> tuple[np.ndarray, np.ndarray | None, np.ndarray | None, np.ndarray | None, np.ndarray]:
        """KHR_draco_mesh_compression: the payload decoded by DracoPy, attributes by unique id."""
        payload = self.accessors.view_bytes(ext.get("bufferView"), f"mesh '{name}' (Draco)")
        try:
            import DracoPy

            decoded = DracoPy.decode(bytes(payload))
        except Exception as exc:  # noqa: BLE001 - a damaged payload raises anything
            raise _Dropped(f"its Draco data could not be decoded ({exc})") from exc
        ids = as_dict(ext.get("attributes"))

        def attribute(key: str) -> np.ndarray | None:
            uid = ids.get(key)
            if not is_int(uid):
                return None
            found = decoded.get_attribute_by_unique_id(uid)
            if not found:
                return None
            data = np.asarray(found["data"])
            data = data.reshape(len(data), -1)
            normalized = False
            try:
                normalized = bool(self.accessors.spec(attrs.get(key)).get("normalized", False))
            except GltfDataError:
                pass
            return to_float(data, normalized)

        pos = attribute("POSITION")
        if pos is None or pos.shape[1] != 3:
            raise _Dropped("its Draco data has no POSITION")
        faces = getattr(decoded, "faces", None)
        if faces is None:
            raise _Dropped("its Draco data holds a point cloud, not triangles")
        flat = np.asarray(faces, np.int64).reshape(-1)
        extras = []
        for key, width in (("NORMAL", (3,)), ("TEXCOORD_0", (2,)), ("COLOR_0", (3, 4))):
            values = attribute(key)
            if values is not None and (values.shape[1] not in width or len(values) != len(pos)):
                self.warnings.append(f"mesh '{name}': Draco {key} ignored (it does not fit)")
                values = None
            extras.append(values)
        return pos, extras[0], extras[1], extras[2], flat


def _world_mesh(
    name: str,
    pos: np.ndarray,
    normals: np.ndarray | None,
    uvs: np.ndarray | None,
    colors: np.ndarray | None,
    tris: np.ndarray,
    material: int,
    matrix: np.ndarray,
) -> Mesh:
    """Bake the node transform and convert to the contract's dtypes and uv convention."""
    rot = matrix[:3, :3]
    with np.errstate(invalid="ignore", over="ignore"):  # NaN vertices: dropped later
        pos = pos @ rot.T + matrix[:3, 3]
    det = float(np.linalg.det(rot))
    if det < 0.0:
        tris = tris[:, [0, 2, 1]]  # a mirroring transform turns the winding inside out
    if normals is not None and abs(det) > 1e-12 and np.isfinite(det):
        with np.errstate(invalid="ignore", over="ignore"):
            normals = normals @ np.linalg.inv(rot)  # inverse transpose, applied to row vectors
            length = np.linalg.norm(normals, axis=1, keepdims=True)
            normals = normals / np.maximum(length, 1e-20)
    else:
        normals = vertex_normals(pos, tris)
    if uvs is None:
        uv32 = np.zeros((len(pos), 2), np.float32)
    else:
        uv32 = np.empty((len(pos), 2), np.float32)
        uv32[:, 0] = uvs[:, 0]
        uv32[:, 1] = 1.0 - uvs[:, 1]  # glTF's top-left origin -> OpenGL's bottom-left
    rgb = None
    if colors is not None:
        rgb = np.clip(np.nan_to_num(colors[:, :3], nan=1.0), 0.0, 1.0).astype(np.float32)
    return Mesh(
        name,
        pos,  # float64 until app.placement.place has scaled and re-centred it
        normals.astype(np.float32),
        uv32,
        tris.astype(np.uint32),
        material,
        rgb,
    )


def _triangles(flat: np.ndarray, mode: int) -> np.ndarray:
    """(M, 3) triangle list from TRIANGLES, TRIANGLE_STRIP or TRIANGLE_FAN indices."""
    n = len(flat)
    if mode == _TRIANGLES:
        return flat[: n - n % 3].reshape(-1, 3)
    if n < 3:
        return np.zeros((0, 3), np.int64)
    k = np.arange(n - 2)
    if mode == _STRIP:
        # glTF: triangle i is (v_i, v_{i+1+i%2}, v_{i+2-i%2}), so every one keeps the winding.
        odd = k % 2
        return np.stack([flat[k], flat[k + 1 + odd], flat[k + 2 - odd]], axis=1)
    # Fan: triangle i is (v_{i+1}, v_{i+2}, v_0).
    return np.stack([flat[k + 1], flat[k + 2], np.full(n - 2, flat[0])], axis=1)


def _primitives(mesh: dict[str, Any]) -> list[dict[str, Any]]:
    prims = mesh.get("primitives")
    return [p for p in prims if isinstance(p, dict)] if isinstance(prims, list) else []


def _size(n_bytes: int) -> str:
    if n_bytes >= 2**30:
        return f"{n_bytes / 2**30:.1f} GB"
    return f"{max(n_bytes / 2**20, 0.1):.1f} MB"
