"""The scene model: meshes, materials, textures, point lights and a spawn viewpoint.

Plain numpy data with no GL or Qt: loaders and the procedural showroom build it, the renderer
uploads it, and the navigation and gaze code ray-cast against it. :meth:`Scene.sanitized` is the
single place where bad input (NaN/inf vertices, degenerate triangles, broken lights) is repaired
or dropped, so nothing downstream has to guess.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

log = logging.getLogger(__name__)


@dataclass
class Texture:
    """An RGBA8 image, row 0 at the top, as authored (sRGB colour)."""

    name: str
    rgba: np.ndarray  # (H, W, 4) uint8
    repeat: bool = True

    @property
    def size(self) -> tuple[int, int]:
        return int(self.rgba.shape[1]), int(self.rgba.shape[0])


ALPHA_MODES = ("OPAQUE", "MASK", "BLEND")


@dataclass
class Material:
    """glTF 2.0 metallic-roughness, per pixel. Texture fields index Scene.textures (None: the
    factor alone). The base colour and emissive maps are sRGB colour; the normal,
    metallic-roughness (G roughness, B metalness) and occlusion (R) maps are linear data."""

    name: str
    base_color: tuple[float, float, float, float] = (0.8, 0.8, 0.8, 1.0)  # linear RGBA
    texture: int | None = None  # base colour (RGB) and alpha (A)
    roughness: float = 0.6
    metallic: float = 0.0
    emissive: tuple[float, float, float] = (0.0, 0.0, 0.0)  # linear, emissive strength included
    normal_texture: int | None = None  # tangent-space normal map (needs Mesh.tangents)
    normal_scale: float = 1.0
    metallic_roughness_texture: int | None = None  # multiplies roughness (G) and metallic (B)
    occlusion_texture: int | None = None  # ambient occlusion (R)
    occlusion_strength: float = 1.0
    emissive_texture: int | None = None  # multiplies emissive
    alpha_mode: str = "OPAQUE"  # "OPAQUE", "MASK" (cut out below alpha_cutoff) or "BLEND"
    alpha_cutoff: float = 0.5
    double_sided: bool = False
    # A glowing pane standing for the sky beyond a window (the built-in rooms' windows): drawn
    # while daylight is off; with daylight on the sky itself shows through the opening, and
    # the floor mirrors it (render.gpu_scene.GpuScene.shown). No file sets it.
    sky_standin: bool = False
    # KHR_materials_unlit (a photo backdrop outside a window): ``emissive`` is its colour's glow
    # under 1 lux (app.gltf_materials.UNLIT_CD_M2). The picture shows it at the scene's light:
    # with daylight on, at the day's outdoor illuminance (app.sky.unlit_gain), so the photo
    # outside reads as the view out, not as a black pane beside a sky of thousands of cd/m2.
    unlit: bool = False


@dataclass
class Mesh:
    """One drawable object: an indexed triangle list with one material."""

    name: str
    positions: (
        np.ndarray
    )  # (N, 3) float32, world space, Y up, metres (readers: float64, file units)
    normals: np.ndarray  # (N, 3) float32, unit length
    uvs: np.ndarray  # (N, 2) float32, may leave [0, 1] (repeat wrapping)
    indices: np.ndarray  # (M, 3) uint32
    material: int = 0
    colors: np.ndarray | None = None  # (N, 3) float32 linear vertex colours, or None
    # (N, 4) float32 unit tangent (xyz) and handedness (w = +-1, bitangent = w * cross(N, T),
    # pointing along +v of ``uvs``); only for meshes whose material has a normal map.
    tangents: np.ndarray | None = None
    ao: np.ndarray | None = None  # (N, 2) float32 baked occlusion, front and back (app.ao_bake)
    lod: Any = None  # app.lod.MeshLod: chunks and simplified levels, built at load (or None)

    @property
    def triangle_count(self) -> int:
        return int(self.indices.shape[0])

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        return self.positions.min(axis=0), self.positions.max(axis=0)


@dataclass
class Light:
    """A lamp (point or spot, intensity in candela) or the sun (directional, in lux).

    Light units: the renderer's linear values are luminance in cd/m2; a point or spot light's
    ``intensity`` is candela (KHR_lights_punctual's), a directional light's is illuminance in
    lux. ``direction`` is where a spot or directional light shines (unit, scene axes); a spot's
    cone is full inside ``inner_cone_deg`` and dark outside ``outer_cone_deg`` (half angles).
    """

    position: tuple[float, float, float]
    color: tuple[float, float, float] = (1.0, 1.0, 1.0)
    intensity: float = 10.0  # candela (point, spot) or lux (directional)
    range_m: float = 10.0  # the light contributes nothing beyond this distance
    kind: str = "point"  # "point", "spot" or "directional"
    direction: tuple[float, float, float] = (0.0, -1.0, 0.0)
    inner_cone_deg: float = 0.0
    outer_cone_deg: float = 45.0
    casts_shadows: bool = True


PointLight = Light  # the name the lamps had before spots and the sun


def lights_with_daylight(lights: list[Light], daylight: bool) -> list[Light]:
    """A scene's lights as a frame uses them: with daylight on (``sky.enabled``), the model's
    own suns (directional lights: a Blender Sun lamp exported to glTF) give way to the sun
    placed by date and time, so a room has one sun and one patch of it on the floor."""
    return [lt for lt in lights if not (daylight and lt.kind == "directional")]


#: The floor on a lamp's squared distance (m2) in its inverse-square falloff: 10 cm, so a
#: surface touching a lamp is bright, not infinite. The renderer's shaders get the same value
#: (render.constants.LIGHT_MIN_DIST2).
LIGHT_MIN_DIST2 = 0.01


def range_window(d2: Any, range_m: float) -> Any:
    """The smooth window that takes a lamp's light to exactly 0 at ``range_m`` (so culling by
    range is exact): ``clamp(1 - (d^2 / r^2)^4, 0, 1)^2``, 1 near the lamp. Flat for most of
    the range (0.9997 at a third, 0.92 at two thirds: the physical inverse square there),
    falling smoothly to 0 over its last third."""
    x = np.asarray(d2, np.float64) / (float(range_m) ** 2)
    return np.clip(1.0 - (x * x) ** 2, 0.0, 1.0) ** 2


def lamp_falloff(d2: Any, range_m: float) -> Any:
    """A point or spot lamp's irradiance per candela at squared distance ``d2`` (m2), facing
    it: the physical inverse square ``1 / max(d^2, LIGHT_MIN_DIST2)`` times the range window,
    as render/shaders/shading.glsl computes it (so E = I cos / d^2 lux for I candela, what a
    path tracer gives)."""
    d2 = np.asarray(d2, np.float64)
    return range_window(d2, range_m) / np.maximum(d2, LIGHT_MIN_DIST2)


@dataclass
class Viewpoint:
    position: tuple[float, float, float]
    yaw_deg: float = 0.0  # 0 looks down -Z, positive turns left (counter-clockwise from above)
    pitch_deg: float = 0.0


@dataclass
class Scene:
    name: str
    meshes: list[Mesh]
    materials: list[Material]
    textures: list[Texture] = field(default_factory=list)
    lights: list[PointLight] = field(default_factory=list)
    spawn: Viewpoint = field(default_factory=lambda: Viewpoint((0.0, 1.6, 0.0)))
    floor_y: float | None = None  # floor height under the spawn, if known
    source: str = ""  # file path, or "built-in"
    lights_added: bool = False  # the lights are the loader's defaults: the file had none
    indirect: bool = False  # the scene asks for photon-mapped indirect light (photons.enabled)
    unit_scale: float = 1.0  # metres per file unit that loading applied
    # What loading subtracted from the file's (scaled) coordinates to bring a model far from the
    # origin to it: file position = scene position + origin_offset (shown, never rendered with).
    origin_offset: tuple[float, float, float] = (0.0, 0.0, 0.0)
    warnings: list[str] = field(default_factory=list)
    # The model's own north for daylight (degrees from its -Z, counter-clockwise seen from
    # above, as sky.north_deg), or None: sky.north_deg decides.
    north_deg: float | None = None
    # The views the file's author saved (glTF cameras), by name: the first near the model is
    # where the viewer starts (app.placement.authored_spawn), all are in View > Viewpoints.
    cameras: list[tuple[str, Viewpoint]] = field(default_factory=list)
    # A RayCaster over triangles() with triangle indices as owners, left by the loader so the
    # session does not build embree's hierarchy a second time; None: build one when needed.
    ray_caster: Any = field(default=None, repr=False, compare=False)
    # The ambient estimate's scene part (app.ambient.probe_for), found once: the window's loader
    # finds it on its worker thread so that the first frame does not wait for it.
    ambient_probe: Any = field(default=None, repr=False, compare=False)
    # The model's own triangles when loading split long edges (app.tessellate); 0: as drawn.
    model_triangles: int = 0

    @property
    def triangle_count(self) -> int:
        return sum(m.triangle_count for m in self.meshes)

    @property
    def lamps_from_file(self) -> bool:
        """Lit by a model file's own lights (not the loader's defaults, not a built-in
        scene's), as bright as the file says."""
        return bool(self.lights) and not self.lights_added and self.source not in ("", "built-in")

    @property
    def model_triangle_count(self) -> int:
        """The triangles the model was made of (what a designer's tool reports), before the
        split of long edges for the per-vertex light."""
        return self.model_triangles or self.triangle_count

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        if not self.meshes:
            return np.zeros(3, np.float32), np.zeros(3, np.float32)
        lo = np.min([m.bounds()[0] for m in self.meshes], axis=0)
        hi = np.max([m.bounds()[1] for m in self.meshes], axis=0)
        return lo, hi

    def triangles(self) -> np.ndarray:
        """All triangles as a (T, 3, 3) float32 array (for ray casting)."""
        if not self.meshes:
            return np.zeros((0, 3, 3), np.float32)
        return np.concatenate([m.positions[m.indices] for m in self.meshes]).astype(np.float32)

    def triangle_owner(self) -> np.ndarray:
        """Mesh index of each triangle in :meth:`triangles` order."""
        return np.concatenate(
            [np.full(m.triangle_count, i, np.int32) for i, m in enumerate(self.meshes)]
            or [np.zeros(0, np.int32)]
        )

    def sanitized(self, geometry: bool = True) -> Scene:
        """A copy with every non-finite or degenerate piece repaired or dropped (and noted).

        ``geometry=False`` repairs only the lights and the spawn, keeping meshes, materials,
        textures and the cached ray caster: for a scene whose geometry was sanitized already.
        """
        notes: list[str] = list(self.warnings)
        meshes, materials, textures = self.meshes, self.materials, self.textures
        if geometry:
            meshes = []
            drops = _Drops()
            for m in self.meshes:
                fixed = _sanitize_mesh(m, len(self.materials), drops)
                if fixed is not None:
                    meshes.append(fixed)
            notes.extend(drops.notes())
            textures = [_sanitize_texture(t, notes) for t in self.textures]
            materials = [_sanitize_material(mat, len(textures), notes) for mat in self.materials]
            if not materials:
                materials = [Material("default")]
        lights = []
        for i, light in enumerate(self.lights):
            fixed_light = _sanitize_light(light)
            if fixed_light is None:
                notes.append(f"light {i}: non-finite position or colour, dropped")
            else:
                lights.append(fixed_light)
        sp = self.spawn
        spawn = Viewpoint(
            tuple(_finite(v, 0.0) for v in sp.position),  # type: ignore[arg-type]
            _finite(sp.yaw_deg, 0.0),
            float(np.clip(_finite(sp.pitch_deg, 0.0), -89.0, 89.0)),
        )
        return replace(
            self,
            meshes=meshes,
            materials=materials,
            textures=textures,
            lights=lights,
            spawn=spawn,
            warnings=notes,
            # new mesh arrays: a cached caster may not match them
            ray_caster=None if geometry else self.ray_caster,
            ambient_probe=None,  # of other meshes and materials
        )


def _finite(v: float, fallback: float) -> float:
    v = float(v)
    return v if math.isfinite(v) else fallback


class _Drops:
    """What repairing the meshes dropped, told in a few lines rather than one per mesh (a real
    interior has hundreds of meshes with a sliver triangle or two)."""

    def __init__(self) -> None:
        self.triangles: dict[str, int] = {}  # mesh name -> triangles dropped
        self.meshes: list[str] = []  # meshes with nothing valid left

    def notes(self) -> list[str]:
        out = []
        if self.triangles:
            total = sum(self.triangles.values())
            worst = max(self.triangles, key=lambda k: self.triangles[k])
            if len(self.triangles) == 1:
                out.append(f"mesh '{worst}': {total:,} invalid or degenerate triangles dropped")
            else:
                out.append(
                    f"{total:,} invalid or degenerate triangles dropped in "
                    f"{len(self.triangles)} meshes (most in '{worst}': "
                    f"{self.triangles[worst]:,})"
                )
        if len(self.meshes) == 1:
            out.append(f"mesh '{self.meshes[0]}': nothing valid left, dropped")
        elif self.meshes:
            shown = ", ".join(f"'{n}'" for n in self.meshes[:3])
            more = f" and {len(self.meshes) - 3} more" if len(self.meshes) > 3 else ""
            out.append(f"{len(self.meshes)} meshes with nothing valid left dropped ({shown}{more})")
        return out


def _sanitize_mesh(m: Mesh, n_materials: int, drops: _Drops) -> Mesh | None:
    pos = np.asarray(m.positions, np.float32).reshape(-1, 3)
    idx = np.asarray(m.indices).reshape(-1, 3)
    n = pos.shape[0]
    if n == 0 or idx.shape[0] == 0:
        drops.meshes.append(m.name)
        return None
    idx = idx.astype(np.int64)
    ok = np.all((idx >= 0) & (idx < n), axis=1)
    good_vertex = np.all(np.isfinite(pos), axis=1)
    ok &= np.all(good_vertex[np.clip(idx, 0, n - 1)], axis=1)
    if ok.any():
        tri = pos[np.clip(idx[ok], 0, n - 1)].astype(np.float64)
        area2 = np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
        keep = np.zeros(ok.shape, bool)
        keep[np.flatnonzero(ok)] = area2 > 1e-12
        ok = keep
    dropped = int((~ok).sum())
    if dropped:
        drops.triangles[m.name] = drops.triangles.get(m.name, 0) + dropped
    idx = idx[ok]
    if idx.shape[0] == 0:
        drops.meshes.append(m.name)
        return None
    pos = np.where(np.isfinite(pos), pos, 0.0).astype(np.float32)
    normals = np.asarray(m.normals, np.float32).reshape(-1, 3)
    if normals.shape[0] != n:
        normals = np.zeros((n, 3), np.float32)
    lengths = np.linalg.norm(np.where(np.isfinite(normals), normals, 0.0), axis=1)
    bad = ~np.isfinite(normals).all(axis=1) | (lengths < 1e-8)
    if bad.any():
        normals = normals.copy()
        normals[bad] = vertex_normals(pos, idx)[bad]
    normals = normals / np.maximum(np.linalg.norm(normals, axis=1, keepdims=True), 1e-12)
    uvs = np.asarray(m.uvs, np.float32).reshape(-1, 2) if m.uvs is not None else None
    if uvs is None or uvs.shape[0] != n:
        uvs = np.zeros((n, 2), np.float32)
    uvs = np.where(np.isfinite(uvs), uvs, 0.0).astype(np.float32)
    colors = m.colors
    if colors is not None:
        colors = np.asarray(colors, np.float32).reshape(-1, colors.shape[-1])[:, :3]
        colors = (
            np.clip(np.where(np.isfinite(colors), colors, 1.0), 0.0, 1.0)
            if colors.shape[0] == n
            else None
        )
    material = m.material if 0 <= m.material < max(n_materials, 1) else 0
    tangents = m.tangents
    if tangents is not None:
        tangents = np.asarray(tangents, np.float32).reshape(-1, 4)
        if tangents.shape[0] != n:
            tangents = None
        else:
            tangents = np.where(np.isfinite(tangents), tangents, 0.0).astype(np.float32)
    return Mesh(
        m.name,
        pos,
        normals.astype(np.float32),
        uvs,
        idx.astype(np.uint32),
        material,
        colors,
        tangents,
    )


def _sanitize_texture(t: Texture, notes: list[str]) -> Texture:
    rgba = np.asarray(t.rgba)
    if rgba.ndim == 2:
        rgba = rgba[:, :, None]
    if rgba.ndim != 3 or rgba.shape[0] < 1 or rgba.shape[1] < 1:
        notes.append(f"texture '{t.name}': unusable shape {rgba.shape}, replaced by magenta")
        rgba = np.array([[[255, 0, 255, 255]]], np.uint8)
    if rgba.dtype != np.uint8:
        f = rgba.astype(np.float64)
        if np.issubdtype(rgba.dtype, np.integer):
            f = f / float(np.iinfo(rgba.dtype).max)
        f = np.clip(np.nan_to_num(f, nan=0.0, posinf=1.0, neginf=0.0), 0.0, 1.0)
        rgba = (f * 255.0 + 0.5).astype(np.uint8)
    c = rgba.shape[2]
    if c == 1:
        rgba = np.concatenate([np.repeat(rgba, 3, axis=2), np.full_like(rgba, 255)], axis=2)
    elif c == 2:
        rgba = np.concatenate([np.repeat(rgba[:, :, :1], 3, axis=2), rgba[:, :, 1:2]], axis=2)
    elif c == 3:
        rgba = np.concatenate([rgba, np.full(rgba.shape[:2] + (1,), 255, np.uint8)], axis=2)
    elif c > 4:
        rgba = rgba[:, :, :4]
    return Texture(t.name, np.ascontiguousarray(rgba), t.repeat)


def _sanitize_material(mat: Material, n_textures: int, notes: list[str]) -> Material:
    def clean(values: tuple[float, ...], fallback: float) -> tuple[float, ...]:
        return tuple(float(np.clip(_finite(v, fallback), 0.0, 1e4)) for v in values)

    def existing(index: int | None) -> int | None:
        return index if index is not None and 0 <= index < n_textures else None

    tex = existing(mat.texture)
    if mat.texture is not None and tex is None:
        notes.append(f"material '{mat.name}': texture {mat.texture} missing, colour only")
    base = clean(mat.base_color, 1.0)
    emissive = clean(mat.emissive, 0.0)
    mode = str(mat.alpha_mode).upper()
    return replace(
        mat,
        base_color=(min(base[0], 1.0), min(base[1], 1.0), min(base[2], 1.0), min(base[3], 1.0)),
        texture=tex,
        roughness=float(np.clip(_finite(mat.roughness, 0.6), 0.02, 1.0)),
        metallic=float(np.clip(_finite(mat.metallic, 0.0), 0.0, 1.0)),
        emissive=(emissive[0], emissive[1], emissive[2]),
        normal_texture=existing(mat.normal_texture),
        normal_scale=float(np.clip(_finite(mat.normal_scale, 1.0), -10.0, 10.0)),
        metallic_roughness_texture=existing(mat.metallic_roughness_texture),
        occlusion_texture=existing(mat.occlusion_texture),
        occlusion_strength=float(np.clip(_finite(mat.occlusion_strength, 1.0), 0.0, 1.0)),
        emissive_texture=existing(mat.emissive_texture),
        alpha_mode=mode if mode in ALPHA_MODES else "OPAQUE",
        alpha_cutoff=float(np.clip(_finite(mat.alpha_cutoff, 0.5), 0.0, 1.0)),
        double_sided=bool(mat.double_sided),
    )


def _sanitize_light(light: PointLight) -> PointLight | None:
    if not all(math.isfinite(v) for v in light.position):
        return None
    color = tuple(_finite(c, -1.0) for c in light.color)
    if any(c < 0 for c in color):
        return None
    intensity = _finite(light.intensity, 0.0)
    intensity = float(np.clip(intensity, 0.0, 1e6))
    rng = _finite(light.range_m, 0.0)
    if rng <= 0.0:
        return None  # a light that reaches nothing costs time and gives no light
    dx, dy, dz = (_finite(v, 0.0) for v in light.direction)
    d = (dx, dy, dz) if any((dx, dy, dz)) else (0.0, -1.0, 0.0)
    kind = light.kind if light.kind in ("point", "spot", "directional") else "point"
    return replace(  # kind, cone and shadows kept
        light,
        color=(color[0], color[1], color[2]),
        intensity=intensity,
        range_m=min(rng, 1e5),
        direction=d,
        kind=kind,
    )


def vertex_normals(positions: np.ndarray, indices: np.ndarray) -> np.ndarray:
    """Area-weighted vertex normals; vertices on no triangle get +Y."""
    pos = positions.astype(np.float64)
    idx = indices.astype(np.int64)
    fn = np.cross(pos[idx[:, 1]] - pos[idx[:, 0]], pos[idx[:, 2]] - pos[idx[:, 0]])
    out = np.zeros_like(pos)
    for k in range(3):
        np.add.at(out, idx[:, k], fn)
    lengths = np.linalg.norm(out, axis=1, keepdims=True)
    out = np.where(lengths > 1e-20, out / np.maximum(lengths, 1e-20), [0.0, 1.0, 0.0])
    return out.astype(np.float32)
