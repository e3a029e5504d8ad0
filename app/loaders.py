"""Turn a glTF, GLB, OBJ or PLY file into a :class:`~app.scene.Scene` you can stand inside.

trimesh does the parsing; this module decides what the result means for a walkable VR preview:
node transforms are baked so every mesh is in world space (Y up, metres), materials become linear
colours plus de-duplicated RGBA8 textures, and the viewer is placed where a person would stand.
For an interior that is on the main floor at eye height, facing down the longest free direction,
found with batched ray casts; a lone object is viewed from outside instead. Files without lights
get a few default point lights so the first frame is never black.

Texture-coordinate contract (the renderer relies on it): ``Texture.rgba`` row 0 is the top row of
the image, and a mesh's ``uv`` follows OpenGL's bottom-left origin, i.e. ``v = 1`` is the top image
row and ``v = 1 - row / height``. trimesh already flips glTF's top-left ``v`` into this convention
and OBJ ``vt`` is authored in it, so uvs pass through unchanged (values outside [0, 1] included:
they mean repeat wrapping). A renderer that uploads row 0 first must therefore sample at
``(u, 1 - v)`` or upload the rows bottom-up.

Every problem the user can fix (missing file, unsupported type, damaged data, no triangles)
raises :class:`SceneLoadError` with the file name in the message; problems that still leave
something to look at (a missing texture, NaN vertices, an unsupported light type) load anyway and
are listed in ``Scene.warnings``.
"""

from __future__ import annotations

import hashlib
import json
import logging
import math
import os
import re
import struct
from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from app.raycast import RayCaster
from app.scene import Material, Mesh, PointLight, Scene, Texture, Viewpoint, vertex_normals

if TYPE_CHECKING:
    from PIL.Image import Image as PILImage

log = logging.getLogger(__name__)

SUPPORTED_EXTENSIONS = (".gltf", ".glb", ".obj", ".ply")

EYE_HEIGHT_M = 1.6
# Head room above the eye: a "floor" with less than this up to the next surface is a shelf, a
# vault's upper face or a slab's underside, not somewhere to stand.
_MIN_CLEARANCE_M = EYE_HEIGHT_M + 0.3
_BODY_RADIUS_M = 0.35  # nearest wall allowed around a spawn candidate at eye height
_GRID_TARGET = 2500  # candidate columns for the spawn search; ~60k rays with embree is ~0.1 s
_MAX_LAYERS = 12  # surfaces peeled per column: roof, vaults, floors, slabs...
_RING_DIRECTIONS = 16
_INSIDE_HIT_FRACTION = 0.75  # "most" horizontal rays must hit something to count as enclosed
_FRONT_FACING_FRACTION = 0.5  # of those hits, the share that must face the eye
_MIN_REVERSED_ROOM_M2 = 20.0  # floor area that makes an inside-out enclosure a room
_LEVEL_BIN_M = 0.35  # floor heights closer than this are one level (thresholds, small steps)
# A lone object's bounding sphere covers this share of a 90 degree view from the spawn.
_OBJECT_VIEW_FILL = 0.6
_LIGHT_TARGET_RADIANCE = 1.0  # per default light, at a typical surface distance
_M_PER_LIGHT = 150.0  # floor area one default interior light is expected to cover (m^2)

_GL_CLAMP_TO_EDGE = 33071
_GLB_MAGIC = b"glTF"
_GLB_JSON_CHUNK = 0x4E4F534A

# OBJ "illum" models that mean glass; such materials are authored with a black Kd and their colour
# in the transmission filter Tf, which would otherwise render as opaque black windows.
_OBJ_GLASS_ILLUM = {4, 6, 7, 9}
_OBJ_GLASS_ALPHA = 0.5


class SceneLoadError(Exception):
    """A file that cannot become a scene; the message is meant for the person who picked it."""


@dataclass
class SpawnResult:
    """Where to stand, and what the search learnt about the walkable level (for default lights).

    ``level_points`` are floor positions on the chosen level that passed the "inside" test, with
    the head room above each in ``level_clearance`` and the distance to the nearest wall at eye
    height in ``level_free``; all are empty for an outside view.
    """

    viewpoint: Viewpoint
    floor_y: float | None
    level_points: np.ndarray  # (K, 3) float64
    level_clearance: np.ndarray  # (K,) float64
    level_free: np.ndarray  # (K,) distance to the nearest wall at eye height
    cell_area: float  # floor area each level point stands for (m^2)
    free_distance: float  # free distance along the view direction (m); inf when unbounded


# --------------------------------------------------------------------------------------------
# public entry point
# --------------------------------------------------------------------------------------------


def load_scene(path: str | os.PathLike[str]) -> Scene:
    """Load ``path`` into a sanitized Scene with spawn, floor height and lights filled in.

    Raises :class:`SceneLoadError` for anything that leaves nothing to show, so callers can show
    the message to the user as it is.
    """
    p = Path(path)
    if not p.exists():
        raise SceneLoadError(f"Cannot open '{p}': the file does not exist.")
    if not p.is_file():
        raise SceneLoadError(f"Cannot open '{p}': it is a folder, not a scene file.")
    ext = p.suffix.lower()
    if ext not in SUPPORTED_EXTENSIONS:
        kind = f"'{ext}' files are" if ext else "files without an extension are"
        raise SceneLoadError(
            f"Cannot open '{p.name}': {kind} not supported "
            f"(supported: {', '.join(SUPPORTED_EXTENSIONS)})."
        )

    warnings: list[str] = []
    gltf_doc = _read_gltf_json(p) if ext in (".gltf", ".glb") else None
    tm_scene = _trimesh_load(p)
    builder = _SceneBuilder(p, gltf_doc, warnings)
    builder.add_trimesh_scene(tm_scene)
    if ext == ".obj":
        builder.warn_missing_obj_textures()
    lights = _gltf_lights(gltf_doc, warnings) if gltf_doc is not None else []

    raw = Scene(
        name=p.stem,
        meshes=builder.meshes,
        materials=builder.materials,
        textures=builder.textures,
        lights=lights,
        source=str(path),
        warnings=warnings,
    )
    if raw.triangle_count == 0:
        raise SceneLoadError(
            f"Cannot show '{p.name}': it contains no triangles "
            "(it is empty, or holds only points or lines)."
        )
    scene = raw.sanitized()
    if not scene.meshes:
        raise SceneLoadError(
            f"Cannot show '{p.name}': none of its triangles are valid "
            "(every vertex position is broken or every triangle is flat)."
        )

    caster = RayCaster(scene.triangles(), np.arange(scene.triangle_count))
    spawn = find_spawn(scene, caster)
    notes = list(scene.warnings)
    lights = scene.lights
    if not lights:
        lights = default_lights(scene, spawn, caster)
        notes.append(
            f"the file has no lights: added {len(lights)} default point "
            f"light{'s' if len(lights) != 1 else ''} so the scene is visible"
        )
    if spawn.floor_y is None:
        log.info("%s: no interior found, viewing it from outside", p.name)
    return replace(
        scene,
        spawn=spawn.viewpoint,
        floor_y=spawn.floor_y,
        lights=lights,
        warnings=notes,
        indirect=_gltf_wants_indirect(gltf_doc),
    ).sanitized()


def _gltf_wants_indirect(doc: dict[str, Any] | None) -> bool:
    """The scene option for photon-mapped indirect light: ``"extras": {"vrpreview":
    {"indirect": true}}`` on the glTF document or on its default scene."""
    if not isinstance(doc, dict):
        return False
    holders = [doc]
    scenes = doc.get("scenes")
    index = doc.get("scene", 0)
    if isinstance(scenes, list) and isinstance(index, int) and 0 <= index < len(scenes):
        holders.append(scenes[index])
    for holder in holders:
        extras = holder.get("extras") if isinstance(holder, dict) else None
        options = extras.get("vrpreview") if isinstance(extras, dict) else None
        if isinstance(options, dict) and options.get("indirect") is True:
            return True
    return False


# --------------------------------------------------------------------------------------------
# reading files
# --------------------------------------------------------------------------------------------


def _read_gltf_json(path: Path) -> dict[str, Any]:
    """The glTF JSON document, read by us because trimesh drops samplers and lights.

    Reading it first also turns a truncated or non-glTF file into a message that names the
    problem instead of whatever trimesh trips over later.
    """
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise SceneLoadError(f"Cannot read '{path.name}': {exc.strerror or exc}.") from exc
    if path.suffix.lower() == ".glb":
        if len(data) < 20 or data[:4] != _GLB_MAGIC:
            raise SceneLoadError(
                f"Cannot read '{path.name}': it is not a binary glTF (.glb) "
                "file (the glTF header is missing or damaged)."
            )
        version = struct.unpack_from("<I", data, 4)[0]
        if version != 2:
            raise SceneLoadError(
                f"Cannot read '{path.name}': only glTF 2.0 is supported "
                f"(this file says version {version})."
            )
        chunk_len, chunk_type = struct.unpack_from("<II", data, 12)
        if chunk_type != _GLB_JSON_CHUNK or 20 + chunk_len > len(data):
            raise SceneLoadError(
                f"Cannot read '{path.name}': the file is truncated or damaged "
                "(its JSON chunk is missing or cut short)."
            )
        text = data[20 : 20 + chunk_len]
    else:
        text = data
    try:
        doc = json.loads(text.decode("utf-8-sig"))
    except UnicodeDecodeError as exc:
        raise SceneLoadError(
            f"Cannot read '{path.name}': it is not a glTF file "
            "(the content is not UTF-8 JSON text)."
        ) from exc
    except json.JSONDecodeError as exc:
        raise SceneLoadError(
            f"Cannot read '{path.name}': its glTF JSON is invalid or truncated "
            f"({exc.msg} at line {exc.lineno}, column {exc.colno})."
        ) from exc
    if not isinstance(doc, dict):
        raise SceneLoadError(f"Cannot read '{path.name}': it is JSON but not a glTF document.")
    version = (
        str(doc.get("asset", {}).get("version", "2.0"))
        if isinstance(doc.get("asset"), dict)
        else "2.0"
    )
    if not version.startswith("2"):
        raise SceneLoadError(
            f"Cannot read '{path.name}': only glTF 2.0 is supported "
            f"(this file says version {version})."
        )
    return doc


def _trimesh_load(path: Path) -> Any:
    """trimesh's scene, with every parser failure turned into a message for the user.

    ``process=False`` keeps the data as authored: trimesh would otherwise merge vertices and
    silently drop NaN ones, and :meth:`Scene.sanitized` is where repairs are made and reported.
    """
    import trimesh

    try:
        return trimesh.load_scene(str(path), process=False)
    except FileNotFoundError as exc:
        missing = Path(exc.filename).name if exc.filename else str(exc)
        raise SceneLoadError(
            f"Cannot read '{path.name}': a file it needs is missing ({missing})."
        ) from exc
    except MemoryError as exc:
        raise SceneLoadError(
            f"Cannot read '{path.name}': it is too large for the available memory."
        ) from exc
    except Exception as exc:  # noqa: BLE001 - parsers raise anything on damaged input
        detail = str(exc).strip() or type(exc).__name__
        if isinstance(exc, (ImportError, UnicodeDecodeError)):
            # trimesh reaches for an optional text-encoding detector on undecodable bytes.
            detail = "its content is not readable text"
        if len(detail) > 200:
            detail = detail[:200] + "..."
        raise SceneLoadError(
            f"Cannot read '{path.name}': the file is damaged or not a valid "
            f"{path.suffix.lower().lstrip('.').upper()} file ({detail})."
        ) from exc


# --------------------------------------------------------------------------------------------
# trimesh scene -> our scene model
# --------------------------------------------------------------------------------------------


class _SceneBuilder:
    """Collects meshes, materials and textures, sharing what trimesh shares.

    Materials are keyed on the trimesh material object and textures on the PIL image object and
    then on their pixels (plus the wrap they are used with), so a texture referenced by ten
    materials is uploaded once.
    """

    def __init__(self, path: Path, gltf_doc: dict[str, Any] | None, warnings: list[str]) -> None:
        self.path = path
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
        self._gltf_materials = self._index_gltf_materials()
        self._skipped_kinds: set[str] = set()
        self._name_uses: dict[str, int] = {}

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
        return Mesh(
            name,
            pos.astype(np.float32),
            normals.astype(np.float32),
            uvs.astype(np.float32),
            idx.astype(np.uint32),
            material,
            None if colors is None else colors.astype(np.float32),
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
        base = _float_list(pbr.get("baseColorFactor", tm_base), 4, 1.0)
        metallic = _float_or(pbr.get("metallicFactor", mat.metallicFactor), 1.0)
        roughness = _float_or(pbr.get("roughnessFactor", mat.roughnessFactor), 1.0)
        emissive = _float_list(doc.get("emissiveFactor", mat.emissiveFactor), 3, 0.0)
        strength = (doc.get("extensions") or {}).get("KHR_materials_emissive_strength")
        if isinstance(strength, dict):
            emissive = [e * _float_or(strength.get("emissiveStrength"), 1.0) for e in emissive]
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

        Bump and normal maps (``bump``/``map_bump``) are ignored on purpose: the renderer has no
        normal mapping, and trimesh does not load them anyway.
        """
        name = str(mat.name or f"material {len(self.materials)}")
        kw: dict[str, Any] = getattr(mat, "kwargs", {}) or {}
        kd = _float_list(kw.get("kd"), 3, -1.0)
        if min(kd) < 0.0:
            kd = (np.asarray(mat.diffuse, np.float64)[:3] / 255.0).tolist()
        rgb = srgb_to_linear(np.asarray(kd, np.float64)).tolist()
        alpha = 1.0
        if "d" in kw:
            alpha = _float_or(_first(kw["d"]), 1.0)
        elif "tr" in kw:
            alpha = 1.0 - _float_or(_first(kw["tr"]), 0.0)
            if alpha <= 0.0:
                # Some exporters write Tr as opacity; an invisible material is the worse guess.
                alpha = 1.0
        illum = int(_float_or(_first(kw.get("illum")), 2.0))
        tf = _float_list(kw.get("tf"), 3, 1.0)
        if illum in _OBJ_GLASS_ILLUM and max(kd) < 0.02 and min(tf) < 0.999:
            # Coloured glass: its colour is the transmission filter, and it is see-through.
            rgb = srgb_to_linear(np.asarray(tf, np.float64)).tolist()
            alpha = min(alpha, _OBJ_GLASS_ALPHA)
        ns = _float_or(kw.get("ns", getattr(mat, "glossiness", None)), 10.0)
        roughness = math.sqrt(2.0 / (max(ns, 0.0) + 2.0))
        emissive = srgb_to_linear(np.asarray(_float_list(kw.get("ke"), 3, 0.0))).tolist()
        texture = None
        image = getattr(mat, "image", None)
        if image is not None:
            texture = self._texture_index(image, name, None, True, False)
        else:
            self._obj_untextured[name] = mat
        return Material(
            name,
            (rgb[0], rgb[1], rgb[2], float(np.clip(alpha, 0.0, 1.0))),
            texture,
            roughness,
            0.0,
            (emissive[0], emissive[1], emissive[2]),
        )

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


def _obj_diffuse_maps(obj_path: Path) -> dict[str, str]:
    """``map_Kd`` file per material name from the MTL files an OBJ names."""
    try:
        text = obj_path.read_bytes()
    except OSError:
        return {}
    result: dict[str, str] = {}
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
            elif len(parts) >= 2 and parts[0].lower() == "map_kd" and current is not None:
                result[current] = parts[-1]
    return result


def _image_to_rgba(image: PILImage) -> np.ndarray:
    """HxWx4 uint8, row 0 = top; 16-bit and float images are scaled, not clipped."""
    mode = image.mode
    if mode in ("I;16", "I;16B", "I;16L", "I", "F"):
        arr = np.asarray(image, np.float64)
        hi = 65535.0 if mode.startswith("I;16") else max(float(np.nanmax(arr)), 1.0)
        if mode == "F":
            hi = 1.0
        grey = (np.clip(np.nan_to_num(arr / hi), 0.0, 1.0) * 255.0 + 0.5).astype(np.uint8)
        rgba = np.stack([grey, grey, grey, np.full_like(grey, 255)], axis=2)
    else:
        rgba = np.asarray(image.convert("RGBA"), np.uint8)
    return np.ascontiguousarray(rgba)


def _image_channel_means(image: PILImage) -> tuple[float, float, float] | None:
    try:
        small = image.convert("RGB")
        small.thumbnail((64, 64))
        arr = np.asarray(small, np.float64) / 255.0
    except Exception:  # noqa: BLE001 - a broken auxiliary map only loses its averages
        return None
    m = arr.reshape(-1, 3).mean(axis=0)
    return float(m[0]), float(m[1]), float(m[2])


def srgb_to_linear(c: np.ndarray) -> np.ndarray:
    """sRGB-encoded values in [0, 1] to linear light (the renderer shades in linear)."""
    c = np.clip(np.asarray(c, np.float64), 0.0, 1.0)
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


def _first(value: Any) -> Any:
    if isinstance(value, (list, tuple)):
        return value[0] if value else None
    return value


def _float_or(value: Any, fallback: float) -> float:
    try:
        v = float(_first(value)) if isinstance(value, (list, tuple)) else float(value)
    except (TypeError, ValueError):
        return fallback
    return v if math.isfinite(v) else fallback


def _float_list(value: Any, n: int, fallback: float) -> list[float]:
    if value is None:
        return [fallback] * n
    try:
        items = [float(v) for v in np.asarray(value).reshape(-1)[:n]]
    except (TypeError, ValueError):
        return [fallback] * n
    items = [v if math.isfinite(v) else fallback for v in items]
    return items + [fallback] * (n - len(items))


# --------------------------------------------------------------------------------------------
# glTF lights (KHR_lights_punctual)
# --------------------------------------------------------------------------------------------


def _gltf_lights(doc: dict[str, Any], warnings: list[str]) -> list[PointLight]:
    """Point and spot lights as point lights at their node's world position.

    glTF point intensity is in candela, which is what ``PointLight.intensity`` means (radiance
    scale at 1 m). A glTF light without a range reaches everything; ours must stop somewhere, so
    it stops where it has fallen to 1/1000 of its value at 1 m.
    """
    ext = (doc.get("extensions") or {}).get("KHR_lights_punctual") or {}
    defs = ext.get("lights") or []
    if not defs:
        return []
    world = _gltf_world_matrices(doc)
    nodes = doc.get("nodes") or []
    lights: list[PointLight] = []
    skipped: dict[str, int] = {}
    spots = 0
    for i, matrix in world.items():
        node = nodes[i]
        ref = ((node.get("extensions") or {}).get("KHR_lights_punctual") or {}).get("light")
        if ref is None:
            continue
        try:
            spec = defs[int(ref)]
        except (IndexError, TypeError, ValueError):
            warnings.append(f"node {i}: refers to light {ref}, which does not exist")
            continue
        kind = str(spec.get("type", "point"))
        if kind not in ("point", "spot"):
            skipped[kind] = skipped.get(kind, 0) + 1
            continue
        spots += kind == "spot"
        color = _float_list(spec.get("color"), 3, 1.0)
        intensity = _float_or(spec.get("intensity"), 1.0)
        rng = _float_or(spec.get("range"), 0.0)
        if rng <= 0.0:
            rng = math.sqrt(max(intensity, 0.0) * 1000.0) + 1.0
        pos = matrix[:3, 3]
        lights.append(
            PointLight(
                (float(pos[0]), float(pos[1]), float(pos[2])),
                (color[0], color[1], color[2]),
                intensity,
                rng,
            )
        )
    if spots:
        warnings.append(
            f"{spots} spot light{'s are' if spots != 1 else ' is'} shown as a point light (no cone)"
        )
    for kind, count in skipped.items():
        warnings.append(f"{count} {kind} light{'s' if count != 1 else ''} not supported, ignored")
    return lights


def _gltf_world_matrices(doc: dict[str, Any]) -> dict[int, np.ndarray]:
    """World matrix of every node reachable from the default scene (cycles are cut)."""
    nodes = doc.get("nodes") or []
    scenes = doc.get("scenes") or []
    try:
        roots = list(scenes[int(doc.get("scene", 0))].get("nodes", []))
    except (IndexError, TypeError, ValueError, AttributeError):
        children = {c for n in nodes for c in (n.get("children") or [])}
        roots = [i for i in range(len(nodes)) if i not in children]
    world: dict[int, np.ndarray] = {}
    stack = [(int(r), np.eye(4)) for r in roots if isinstance(r, int) and 0 <= r < len(nodes)]
    while stack:
        i, parent = stack.pop()
        if i in world:
            continue
        m = parent @ _gltf_local_matrix(nodes[i])
        world[i] = m
        for c in nodes[i].get("children") or []:
            if isinstance(c, int) and 0 <= c < len(nodes) and c not in world:
                stack.append((c, m))
    return world


def _gltf_local_matrix(node: dict[str, Any]) -> np.ndarray:
    if "matrix" in node:
        values = _float_list(node["matrix"], 16, 0.0)
        return np.asarray(values).reshape(4, 4).T  # glTF stores column-major
    t = _float_list(node.get("translation"), 3, 0.0)
    x, y, z, w = (
        _float_list(node.get("rotation"), 4, 0.0) if "rotation" in node else (0.0, 0.0, 0.0, 1.0)
    )
    s = _float_list(node.get("scale"), 3, 1.0)
    norm = math.sqrt(x * x + y * y + z * z + w * w) or 1.0
    x, y, z, w = x / norm, y / norm, z / norm, w / norm
    rot = np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )
    m = np.eye(4)
    m[:3, :3] = rot * np.asarray(s)[None, :]
    m[:3, 3] = t
    return m


# --------------------------------------------------------------------------------------------
# spawn
# --------------------------------------------------------------------------------------------


def find_spawn(scene: Scene, caster: RayCaster | None = None) -> SpawnResult:
    """Stand inside the main room if there is one, otherwise look at the object from outside.

    ``caster`` must have been built from ``scene.triangles()`` with triangle indices as owners
    (as :func:`load_scene` does); it is built here when not given.
    """
    if caster is None:
        caster = RayCaster(scene.triangles(), np.arange(scene.triangle_count))
    lo, hi = (np.asarray(b, np.float64) for b in scene.bounds())
    tris = scene.triangles().astype(np.float64)
    interior = _interior_spawn(caster, _triangle_normals(tris), lo, hi)
    if interior is not None:
        return interior
    return _outside_spawn(lo, hi)


def _triangle_normals(tris: np.ndarray) -> np.ndarray:
    n = np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0])
    return n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-30)


def _ring(n: int) -> np.ndarray:
    a = np.arange(n) * (2.0 * math.pi / n)
    return np.column_stack([np.cos(a), np.zeros(n), np.sin(a)])


def _interior_spawn(
    caster: RayCaster, normals: np.ndarray, lo: np.ndarray, hi: np.ndarray
) -> SpawnResult | None:
    """Search a grid of columns for the lowest large enclosed floor and its most open point.

    Each column is peeled from the top down with one batched cast per layer, so every surface
    under the column is found (roof, vault, floor, slab...). A roughly horizontal surface with at
    least head room up to the surface above it is a floor; its eye point is "inside" when most
    of a ring of horizontal rays hit something (walls all round), none is closer than a body's
    width, and most of what they hit faces the eye: walls seen from inside a room show their
    front faces, while the inside of a closed object (a truck's tank) shows back faces.
    """
    size = hi - lo
    diag = float(np.linalg.norm(size))
    if size[1] < _MIN_CLEARANCE_M or min(size[0], size[2]) < 2.0 * _BODY_RADIUS_M:
        return None  # nothing a person could stand inside
    area = float(size[0] * size[2])
    step = max(math.sqrt(area / _GRID_TARGET), 0.2)
    nx = max(int(round(size[0] / step)), 1)
    nz = max(int(round(size[2] / step)), 1)
    xs = lo[0] + (np.arange(nx) + 0.5) * (size[0] / nx)
    zs = lo[2] + (np.arange(nz) + 0.5) * (size[2] / nz)
    gx, gz = np.meshgrid(xs, zs, indexing="ij")
    xz = np.column_stack([gx.ravel(), gz.ravel()])
    cell_area = float(size[0] / nx * size[2] / nz)

    eps = max(1e-4 * diag, 1e-4)
    ys, tri = _peel_down(caster, xz, float(hi[1]) + 0.01 * diag + 0.1, eps)

    # Floors: a horizontal surface with a surface above it (so there is a ceiling) far enough up.
    above = ys[:, :-1]
    below = ys[:, 1:]
    flat = np.abs(normals[np.maximum(tri[:, 1:], 0), 1]) > 0.7
    clearance = above - below
    ok = np.isfinite(below) & np.isfinite(above) & flat & (clearance >= _MIN_CLEARANCE_M)
    col, layer = np.nonzero(ok)
    if col.size == 0:
        return None
    floor_y = below[col, layer]
    head = clearance[col, layer]
    eyes = np.column_stack([xz[col, 0], floor_y + EYE_HEIGHT_M, xz[col, 1]])

    ring = _ring(_RING_DIRECTIONS)
    dirs = np.tile(ring, (len(eyes), 1))
    dist, who = caster.cast_many(np.repeat(eyes, len(ring), axis=0), dirs)
    facing = np.einsum("ij,ij->i", normals[np.maximum(who, 0)], dirs) < 0.0
    hit = np.isfinite(dist)
    dist = dist.reshape(len(eyes), len(ring))
    hit_frac = hit.reshape(dist.shape).mean(axis=1)
    front_frac = (facing & hit).reshape(dist.shape).sum(axis=1) / np.maximum(
        hit.reshape(dist.shape).sum(axis=1), 1
    )
    nearest = dist.min(axis=1)
    enclosed = (hit_frac >= _INSIDE_HIT_FRACTION) & (nearest >= _BODY_RADIUS_M)
    inside = enclosed & (front_frac >= _FRONT_FACING_FRACTION)
    reversed_walls = not inside.any()
    if reversed_walls:
        # Some exporters (SketchUp, for one) leave walls facing out; such a room still counts
        # if it is big enough to walk around in, which a closed object's cavity is not.
        inside = enclosed
    if not inside.any():
        return None
    eyes, floor_y, head, dist = eyes[inside], floor_y[inside], head[inside], dist[inside]

    level = _main_level(floor_y)
    if reversed_walls and level.sum() * cell_area < _MIN_REVERSED_ROOM_M2:
        return None
    eyes, floor_y, head, dist = eyes[level], floor_y[level], head[level], dist[level]
    # Most free space: the largest distance to the nearest wall, then the roomiest on average.
    finite = np.where(np.isfinite(dist), dist, diag)
    free = finite.min(axis=1)
    score = free + 0.01 * finite.mean(axis=1)
    best = int(np.argmax(score))
    eye = eyes[best]
    yaw, view_free = _longest_view(caster, eye, diag)
    return SpawnResult(
        Viewpoint((float(eye[0]), float(eye[1]), float(eye[2])), yaw, 0.0),
        float(floor_y[best]),
        np.column_stack([eyes[:, 0], floor_y, eyes[:, 2]]),
        head.astype(np.float64),
        free,
        cell_area,
        view_free,
    )


def _peel_down(
    caster: RayCaster, xz: np.ndarray, y_top: float, eps: float
) -> tuple[np.ndarray, np.ndarray]:
    """Heights (NaN past the last) and triangle ids (-1) of every surface under each column."""
    n = len(xz)
    ys = np.full((n, _MAX_LAYERS), np.nan)
    tri = np.full((n, _MAX_LAYERS), -1, np.int64)
    origins = np.column_stack([xz[:, 0], np.full(n, y_top), xz[:, 1]])
    down = np.array([[0.0, -1.0, 0.0]])
    active = np.arange(n)
    for k in range(_MAX_LAYERS):
        if active.size == 0:
            break
        dist, who = caster.cast_many(origins[active], np.repeat(down, active.size, axis=0))
        hit = np.isfinite(dist)
        idx = active[hit]
        y_hit = origins[idx, 1] - dist[hit]
        ys[idx, k] = y_hit
        tri[idx, k] = who[hit]
        origins[idx, 1] = y_hit - eps
        active = idx
    return ys, tri


def _main_level(floor_y: np.ndarray) -> np.ndarray:
    """Mask of the candidates on the lowest floor level that is large.

    "Large" is at least a quarter of the biggest level's sampled area: a crypt stair or a sunken
    tomb is lower than the main floor but small, an organ loft is large but higher.
    """
    base = float(floor_y.min())
    bins = np.round((floor_y - base) / _LEVEL_BIN_M).astype(np.int64)
    counts = np.bincount(bins)
    # A level straddling a bin boundary splits in two: judge each bin with its neighbours.
    padded = np.concatenate([[0], counts, [0]])
    merged = counts + np.maximum(padded[:-2], padded[2:])
    large = np.flatnonzero(merged >= max(0.25 * merged.max(), 3))
    chosen = int(large.min())
    members = bins == chosen
    if not members.any():  # large only thanks to a neighbour: centre on the neighbourhood
        members = np.abs(bins - chosen) <= 1
    centre = float(np.median(floor_y[members]))
    return np.abs(floor_y - centre) <= _LEVEL_BIN_M


def _longest_view(caster: RayCaster, eye: np.ndarray, diag: float) -> tuple[float, float]:
    """Yaw (degrees, 0 = -Z, positive = left) of the longest free horizontal sight line.

    A direction counts only as far as its neighbours +-10 degrees also reach, so a slit between
    two columns does not win over an open nave.
    """
    n = 72
    ring = _ring(n)
    dist, _ = caster.cast_many(np.repeat(eye[None, :], n, axis=0), ring)
    reach = np.where(np.isfinite(dist), dist, 2.0 * diag)
    window = np.stack([np.roll(reach, s) for s in (-2, -1, 0, 1, 2)]).min(axis=0)
    best = int(np.argmax(window))
    d = ring[best]
    yaw = math.degrees(math.atan2(-d[0], -d[2]))
    free = float(dist[best])
    return yaw, free


def _outside_spawn(lo: np.ndarray, hi: np.ndarray) -> SpawnResult:
    """Stand on the +Z side (glTF's front), level with the centre, the object filling the view."""
    centre = (lo + hi) / 2.0
    radius = max(float(np.linalg.norm(hi - lo)) / 2.0, 1e-3)
    half_angle = math.radians(90.0 * _OBJECT_VIEW_FILL / 2.0)
    distance = radius / math.sin(half_angle)
    pos = (float(centre[0]), float(centre[1]), float(centre[2] + distance))
    return SpawnResult(
        Viewpoint(pos, 0.0, 0.0), None, np.zeros((0, 3)), np.zeros(0), np.zeros(0), 0.0, math.inf
    )


# --------------------------------------------------------------------------------------------
# default lights
# --------------------------------------------------------------------------------------------


def default_lights(scene: Scene, spawn: SpawnResult, caster: RayCaster) -> list[PointLight]:
    """A few point lights so a file without lights is visible on the first frame.

    Interior: 1-4 lights spread over the floor level the viewer stands on, part way up to the
    ceiling. Object: a key light above and in front and a weaker fill beside the viewer.
    Intensity is set so a surface at a typical distance receives about unit radiance under the
    renderer's ``intensity / (d^2 + 1)`` law, and the range is a few times that distance (at
    least a third of the scene) so the window falloff does not cut it short.
    """
    lo, hi = (np.asarray(b, np.float64) for b in scene.bounds())
    diag = max(float(np.linalg.norm(hi - lo)), 1e-3)
    if spawn.floor_y is not None and len(spawn.level_points):
        positions = _interior_light_positions(spawn, caster)
        targets = [_LIGHT_TARGET_RADIANCE] * len(positions)
    else:
        centre = (lo + hi) / 2.0
        radius = diag / 2.0
        eye = np.asarray(spawn.viewpoint.position, np.float64)
        key = centre + radius * np.array([1.2, 2.0, 1.8])
        fill = eye + np.array([-0.8 * radius, 0.5 * radius, 0.0])
        positions = [key, fill]
        targets = [_LIGHT_TARGET_RADIANCE, 0.4 * _LIGHT_TARGET_RADIANCE]
    dirs = _sphere_directions(64)
    lights = []
    for pos, target in zip(positions, targets, strict=True):
        dist, _ = caster.cast_many(np.repeat(pos[None, :], len(dirs), axis=0), dirs)
        hits = dist[np.isfinite(dist)]
        typical = float(np.median(hits)) if hits.size >= len(dirs) // 4 else diag / 2.0
        typical = max(typical, 0.1)
        rng = max(3.0 * typical, diag / 3.0)
        intensity = target * (typical * typical + 1.0) / _window(typical / rng)
        lights.append(
            PointLight(
                (float(pos[0]), float(pos[1]), float(pos[2])),
                (1.0, 1.0, 1.0),
                float(intensity),
                float(rng),
            )
        )
    return lights


def _interior_light_positions(spawn: SpawnResult, caster: RayCaster) -> list[np.ndarray]:
    """Spread over the level by a small k-means, each in open space, raised under the ceiling.

    Each light goes above the floor point of its cluster that is most open (not the centroid,
    which may be in a column), then is lowered until nothing is within half a metre of it, so a
    capital or an arch at that height does not swallow it.
    """
    pts = spawn.level_points
    area = len(pts) * spawn.cell_area
    k = int(np.clip(math.ceil(area / _M_PER_LIGHT), 1, 4))
    k = min(k, len(pts))
    xz = pts[:, [0, 2]]
    # Farthest-point start, then a few Lloyd steps: spread out, but not pinned to the corners.
    start = int(
        np.argmin(np.linalg.norm(xz - np.asarray(spawn.viewpoint.position)[[0, 2]], axis=1))
    )
    centres = [xz[start]]
    for _ in range(1, k):
        d = np.min([np.linalg.norm(xz - c, axis=1) for c in centres], axis=0)
        centres.append(xz[int(np.argmax(d))])
    c = np.asarray(centres)

    def nearest_centre(c: np.ndarray) -> np.ndarray:
        return np.argmin(np.linalg.norm(xz[:, None, :] - c[None, :, :], axis=2), axis=1)

    for _ in range(8):
        label = nearest_centre(c)
        c = np.asarray(
            [xz[label == j].mean(axis=0) if (label == j).any() else c[j] for j in range(k)]
        )
    label = nearest_centre(c)
    probe = _sphere_directions(32)
    out = []
    for j in range(k):
        members = np.flatnonzero(label == j) if (label == j).any() else np.arange(len(pts))
        spread = np.linalg.norm(xz[members] - c[j], axis=1)
        near = members[spread <= np.quantile(spread, 0.25)]  # the cluster's middle quarter
        i = int(near[np.argmax(spawn.level_free[near])])
        head = float(spawn.level_clearance[i])
        top = min(float(np.clip(0.5 * head, 2.2, 6.0)), head - 0.3)
        heights = np.linspace(top, min(EYE_HEIGHT_M, top), 5)
        cands = np.column_stack([np.full(5, pts[i, 0]), pts[i, 1] + heights, np.full(5, pts[i, 2])])
        dist, _ = caster.cast_many(np.repeat(cands, len(probe), axis=0), np.tile(probe, (5, 1)))
        clear = np.flatnonzero(dist.reshape(5, -1).min(axis=1) >= 0.5)
        out.append(cands[int(clear[0]) if clear.size else -1])
    return out


def _sphere_directions(n: int) -> np.ndarray:
    """Evenly spread unit vectors (Fibonacci sphere)."""
    i = np.arange(n) + 0.5
    y = 1.0 - 2.0 * i / n
    r = np.sqrt(np.maximum(1.0 - y * y, 0.0))
    phi = i * math.pi * (3.0 - math.sqrt(5.0))
    return np.column_stack([r * np.cos(phi), y, r * np.sin(phi)])


def _window(x: float) -> float:
    """The renderer's range falloff as assumed here: (1 - x^4)^2, clamped."""
    return float(np.clip(1.0 - x**4, 1e-3, 1.0) ** 2)
