"""trimesh scene -> our scene model: world-space meshes, linear materials, shared textures.

Since glTF has its own reader (:mod:`app.gltf_reader`), this serves OBJ and PLY; the glTF paths
here (``gltf_doc``, PBR materials) remain for trimesh-read files that carry PBR materials and as
the reference the glTF reader was checked against. See :mod:`app.loaders` for the
texture-coordinate contract this module keeps.
"""

from __future__ import annotations

import hashlib
import math
import re
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from app.color import srgb_to_linear
from app.images import fitted_size, image_to_rgba
from app.scene import Material, Mesh, Texture, vertex_normals
from app.tangents import generate_tangents

if TYPE_CHECKING:
    from PIL.Image import Image as PILImage

_GL_CLAMP_TO_EDGE = 33071

# OBJ "illum" models that mean glass; such materials are authored with a black Kd and their colour
# in the transmission filter Tf, which would otherwise render as opaque black windows.
_OBJ_GLASS_ILLUM = {4, 6, 7, 9}
_OBJ_GLASS_ALPHA = 0.5


class SceneBuilder:
    """Collects meshes, materials and textures, sharing what trimesh shares.

    Materials are keyed on the trimesh material object and textures on the PIL image object and
    then on their pixels (plus the wrap they are used with), so a texture referenced by ten
    materials is uploaded once.
    """

    def __init__(
        self,
        path: Path,
        gltf_doc: dict[str, Any] | None,
        warnings: list[str],
        max_texture_px: int = 8192,
    ) -> None:
        self.path = path
        self.max_texture_px = max_texture_px
        self.gltf = gltf_doc
        self.colors_linear = gltf_doc is not None  # glTF COLOR_0 is linear; OBJ/PLY are sRGB
        self.warnings = warnings
        self.meshes: list[Mesh] = []
        self.materials: list[Material] = []
        self.textures: list[Texture] = []
        self._material_keys: dict[Any, int] = {}
        self._texture_keys: dict[tuple[int, bool, bool], int | None] = {}
        self._texture_digests: dict[tuple[bytes, bool], int] = {}
        self._keep_alive: list[Any] = []  # objects whose id() is used as a key
        self._obj_untextured: dict[str, Any] = {}  # OBJ material name -> material without image
        # our material index -> (scale, offset) of its colour map's uvs (MTL ``-s``, ``-o``)
        self._obj_uv_placement: dict[int, tuple[tuple[float, float], tuple[float, float]]] = {}
        self._gltf_materials = self._index_gltf_materials()
        self._skipped_kinds: set[str] = set()
        self._name_uses: dict[str, int] = {}
        self._mtl_maps: dict[str, dict[str, MtlMap]] | None = None  # read on first use
        self._mtl_images: dict[Path, PILImage | None] = {}  # MTL map files, decoded once

    # ---- geometry ------------------------------------------------------------------------

    def add_trimesh_scene(self, tm_scene: Any) -> None:
        for node in tm_scene.graph.nodes_geometry:
            matrix, geom_name = tm_scene.graph[node]
            geom = tm_scene.geometry.get(geom_name)
            if geom is None:
                continue
            faces = getattr(geom, "faces", None)
            if faces is None:
                kind = type(geom).__name__
                if kind not in self._skipped_kinds:
                    self._skipped_kinds.add(kind)
                    self.warnings.append(f"{kind} geometry (no triangles) ignored")
                continue
            if len(faces) == 0:
                continue
            # Geometry names are stable; trimesh's node names for multi-primitive glTF meshes
            # carry a random suffix, so instances are numbered instead.
            name = str(geom_name)
            self._name_uses[name] = self._name_uses.get(name, 0) + 1
            if self._name_uses[name] > 1:
                name = f"{name}#{self._name_uses[name]}"
            self.meshes.append(self._mesh(name, geom, np.asarray(matrix, np.float64)))

    def _mesh(self, name: str, geom: Any, matrix: np.ndarray) -> Mesh:
        pos = np.asarray(geom.vertices, np.float64).reshape(-1, 3)
        idx = np.asarray(geom.faces, np.int64).reshape(-1, 3)
        normals = _authored_normals(geom)
        visual = getattr(geom, "visual", None)
        uvs = getattr(visual, "uv", None) if visual is not None else None
        uvs = (
            np.asarray(uvs, np.float64)[:, :2] if uvs is not None and len(uvs) == len(pos) else None
        )
        colors = self._vertex_colors(visual, len(pos))
        face_colors = self._face_colors(visual, len(idx))
        if face_colors is not None:
            # One colour per face: give each triangle its own three vertices so the colour can
            # ride on them (the renderer only knows vertex colours).
            flat = idx.reshape(-1)
            pos = pos[flat]
            normals = normals[flat] if normals is not None else None
            uvs = uvs[flat] if uvs is not None else None
            colors = np.repeat(face_colors, 3, axis=0)
            idx = np.arange(flat.size, dtype=np.int64).reshape(-1, 3)
        material = self._material_index(visual, colors is not None)
        placement = self._obj_uv_placement.get(material)
        if placement is not None and uvs is not None:  # the MTL's -s and -o, baked
            uvs = uvs * np.asarray(placement[0]) + np.asarray(placement[1])

        rot = matrix[:3, :3]
        with np.errstate(invalid="ignore", over="ignore"):  # NaN vertices: dropped later
            pos = pos @ rot.T + matrix[:3, 3]
        det = float(np.linalg.det(rot))
        if det < 0.0:
            idx = idx[:, [0, 2, 1]]  # a mirroring transform turns the winding inside out
        if normals is not None and abs(det) > 1e-12 and np.isfinite(det):
            normals = normals @ np.linalg.inv(rot)  # inverse transpose, applied to row vectors
            length = np.linalg.norm(normals, axis=1, keepdims=True)
            normals = normals / np.maximum(length, 1e-20)
        else:
            normals = vertex_normals(pos, idx)
        if uvs is None:
            uvs = np.zeros((len(pos), 2))
        tangents = None
        if self.materials[material].normal_texture is not None:
            tangents = generate_tangents(pos, normals, uvs, idx)
        return Mesh(
            name,
            pos,  # float64 until app.placement.place has scaled and re-centred it
            normals.astype(np.float32),
            uvs.astype(np.float32),
            idx.astype(np.uint32),
            material,
            None if colors is None else colors.astype(np.float32),
            tangents,
        )

    def _vertex_colors(self, visual: Any, n: int) -> np.ndarray | None:
        raw = None
        attrs = getattr(visual, "vertex_attributes", None)
        if attrs is not None and "color" in attrs:
            raw = np.asarray(attrs["color"])
        elif getattr(visual, "kind", None) == "vertex":
            raw = np.asarray(visual.vertex_colors)
        if raw is None or raw.ndim != 2 or raw.shape[0] != n or raw.shape[1] < 3:
            return None
        return self._to_linear_rgb(raw[:, :3])

    def _face_colors(self, visual: Any, n_faces: int) -> np.ndarray | None:
        if getattr(visual, "kind", None) != "face":
            return None
        raw = np.asarray(visual.face_colors)
        if raw.ndim != 2 or raw.shape[0] != n_faces or raw.shape[1] < 3:
            return None
        return self._to_linear_rgb(raw[:, :3])

    def _to_linear_rgb(self, raw: np.ndarray) -> np.ndarray:
        rgb = raw.astype(np.float64)
        if np.issubdtype(raw.dtype, np.integer):
            rgb = rgb / float(np.iinfo(raw.dtype).max)
        rgb = np.clip(np.nan_to_num(rgb, nan=1.0), 0.0, 1.0)
        # glTF COLOR_0 is linear (trimesh keeps it as floats, or as uint8 of the linear value
        # for untextured primitives); OBJ and PLY colours are sRGB bytes.
        return rgb if self.colors_linear else srgb_to_linear(rgb)

    # ---- materials -----------------------------------------------------------------------

    def _material_index(self, visual: Any, has_colors: bool) -> int:
        mat = getattr(visual, "material", None) if visual is not None else None
        if mat is None:
            # Vertex colours carry the colour: a white base keeps them as authored.
            key: Any = "vertex-colours" if has_colors else "default"
            if key not in self._material_keys:
                base = (1.0, 1.0, 1.0, 1.0) if has_colors else Material("default").base_color
                self._material_keys[key] = len(self.materials)
                self.materials.append(Material(key, base))
            return self._material_keys[key]
        key = id(mat)
        if key not in self._material_keys:
            self._keep_alive.append(mat)
            self._material_keys[key] = len(self.materials)
            self.materials.append(self._convert_material(mat))
        return self._material_keys[key]

    def _convert_material(self, mat: Any) -> Material:
        from trimesh.visual.material import PBRMaterial, SimpleMaterial

        if isinstance(mat, PBRMaterial):
            return self._pbr_material(mat)
        if isinstance(mat, SimpleMaterial):
            return self._simple_material(mat)
        return Material(str(getattr(mat, "name", None) or "material"))

    def _pbr_material(self, mat: Any) -> Material:
        """glTF factors, taken from the JSON where it has them.

        The JSON keeps full float precision, while trimesh rounds ``baseColorFactor`` to uint8,
        which crushes dark linear colours. trimesh's values stand in for keys the JSON lacks
        (it converts KHR_materials_pbrSpecularGlossiness, for one), then glTF's own defaults:
        white, fully metallic, fully rough.
        """
        name = str(mat.name or f"material {len(self.materials)}")
        doc = self._gltf_materials.get(mat.name, {}) if mat.name is not None else {}
        pbr = doc.get("pbrMetallicRoughness") or {}
        factor = mat.baseColorFactor
        tm_base = (
            (np.asarray(factor, np.float64) / 255.0).tolist()
            if factor is not None
            else [1.0, 1.0, 1.0, 1.0]
        )
        base = float_list(pbr.get("baseColorFactor", tm_base), 4, 1.0)
        metallic = float_or(pbr.get("metallicFactor", mat.metallicFactor), 1.0)
        roughness = float_or(pbr.get("roughnessFactor", mat.roughnessFactor), 1.0)
        emissive = float_list(doc.get("emissiveFactor", mat.emissiveFactor), 3, 0.0)
        strength = (doc.get("extensions") or {}).get("KHR_materials_emissive_strength")
        if isinstance(strength, dict):
            emissive = [e * float_or(strength.get("emissiveStrength"), 1.0) for e in emissive]
        alpha_mode = str(doc.get("alphaMode", mat.alphaMode or "OPAQUE"))
        repeat = True
        label: str | None = None
        tex_info = pbr.get("baseColorTexture")
        if isinstance(tex_info, dict):
            repeat = self._gltf_texture_repeats(tex_info)
            label = self._gltf_image_label(tex_info)
            if "KHR_texture_transform" in (tex_info.get("extensions") or {}):
                self.warnings.append(f"material '{name}': texture transform ignored")
            if mat.baseColorTexture is None:
                self.warnings.append(
                    f"material '{name}': base colour texture "
                    f"'{label or 'embedded image'}' could not be read, "
                    "using its colour only"
                )
        opaque = alpha_mode.upper() == "OPAQUE"
        if opaque:
            base[3] = 1.0  # glTF: alpha is ignored for OPAQUE materials
        mr = mat.metallicRoughnessTexture
        if mr is not None:
            # No per-pixel metal/roughness in the renderer: fold the map's average into the
            # factors (glTF: G = roughness, B = metalness) rather than ignore it.
            means = _image_channel_means(mr)
            if means is not None:
                roughness *= means[1]
                metallic *= means[2]
        texture = None
        if mat.baseColorTexture is not None:
            texture = self._texture_index(mat.baseColorTexture, name, label, repeat, opaque)
        return Material(
            name,
            (base[0], base[1], base[2], base[3]),
            texture,
            float(roughness),
            float(metallic),
            (emissive[0], emissive[1], emissive[2]),
        )

    def _simple_material(self, mat: Any) -> Material:
        """OBJ/MTL colours are sRGB; Blinn-Phong ``Ns`` becomes a roughness.

        trimesh reads only ``map_Kd``; the other maps come from the MTL itself (:meth:`_mtl`):
        ``norm`` (a tangent-space normal map) or ``map_Bump``/``bump`` (a height map, turned
        into a normal map), ``map_d`` (cut-out alpha, MASK), ``map_Ke`` (emissive). ``d`` or
        ``Tr`` below 1 makes the material BLEND.
        """
        name = str(mat.name or f"material {len(self.materials)}")
        kw: dict[str, Any] = getattr(mat, "kwargs", {}) or {}
        kd = float_list(kw.get("kd"), 3, -1.0)
        if min(kd) < 0.0:
            kd = (np.asarray(mat.diffuse, np.float64)[:3] / 255.0).tolist()
        rgb = srgb_to_linear(np.asarray(kd, np.float64)).tolist()
        alpha = 1.0
        if "d" in kw:
            alpha = float_or(first(kw["d"]), 1.0)
        elif "tr" in kw:
            alpha = 1.0 - float_or(first(kw["tr"]), 0.0)
            if alpha <= 0.0:
                # Some exporters write Tr as opacity; an invisible material is the worse guess.
                alpha = 1.0
        illum = int(float_or(first(kw.get("illum")), 2.0))
        tf = float_list(kw.get("tf"), 3, 1.0)
        if illum in _OBJ_GLASS_ILLUM and max(kd) < 0.02 and min(tf) < 0.999:
            # Coloured glass: its colour is the transmission filter, and it is see-through.
            rgb = srgb_to_linear(np.asarray(tf, np.float64)).tolist()
            alpha = min(alpha, _OBJ_GLASS_ALPHA)
        ns = float_or(kw.get("ns", getattr(mat, "glossiness", None)), 10.0)
        roughness = math.sqrt(2.0 / (max(ns, 0.0) + 2.0))
        emissive = srgb_to_linear(np.asarray(float_list(kw.get("ke"), 3, 0.0))).tolist()
        maps = self._mtl().get(name, {})
        texture = None
        image = getattr(mat, "image", None)
        diffuse = maps.get("map_kd")
        if image is None and diffuse is not None and diffuse.path.is_file():
            # trimesh takes the whole rest of the line for the file name, so a map with options
            # (Blender's ``-s 2 2 1 oak.jpg``) was lost: read it here.
            image = self._map_image(diffuse, name, "colour")
        if diffuse is not None and diffuse.placed:
            self._obj_uv_placement[len(self.materials)] = (diffuse.scale, diffuse.offset)
        cutout = self._map_image(maps.get("map_d"), name, "alpha")
        if image is not None and cutout is not None:
            image = _with_alpha(image, cutout)
        elif cutout is not None:
            image = _with_alpha(None, cutout)
        if image is not None:
            texture = self._texture_index(image, name, None, True, False)
        else:
            self._obj_untextured[name] = mat
        normal_texture = None
        normal_scale = 1.0
        if "norm" in maps:
            normal = self._map_image(maps["norm"], name, "normal")
            if normal is not None:
                normal_texture = self._texture_index(normal, name, maps["norm"].file, True, True)
        else:
            bump = maps.get("map_bump") or maps.get("bump")
            height = self._map_image(bump, name, "bump")
            if bump is not None and height is not None:
                normal = _height_to_normal(height, bump.multiplier)
                normal_texture = self._texture_index(normal, name, bump.file, True, True)
        emissive_texture = None
        glow = self._map_image(maps.get("map_ke"), name, "emissive")
        if glow is not None:
            emissive_texture = self._texture_index(glow, name, maps["map_ke"].file, True, True)
            if max(emissive) <= 0.0:
                emissive = [1.0, 1.0, 1.0]  # a map without Ke: the map is the glow
        alpha = float(np.clip(alpha, 0.0, 1.0))
        mode = "MASK" if cutout is not None else "BLEND" if alpha < 0.999 else "OPAQUE"
        return Material(
            name,
            (rgb[0], rgb[1], rgb[2], alpha if mode == "BLEND" else 1.0),
            texture,
            roughness,
            0.0,
            (emissive[0], emissive[1], emissive[2]),
            normal_texture=normal_texture,
            normal_scale=normal_scale,
            emissive_texture=emissive_texture,
            alpha_mode=mode,
        )

    def _mtl(self) -> dict[str, dict[str, MtlMap]]:
        if self._mtl_maps is None:
            self._mtl_maps = _obj_maps(self.path)
        return self._mtl_maps

    def _map_image(self, spec: MtlMap | None, material: str, role: str) -> PILImage | None:
        """An MTL map's image (decoded once per file), or None with a warning."""
        if spec is None:
            return None
        from PIL import Image

        if spec.path in self._mtl_images:
            return self._mtl_images[spec.path]
        try:
            with Image.open(spec.path) as opened:
                image = self._fit(opened.copy(), material, spec.file)
        except Exception as exc:  # noqa: BLE001 - PIL raises anything for a broken file
            self.warnings.append(
                f"material '{material}': {role} map '{spec.file}' could not be read ({exc}), "
                f"shaded without it"
            )
            self._mtl_images[spec.path] = None
            return None
        self._mtl_images[spec.path] = image
        return image

    # ---- textures ------------------------------------------------------------------------

    def _texture_index(
        self, image: PILImage, material: str, label: str | None, repeat: bool, opaque: bool
    ) -> int | None:
        key = (id(image), repeat, opaque)
        if key in self._texture_keys:
            return self._texture_keys[key]
        self._keep_alive.append(image)
        label = str(
            label or image.info.get("file_path") or getattr(image, "filename", "") or material
        )
        try:
            image = self._fit(image, material, label)
            rgba = _image_to_rgba(image)
        except Exception as exc:  # noqa: BLE001 - PIL decodes lazily and raises anything
            self.warnings.append(
                f"material '{material}': texture '{Path(label).name}' could "
                f"not be decoded ({exc}), using its colour only"
            )
            self._texture_keys[key] = None
            return None
        if opaque:
            rgba = rgba.copy()
            rgba[:, :, 3] = 255
        # trimesh opens an OBJ texture once per material that names it: compare pixels too.
        digest = (
            hashlib.blake2b(rgba.tobytes(), digest_size=16).digest() + repr(rgba.shape).encode()
        )
        index = self._texture_digests.get((digest, repeat))
        if index is None:
            index = len(self.textures)
            self._texture_digests[(digest, repeat)] = index
            self.textures.append(Texture(Path(label).name or material, rgba, repeat))
        self._texture_keys[key] = index
        return index

    def _fit(self, image: PILImage, material: str, label: str) -> PILImage:
        """``image`` no larger than ``scene.max_texture_px`` on its longest side (noted)."""
        from PIL import Image

        w, h = image.size
        target = fitted_size((w, h), self.max_texture_px)
        if target == (w, h):
            return image
        if image.format == "JPEG":
            image.draft("RGB", target)  # decode at a power-of-two reduction, at least `target`
        self.warnings.append(
            f"material '{material}': texture '{Path(label).name}' downscaled from {w} x {h} "
            f"to {target[0]} x {target[1]} (scene.max_texture_px)"
        )
        return image.resize(target, Image.Resampling.BILINEAR, reducing_gap=2.0)

    # ---- glTF details trimesh does not keep ----------------------------------------------

    def _index_gltf_materials(self) -> dict[str, dict[str, Any]]:
        """glTF materials by name, for names that are unique (trimesh keeps only the name)."""
        if self.gltf is None:
            return {}
        mats = [m for m in self.gltf.get("materials", []) or [] if isinstance(m, dict)]
        counts: dict[str, int] = {}
        for m in mats:
            if "name" in m:
                counts[str(m["name"])] = counts.get(str(m["name"]), 0) + 1
        return {str(m["name"]): m for m in mats if "name" in m and counts[str(m["name"])] == 1}

    def _gltf_texture_repeats(self, tex_info: dict[str, Any]) -> bool:
        """False only when the sampler explicitly clamps; mirrored repeat is treated as repeat."""
        assert self.gltf is not None
        try:
            texture = self.gltf["textures"][int(tex_info["index"])]
            sampler = self.gltf["samplers"][int(texture["sampler"])]
        except (KeyError, IndexError, TypeError, ValueError):
            return True
        return _GL_CLAMP_TO_EDGE not in (sampler.get("wrapS"), sampler.get("wrapT"))

    def _gltf_image_label(self, tex_info: dict[str, Any]) -> str | None:
        """The image's file name or name, to name textures and missing files after."""
        assert self.gltf is not None
        try:
            texture = self.gltf["textures"][int(tex_info["index"])]
            image = self.gltf["images"][int(texture["source"])]
        except (KeyError, IndexError, TypeError, ValueError):
            return None
        uri = image.get("uri")
        if isinstance(uri, str) and not uri.startswith("data:"):
            return uri
        name = image.get("name")
        return str(name) if name else None

    def warn_missing_obj_textures(self) -> None:
        """Name the texture files an OBJ's MTL asks for that trimesh could not read.

        trimesh drops an unreadable ``map_Kd`` silently, so the MTL is read again here.
        """
        if not self._obj_untextured:
            return
        wanted = _obj_diffuse_maps(self.path)
        for name in self._obj_untextured:
            if name in wanted:
                self.warnings.append(
                    f"material '{name}': texture '{wanted[name]}' is missing "
                    "or unreadable, using its colour only"
                )


def _authored_normals(geom: Any) -> np.ndarray | None:
    """Normals stored by the file, or None when trimesh would have to compute them.

    trimesh computes ``vertex_normals`` on access, so only what its loader put in the cache
    counts as authored.
    """
    cache = getattr(geom, "_cache", None)
    try:
        if cache is None or "vertex_normals" not in cache:
            return None
        normals = np.asarray(geom.vertex_normals, np.float64)
    except Exception:  # noqa: BLE001 - private trimesh API: any change means "not authored"
        return None
    if normals.shape != np.asarray(geom.vertices).shape:
        return None
    return normals


@dataclass
class MtlMap:
    """One texture map statement of an MTL material."""

    file: str  # as written
    path: Path  # resolved next to the MTL
    multiplier: float = 1.0  # ``-bm`` (bump maps)
    scale: tuple[float, float] = (1.0, 1.0)  # ``-s u v``: the map tiles this many times
    offset: tuple[float, float] = (0.0, 0.0)  # ``-o u v``: and is shifted by this

    @property
    def placed(self) -> bool:
        return self.scale != (1.0, 1.0) or self.offset != (0.0, 0.0)


# A map statement's options and how many values each takes (the MTL spec); ``-o``, ``-s`` and
# ``-t`` take one to three numbers (the values that read as numbers are theirs).
_MTL_OPTION_VALUES = {
    "-blendu": 1,
    "-blendv": 1,
    "-bm": 1,
    "-boost": 1,
    "-cc": 1,
    "-clamp": 1,
    "-imfchan": 1,
    "-mm": 2,
    "-texres": 1,
    "-type": 1,
}
_MTL_VECTOR_OPTIONS = ("-o", "-s", "-t")


def mtl_map_statement(parts: list[str]) -> tuple[str, dict[str, list[float]]]:
    """An MTL map statement's file name (which may hold spaces) and its options, from the
    tokens after the statement's keyword: ``-s 2 2 1 oak floor.jpg`` is ``oak floor.jpg``
    tiled twice. Blender writes ``-s`` and ``-o`` for a scaled or shifted texture."""
    options: dict[str, list[float]] = {}
    i = 0
    while i < len(parts) - 1 and parts[i].startswith("-"):
        key = parts[i].lower()
        if key in _MTL_VECTOR_OPTIONS:
            values: list[float] = []
            while i + 1 < len(parts) - 1 and len(values) < 3 and _is_number(parts[i + 1]):
                values.append(float(parts[i + 1]))
                i += 1
            options[key] = values
            i += 1
        elif key in _MTL_OPTION_VALUES:
            n = _MTL_OPTION_VALUES[key]
            options[key] = [float_or(v, 0.0) for v in parts[i + 1 : i + 1 + n]]
            i += 1 + n
        else:
            break  # not an option: the file name starts here
    return " ".join(parts[i:]), options


def _is_number(token: str) -> bool:
    try:
        return math.isfinite(float(token))
    except ValueError:
        return False


_MTL_MAPS = ("map_kd", "map_bump", "bump", "norm", "map_d", "map_ke")


def _obj_maps(obj_path: Path) -> dict[str, dict[str, MtlMap]]:
    """The texture maps (lower-case statement -> map) per material name from the MTL files an
    OBJ names."""
    try:
        text = obj_path.read_bytes()
    except OSError:
        return {}
    result: dict[str, dict[str, MtlMap]] = {}
    for match in re.finditer(rb"^[ \t]*mtllib[ \t]+(.+?)[ \t]*\r?$", text, re.MULTILINE):
        mtl = obj_path.parent / match.group(1).decode("utf-8", "replace")
        try:
            lines = mtl.read_text("utf-8", "replace").splitlines()
        except OSError:
            continue
        current = None
        for line in lines:
            parts = line.split()
            if len(parts) >= 2 and parts[0].lower() == "newmtl":
                current = " ".join(parts[1:])
            elif len(parts) >= 2 and parts[0].lower() in _MTL_MAPS and current is not None:
                name, options = mtl_map_statement(parts[1:])
                file = name.replace("\\", "/")
                su, sv = (options.get("-s", []) + [1.0, 1.0])[:2]  # the spec's defaults
                ou, ov = (options.get("-o", []) + [0.0, 0.0])[:2]
                result.setdefault(current, {})[parts[0].lower()] = MtlMap(
                    file, mtl.parent / file, (options.get("-bm") or [1.0])[0], (su, sv), (ou, ov)
                )
    return result


def _obj_diffuse_maps(obj_path: Path) -> dict[str, str]:
    """``map_Kd`` file per material name from the MTL files an OBJ names."""
    return {
        name: maps["map_kd"].file for name, maps in _obj_maps(obj_path).items() if "map_kd" in maps
    }


# Slope of a bump map: a height step of 1/BUMP_SLOPE (in 0..1) between neighbouring texels
# tilts the normal by 45 degrees (times the map's -bm multiplier).
BUMP_SLOPE = 4.0


def _height_to_normal(height: PILImage, multiplier: float) -> PILImage:
    """A bump (height) map, bright = raised, as a tangent-space normal map (+Y up the image)."""
    from PIL import Image

    h = np.asarray(height.convert("L"), np.float64) / 255.0
    # Central differences with repeat wrapping (bump maps tile); rows run down the image.
    du = (np.roll(h, -1, axis=1) - np.roll(h, 1, axis=1)) * 0.5
    dv = (np.roll(h, 1, axis=0) - np.roll(h, -1, axis=0)) * 0.5  # +v is up the image
    k = BUMP_SLOPE * multiplier
    n = np.stack([-du * k, -dv * k, np.ones_like(h)], axis=-1)
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    rgb = np.clip((n * 0.5 + 0.5) * 255.0 + 0.5, 0, 255).astype(np.uint8)
    return Image.fromarray(rgb, "RGB")


def _with_alpha(image: PILImage | None, alpha: PILImage) -> PILImage:
    """``image`` (white when None) with ``alpha``'s luminance as its alpha channel."""
    from PIL import Image

    base = image.convert("RGB") if image is not None else Image.new("RGB", alpha.size, "white")
    mask = alpha.convert("L").resize(base.size)
    out = base.copy()
    out.putalpha(mask)
    return out


def _image_to_rgba(image: PILImage) -> np.ndarray:
    """HxWx4 uint8, row 0 = top (the same conversion glTF textures get)."""
    return image_to_rgba(image)


def _image_channel_means(image: PILImage) -> tuple[float, float, float] | None:
    try:
        small = image.convert("RGB")
        small.thumbnail((64, 64))
        arr = np.asarray(small, np.float64) / 255.0
    except Exception:  # noqa: BLE001 - a broken auxiliary map only loses its averages
        return None
    m = arr.reshape(-1, 3).mean(axis=0)
    return float(m[0]), float(m[1]), float(m[2])


def first(value: Any) -> Any:
    if isinstance(value, (list, tuple)):
        return value[0] if value else None
    return value


def float_or(value: Any, fallback: float) -> float:
    try:
        v = float(first(value)) if isinstance(value, (list, tuple)) else float(value)
    except (TypeError, ValueError):
        return fallback
    return v if math.isfinite(v) else fallback


def float_list(value: Any, n: int, fallback: float) -> list[float]:
    if value is None:
        return [fallback] * n
    try:
        items = [float(v) for v in np.asarray(value).reshape(-1)[:n]]
    except (TypeError, ValueError):
        return [fallback] * n
    items = [v if math.isfinite(v) else fallback for v in items]
    return items + [fallback] * (n - len(items))
