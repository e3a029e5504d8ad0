"""glTF materials and textures -> linear-colour :class:`Material` and shared RGBA8 textures.

The factors come straight from the JSON (full float precision), with glTF's defaults: white,
fully metallic, fully rough. Every map the renderer shades per pixel is kept: base colour (with
its alpha for MASK and BLEND), normal (+ scale), metallic-roughness, occlusion (+ strength) and
emissive (times KHR_materials_emissive_strength). KHR_materials_unlit glows in its colour
(``UNLIT_CD_M2``). KHR_materials_pbrSpecularGlossiness becomes a
base colour (diffuse) and a roughness (1 - glossiness). A texture used by ten materials (or an
occlusion-roughness-metal image used for two roles) is decoded and uploaded once.
"""

from __future__ import annotations

import hashlib
import math
from pathlib import Path
from typing import Any

import numpy as np

from app.gltf_accessors import (
    Accessors,
    Blob,
    BufferUnavailable,
    GltfDataError,
    UriResolver,
    as_dict,
    as_list,
    is_int,
)
from app.images import ImageError, decode_image, fitted_size, image_size
from app.progress import Progress
from app.scene import ALPHA_MODES, Material, Texture
from app.scene_builder import float_list, float_or

_GL_CLAMP_TO_EDGE = 33071
# KHR_materials_transmission (Blender's glass, an OPAQUE material that transmits): drawn as
# blended glass whose opacity is this at full transmission. The renderer has no refraction
# pass; a clear pane still shows a faint film of its colour (real glass reflects about 8 % of
# the light at its two faces), and it lets the sky's and the sun's light through as blended
# glass does (no shadow, no photon stops at it).
GLASS_ALPHA = 0.1
# KHR_materials_unlit (a photo backdrop outside a window, a scanned room whose light is in its
# textures): shown as its colour, lit by nothing. It glows at this luminance per unit colour
# (cd/m2): a white surface under the 1 lux the default lights give (app.default_lights), so
# at the fixed exposure a room opens with it shows as a white wall does; with daylight on the
# picture shows it at the day's outdoor light instead (Material.unlit, app.sky.unlit_gain).
# Vertex colours tint it in the picture (material.glsl UNLIT: a scan coloured per vertex).
UNLIT_CD_M2 = 1.0 / math.pi


class GltfImages:
    """Image bytes by glTF image index (from a file, a data: URI or a buffer view), read once."""

    def __init__(
        self, doc: dict[str, Any], accessors: Accessors, resolver: UriResolver, max_px: int
    ) -> None:
        self.images = as_list(doc.get("images"))
        self.accessors = accessors
        self.resolver = resolver
        self.max_px = max_px
        self._bytes: dict[int, Blob | None] = {}
        self._failures: dict[int, str] = {}

    def label(self, index: int) -> str:
        """The image's file name, or its name, to name textures and missing files after."""
        spec = as_dict(self.images[index]) if 0 <= index < len(self.images) else {}
        uri = spec.get("uri")
        if isinstance(uri, str) and not uri.startswith("data:"):
            from urllib.parse import unquote

            return unquote(uri)
        name = spec.get("name")
        return str(name) if name else f"image {index}"

    def data(self, index: int) -> Blob | None:
        """The encoded image, or None (the reason is kept for :meth:`failure`)."""
        if index in self._bytes:
            return self._bytes[index]
        spec = self.images[index] if 0 <= index < len(self.images) else None
        result: Blob | None = None
        if not isinstance(spec, dict):
            self._failures[index] = f"image {index} does not exist"
        elif isinstance(spec.get("uri"), str):
            before = len(self.resolver.warnings)
            result = self.resolver.read(spec["uri"], f"image {index}")
            if result is None:
                # The material's warning names the image; the resolver's would say it twice.
                added = self.resolver.warnings[before:]
                del self.resolver.warnings[before:]
                self._failures[index] = added[-1] if added else "it cannot be read"
        elif spec.get("bufferView") is not None:
            try:
                result = self.accessors.view_bytes(spec["bufferView"], f"image {index}")
            except (GltfDataError, BufferUnavailable) as exc:
                self._failures[index] = str(exc)
        else:
            self._failures[index] = f"image {index} has neither a uri nor a buffer view"
        self._bytes[index] = result
        return result

    def failure(self, index: int) -> str:
        return self._failures.get(index, "it cannot be read")

    def decoded_bytes(self, index: int) -> int:
        """RGBA8 bytes the image will take once decoded (0 when it will not decode)."""
        data = self.data(index)
        size = image_size(data) if data is not None else None
        if size is None:
            return 0
        w, h = fitted_size(size, self.max_px)
        return w * h * 4


class GltfMaterials:
    """Converts glTF materials on first use, sharing textures by image, wrap and opacity."""

    def __init__(
        self,
        doc: dict[str, Any],
        images: GltfImages,
        warnings: list[str],
        progress: Progress,
        tick: Any,
    ) -> None:
        self.doc = doc
        self.images = images
        self.warnings = warnings
        self.progress = progress
        self.tick = tick  # callable(text) -> None: one unit of load progress done
        self.materials: list[Material] = []
        self.textures: list[Texture] = []
        self._by_gltf: dict[Any, int] = {}
        self._texture_keys: dict[tuple[int, bool, bool], int | None] = {}
        self._texture_digests: dict[tuple[bytes, bool], int] = {}
        self._decoded: dict[int, np.ndarray | None] = {}
        self._uv_transforms: dict[int, np.ndarray | None] = {}  # by glTF material

    def used_images(self, material_indices: set[int]) -> set[int]:
        """Image indices the given materials sample (for the memory estimate)."""
        out = set()
        for m in material_indices:
            spec = self._spec(m)
            for info in _texture_infos(spec):
                image = self._image_of(info)
                if image is not None:
                    out.add(image)
        return out

    def index(self, gltf_index: Any, has_colors: bool) -> int:
        """Our material index for a primitive's ``material`` (None: the default material)."""
        if gltf_index is None or self._spec(gltf_index) is None:
            if gltf_index is not None:
                self.warnings.append(f"material {gltf_index} does not exist, using a default")
            # Vertex colours carry the colour: a white base keeps them as authored.
            key = "vertex-colours" if has_colors else "default"
            if key not in self._by_gltf:
                base = (1.0, 1.0, 1.0, 1.0) if has_colors else Material("default").base_color
                self._by_gltf[key] = len(self.materials)
                self.materials.append(Material(key, base))
            return self._by_gltf[key]
        if gltf_index not in self._by_gltf:
            material = self._convert(gltf_index)
            self._by_gltf[gltf_index] = len(self.materials)
            self.materials.append(material)
        return self._by_gltf[gltf_index]

    def uv_transform(self, gltf_index: Any) -> np.ndarray | None:
        """The KHR_texture_transform a primitive of material ``gltf_index`` bakes into its
        uvs: a 3x3 matrix on glTF uvs, or None (no transform). A mesh has one set of uvs, so
        one transform serves every map of the material: the base colour's, else the first
        map's that has one; a map that asks for another gets a warning (once a material)."""
        if not is_int(gltf_index):  # no material, or not an index (the default material)
            return None
        if gltf_index not in self._uv_transforms:
            spec = self._spec(gltf_index)
            name = str((spec or {}).get("name") or f"material {gltf_index}")
            matrices = []
            for info in _texture_infos(spec, base_first=True):
                ext = as_dict(info.get("extensions")).get("KHR_texture_transform")
                matrices.append(_uv_matrix(ext, name, self.warnings))
            chosen = next((m for m in matrices if m is not None), None)
            if chosen is not None and any(
                not np.allclose(chosen, np.eye(3) if m is None else m) for m in matrices
            ):
                self.warnings.append(
                    f"material '{name}': its maps are placed by different texture "
                    "transforms; all follow the base colour's"
                )
            self._uv_transforms[gltf_index] = chosen
        return self._uv_transforms[gltf_index]

    def _spec(self, index: Any) -> dict[str, Any] | None:
        mats = as_list(self.doc.get("materials"))
        if is_int(index) and 0 <= index < len(mats) and isinstance(mats[index], dict):
            return as_dict(mats[index])
        return None

    # ---- one material ---------------------------------------------------------------------

    def _convert(self, index: int) -> Material:
        doc = self._spec(index) or {}
        name = str(doc.get("name") or f"material {len(self.materials)}")
        exts = as_dict(doc.get("extensions"))
        pbr = as_dict(doc.get("pbrMetallicRoughness"))
        base = float_list(pbr.get("baseColorFactor"), 4, 1.0)
        metallic = float_or(pbr.get("metallicFactor"), 1.0)
        roughness = float_or(pbr.get("roughnessFactor"), 1.0)
        tex_info = pbr.get("baseColorTexture")
        mr_info = pbr.get("metallicRoughnessTexture")
        sg = exts.get("KHR_materials_pbrSpecularGlossiness")
        if isinstance(sg, dict) and "pbrMetallicRoughness" not in doc:
            base = float_list(sg.get("diffuseFactor"), 4, 1.0)
            metallic = 0.0
            roughness = 1.0 - float_or(sg.get("glossinessFactor"), 1.0)
            tex_info = sg.get("diffuseTexture")
            mr_info = None  # its specular-glossiness map is not metallic-roughness
        emissive = float_list(doc.get("emissiveFactor"), 3, 0.0)
        strength = exts.get("KHR_materials_emissive_strength")
        if isinstance(strength, dict):
            emissive = [e * float_or(strength.get("emissiveStrength"), 1.0) for e in emissive]
        alpha_mode = str(doc.get("alphaMode", "OPAQUE")).upper()
        if alpha_mode not in ALPHA_MODES:
            self.warnings.append(f"material '{name}': unknown alpha mode {alpha_mode!r:.20}")
            alpha_mode = "OPAQUE"
        opaque = alpha_mode == "OPAQUE"
        if opaque:
            base[3] = 1.0  # glTF: alpha is ignored for OPAQUE materials
        transmission = _transmission(exts.get("KHR_materials_transmission"))
        if transmission > 0.0:  # glass as Blender exports it: see-through, blended
            alpha_mode = "BLEND"
            base[3] *= 1.0 - transmission * (1.0 - GLASS_ALPHA)
        normal_info = doc.get("normalTexture")
        occlusion_info = doc.get("occlusionTexture")
        texture = self._texture(name, tex_info, "base colour", keep_alpha=not opaque)
        emissive_texture = self._texture(name, doc.get("emissiveTexture"), "emissive")
        if "KHR_materials_unlit" in exts:  # its colour glows; black, rough metal to the lamps
            emissive = [c * UNLIT_CD_M2 for c in base[:3]]
            emissive_texture = texture  # the colour map (sRGB, as an emissive map is)
            base[:3] = [0.0, 0.0, 0.0]  # alpha stays: cut-outs and glass as they were
            roughness, metallic, mr_info = 1.0, 1.0, None
            normal_info = occlusion_info = None
        return Material(
            name,
            (base[0], base[1], base[2], base[3]),
            texture,
            float(roughness),
            float(metallic),
            (emissive[0], emissive[1], emissive[2]),
            normal_texture=self._texture(name, normal_info, "normal"),
            normal_scale=float_or(as_dict(normal_info).get("scale"), 1.0),
            metallic_roughness_texture=self._texture(name, mr_info, "metallic-roughness"),
            occlusion_texture=self._texture(name, occlusion_info, "occlusion"),
            occlusion_strength=float_or(as_dict(occlusion_info).get("strength"), 1.0),
            emissive_texture=emissive_texture,
            alpha_mode=alpha_mode,
            alpha_cutoff=float_or(doc.get("alphaCutoff"), 0.5),
            double_sided=doc.get("doubleSided") is True,
            unlit="KHR_materials_unlit" in exts,
        )

    def _texture(self, material: str, info: Any, role: str, keep_alpha: bool = False) -> int | None:
        """Our texture index for a texture reference (None, with a warning when it is broken).

        ``keep_alpha``: the base colour of a MASK or BLEND material keeps its alpha; every
        other use stores A = 255 (so two uses of one image share a texture)."""
        if info is None:
            return None
        if not isinstance(info, dict):
            self.warnings.append(
                f"material '{material}': its {role} texture reference {info!r:.40} is "
                f"not a texture, {_fallback(role)}"
            )
            return None
        if is_int(info.get("texCoord")) and info["texCoord"] != 0:
            self.warnings.append(
                f"material '{material}': its {role} texture uses texture coordinates "
                f"{info['texCoord']}; the first set stands in"
            )
        image = self._image_of(info)
        if image is None:
            self.warnings.append(
                f"material '{material}': its {role} texture {info.get('index')!r} does not "
                f"exist, {_fallback(role)}"
            )
            return None
        repeat = self._repeats(info)
        key = (image, repeat, keep_alpha)
        if key in self._texture_keys:
            return self._texture_keys[key]
        rgba = self._decode(image, material, role)
        if rgba is None:
            self._texture_keys[key] = None
            return None
        if not keep_alpha:
            rgba = rgba.copy()
            rgba[:, :, 3] = 255
        # Two images with the same pixels (an exporter writing a file twice) are one texture.
        digest = (
            hashlib.blake2b(rgba.tobytes(), digest_size=16).digest() + repr(rgba.shape).encode()
        )
        index = self._texture_digests.get((digest, repeat))
        if index is None:
            index = len(self.textures)
            self._texture_digests[(digest, repeat)] = index
            label = Path(self.images.label(image)).name or material
            self.textures.append(Texture(label, rgba, repeat))
        self._texture_keys[key] = index
        return index

    def _decode(self, image: int, material: str, role: str) -> np.ndarray | None:
        """RGBA8 of a glTF image, decoded once; None (with a warning) when it cannot be."""
        if image in self._decoded:
            return self._decoded[image]
        label = self.images.label(image)
        data = self.images.data(image)
        rgba: np.ndarray | None = None
        if data is None:
            self.warnings.append(
                f"material '{material}': {role} texture '{label}' could not be read "
                f"({self.images.failure(image)}), {_fallback(role)}"
            )
        else:
            try:
                decoded = decode_image(data, self.images.max_px)
                rgba = decoded.rgba
                if decoded.note:
                    self.warnings.append(f"texture '{Path(label).name}': {decoded.note}")
            except ImageError as exc:
                self.warnings.append(
                    f"material '{material}': {role} texture '{Path(label).name}' dropped "
                    f"({exc}), {_fallback(role)}"
                )
        self._decoded[image] = rgba
        self.tick(f"Texture {Path(label).name}")
        return rgba

    def _image_of(self, info: dict[str, Any]) -> int | None:
        textures = as_list(self.doc.get("textures"))
        index = info.get("index")
        if not is_int(index) or not 0 <= index < len(textures):
            return None
        tex = textures[index]
        if not isinstance(tex, dict):
            return None
        source = tex.get("source")
        exts = as_dict(tex.get("extensions"))
        for ext in exts.values():  # EXT_texture_webp, MSFT_texture_dds... name their own image
            if source is None and isinstance(ext, dict) and is_int(ext.get("source")):
                source = ext["source"]
        n_images = len(self.images.images)
        return source if is_int(source) and 0 <= source < n_images else None

    def _repeats(self, info: dict[str, Any]) -> bool:
        """False only when the sampler explicitly clamps; mirrored repeat is treated as repeat."""
        try:
            texture = self.doc["textures"][int(info["index"])]
            sampler = self.doc["samplers"][int(texture["sampler"])]
        except (KeyError, IndexError, TypeError, ValueError):
            return True
        if not isinstance(sampler, dict):
            return True
        return _GL_CLAMP_TO_EDGE not in (sampler.get("wrapS"), sampler.get("wrapT"))


def _fallback(role: str) -> str:
    """What a material does without its texture, for the warning."""
    return "using its colour only" if role == "base colour" else f"shaded without its {role} map"


def _texture_infos(spec: dict[str, Any] | None, base_first: bool = False) -> list[dict[str, Any]]:
    """The material's texture references; ``base_first``: the one that gives the colour
    (a specular-glossiness material's diffuse map where it has no metallic-roughness) first."""
    if spec is None:
        return []
    pbr = as_dict(spec.get("pbrMetallicRoughness"))
    exts = as_dict(spec.get("extensions"))
    sg = exts.get("KHR_materials_pbrSpecularGlossiness")
    candidates = [
        pbr.get("baseColorTexture"),
        pbr.get("metallicRoughnessTexture"),
        spec.get("normalTexture"),
        spec.get("occlusionTexture"),
        spec.get("emissiveTexture"),
    ]
    if isinstance(sg, dict):
        diffuse = sg.get("diffuseTexture")
        if base_first and "pbrMetallicRoughness" not in spec:
            candidates.insert(0, diffuse)
        else:
            candidates.append(diffuse)
    return [c for c in candidates if isinstance(c, dict)]


def _transmission(ext: Any) -> float:
    """KHR_materials_transmission's factor in [0, 1] (0 without the extension; its texture is
    not read)."""
    if not isinstance(ext, dict):
        return 0.0
    return min(max(float_or(ext.get("transmissionFactor"), 0.0), 0.0), 1.0)


def _uv_matrix(ext: Any, material: str, warnings: list[str]) -> np.ndarray | None:
    """KHR_texture_transform as the 3x3 matrix on glTF uvs (translation x rotation x scale,
    as the extension defines it); None without one. Values that are not finite numbers leave
    the map as authored, with a warning."""
    if not isinstance(ext, dict):
        return None
    offset = ext.get("offset", [0.0, 0.0])
    scale = ext.get("scale", [1.0, 1.0])
    rotation = ext.get("rotation", 0.0)
    try:
        ox, oy = (float(v) for v in offset)
        sx, sy = (float(v) for v in scale)
        angle = float(rotation)
        usable = bool(np.isfinite([ox, oy, sx, sy, angle]).all())
    except (TypeError, ValueError):
        usable = False
    if not usable:
        warnings.append(f"material '{material}': a texture transform that is not a number, ignored")
        return None
    c, s = np.cos(angle), np.sin(angle)
    translation = np.array([[1.0, 0.0, ox], [0.0, 1.0, oy], [0.0, 0.0, 1.0]])
    turn = np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]])
    return translation @ turn @ np.diag([sx, sy, 1.0])
