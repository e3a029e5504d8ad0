"""An independent reference for "how it will look": our scene path-traced by Blender's Cycles.

``vrpreview reference`` exports a :class:`~app.scene.Scene` (meshes, materials, lamps, the sun
and the sky) and our left eye's camera into a job folder, renders it with Cycles on the CPU in
a separate process (:mod:`app.lab.blender_scene`, the ``bpy`` package: ``pip install
.[reference]``) and keeps the linear radiance in a cache keyed by a content hash.
``vrpreview reference-compare`` renders our frame of the same view with each feature on and
off and reports FLIP against the reference.

Units (checked by tests/test_reference.py, a white floor under a 1 cd lamp):

- Pixel values on both sides are luminance in cd/m2. Blender's light "watts" are then read as
  photometric: a Cycles point lamp of power P gives the irradiance P / (4 pi d^2) at distance d
  (measured: a white Lambertian plane 1 m under a lamp of 4 pi W renders 1/pi), so a lamp of
  I candela is ``P = 4 pi I`` (the 683 lm/W of radiometric watts cancels, since we never
  leave photometric units: a radiometric export would be ``4 pi I / 683`` W and every pixel
  683 times smaller). A spot is the same lamp with Blender's cone (Blender spots do not
  concentrate their power), a sun of E lux has strength E.
- Our lamps fall off as the physical 1 / d^2 (floored at 10 cm, ``app.scene.lamp_falloff``)
  times a smooth window that reaches 0 at ``range_m`` (render/shaders/shading.glsl); Cycles'
  as 1 / d^2 with no range: the same up to the window (0.9997 of it at a third of the range, 0.92 at
  two thirds).
- ``render.brightness`` scales every lamp (as our renderer does); ``render.ambient`` and
  ``render.ambient_estimate`` (app/ambient.py) have no counterpart: Cycles computes the light
  bounced off walls instead, which the estimate approximates.

Display transform: both images go through our present pass (render/shaders/present.frag.glsl):
``srgb_encode(aces(radiance * render.exposure))``, :func:`present` here in numpy on the linear
radiance, so the reference PNG is what our renderer would show for that radiance.
"""

from __future__ import annotations

import hashlib
import importlib
import importlib.metadata
import json
import logging
import math
import os
import shutil
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from app import metrics
from app.camera import StereoCamera, orientation
from app.fileio import atomic_write_json, atomic_write_png
from app.scene import Material, Scene, Viewpoint
from app.settings import Settings, SettingsError

log = logging.getLogger(__name__)

WORKER = Path(__file__).with_name("blender_scene.py")


class CyclesError(RuntimeError):
    """The reference could not be rendered (no bpy, Blender failed)."""


def bpy_version() -> str | None:
    """The installed ``bpy`` package's version, without importing it (800 MB), or None."""
    try:
        return importlib.metadata.version("bpy")
    except importlib.metadata.PackageNotFoundError:
        return None


def cache_dir() -> Path:
    """Where references are kept: ``$VRPREVIEW_REFERENCE_CACHE``, else
    ``$XDG_CACHE_HOME/vrpreview/reference`` (``~/.cache/vrpreview/reference``)."""
    env = os.environ.get("VRPREVIEW_REFERENCE_CACHE")
    if env:
        return Path(env).expanduser()
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "vrpreview" / "reference"


# -- the display transform -----------------------------------------------------------------------
def aces(x: np.ndarray) -> np.ndarray:
    """Narkowicz's ACES fit, as present.frag.glsl's ``tonemap``."""
    return np.clip((x * (2.51 * x + 0.03)) / (x * (2.43 * x + 0.59) + 0.14), 0.0, 1.0)


def srgb_encode(c: np.ndarray) -> np.ndarray:
    c = np.asarray(c, np.float64)
    curve = 1.055 * np.power(np.maximum(c, 1e-7), 1.0 / 2.4) - 0.055
    return np.where(c >= 0.0031308, curve, c * 12.92)


ToneCurve = Callable[[np.ndarray], np.ndarray]


def tone_curve(settings: Settings) -> ToneCurve:
    """The present pass's tone curve for ``settings``: ``app.exposure.tone_map`` with
    ``render.tone_mapping`` where this build has them (the exposure branch), else the ACES fit
    above."""
    curve = getattr(settings.render, "tone_mapping", None)
    if curve is None:
        return aces
    exposure = importlib.import_module("app.exposure")
    return lambda x: np.asarray(exposure.tone_map(x, str(curve)), np.float64)


def brightness_dims_lamps(settings: Settings) -> bool:
    """Whether ``render.brightness`` scales the lamps (before the exposure branch) rather than
    the exposure (with ``render.exposure_ev``, after it)."""
    return not hasattr(settings.render, "exposure_ev")


def fixed_exposure(settings: Settings) -> float:
    """The present pass's exposure for a fixed exposure: ``render.exposure``, times the EV100
    scale where this build has one (the exposure branch's ``render.exposure_ev``)."""
    scale = float(settings.render.exposure)
    ev = getattr(settings.render, "exposure_ev", None)
    if ev is None:
        return scale
    exposure = importlib.import_module("app.exposure")
    return scale * float(
        exposure.exposure_scale(exposure.effective_ev(float(ev), settings.render.brightness))
    )


def present(radiance: np.ndarray, exposure: float, curve: ToneCurve = aces) -> np.ndarray:
    """Linear radiance (cd/m2) as our present pass shows it: (H, W, 3) uint8 sRGB."""
    x = np.maximum(np.nan_to_num(np.asarray(radiance, np.float64)), 0.0) * exposure
    return (np.clip(srgb_encode(curve(x)), 0.0, 1.0) * 255.0 + 0.5).astype(np.uint8)


# -- the view --------------------------------------------------------------------------------------
def parse_view(text: str | None, scene: Scene) -> Viewpoint:
    """``spawn`` (or None) or ``x,y,z,yaw,pitch`` (metres, degrees) as a viewpoint."""
    if text is None or text == "spawn":
        return scene.spawn
    try:
        x, y, z, yaw, pitch = (float(v) for v in text.split(","))
    except ValueError:
        raise ValueError(f"view must be 'spawn' or x,y,z,yaw,pitch, got '{text}'") from None
    return Viewpoint((x, y, z), yaw, pitch)


def eye_camera(settings: Settings, view: Viewpoint, size: tuple[int, int]) -> dict[str, Any]:
    """Our left eye for an eye viewport of ``size``: position, axes, vertical field of view and
    the off-axis frustum's centre in NDC (the eyes' frusta shift towards each other)."""
    cam = StereoCamera(settings.stereo)
    cam.set_pose(view.position, view.yaw_deg, view.pitch_deg)
    left = cam.eyes(*size)[0]
    p = left.projection
    right, up, fwd = orientation(cam.yaw_deg, cam.pitch_deg)
    return {
        "position": [float(v) for v in left.position],
        "right": [float(v) for v in right],
        "up": [float(v) for v in up],
        "forward": [float(v) for v in fwd],
        "fov_y_deg": float(math.degrees(2.0 * math.atan(1.0 / p[1, 1]))),
        "ndc_shift_x": float(p[0, 2]),
        "ndc_shift_y": float(p[1, 2]),
        "near": float(left.near),
        "far": float(left.far),
    }


# -- the export ------------------------------------------------------------------------------------
def scene_sky_settings(scene: Scene, settings: Settings) -> Any:
    """The ``sky.*`` settings as the renderer applies them to ``scene``: turned by the scene's
    own north (``app.sky.scene_sky``, the showroom's 200 degrees) as well as ``sky.north_deg``.
    (The export once placed the sun by ``sky.north_deg`` alone, so the showroom's sun came in
    from a mirrored bearing.)"""
    from app.sky import scene_sky

    return scene_sky(settings.sky, scene)


def lights_for(scene: Scene, settings: Settings) -> list[dict[str, Any]]:
    """Our lamps in Blender's terms (see the module's units); brightness applied. With
    ``sky.enabled``, the sun of ``app.sky.sun_light`` (in lux) as the renderer adds it to the
    frame's lights (render.renderer ``frame_lights``), for the scene's north."""
    scale = settings.render.brightness if brightness_dims_lamps(settings) else 1.0
    out = []
    lights = list(scene.lights)
    if settings.sky.enabled:
        from app.sky import sun_light

        sun = sun_light(scene_sky_settings(scene, settings))
        if sun is not None:
            lights.append(sun)
    for light in lights:
        intensity = float(light.intensity) * scale
        if intensity <= 0.0:
            continue
        out.append(
            {
                "kind": light.kind,
                "position": [float(v) for v in light.position],
                "direction": [float(v) for v in light.direction],
                "color": [float(c) for c in light.color],
                "watts": 4.0 * math.pi * intensity,  # candela -> Cycles point/spot power
                "sun_strength": intensity,  # lux -> Cycles sun strength
                "inner_cone_deg": float(light.inner_cone_deg),
                "outer_cone_deg": float(light.outer_cone_deg),
            }
        )
    return out


SKY_EXPORT_SIZE = (512, 256)  # the exported sky's equirectangular texels


def sky_for(scene: Scene, settings: Settings) -> dict[str, Any] | None:
    """The world Cycles gets with ``sky.enabled``: our own sky, not Blender's sky model (whose
    colours and brightness are another model's), as an equirectangular image of cd/m2 in
    Blender's layout (:func:`sky_image`) with strength 1 (the lamps' brightness scale where
    brightness dims the lamps)."""
    if not settings.sky.enabled:
        return None
    from app.sky import sun_direction

    sky = scene_sky_settings(scene, settings)
    scale = settings.render.brightness if brightness_dims_lamps(settings) else 1.0
    return {
        "sun_direction": [float(v) for v in sun_direction(sky)],
        "strength": float(scale),
        "when": f"{sky.date} {sky.time}",
        "north_deg": float(sky.north_deg),
        "image": "sky",  # meshes.npz's "sky" array
    }


def sky_image(scene: Scene, settings: Settings, size: tuple[int, int] = SKY_EXPORT_SIZE):
    """Our baked sky (``app.sky.bake_sky``: Preetham and the ground, or the user's panorama),
    resampled into the layout of Blender's Environment Texture (Cycles'
    ``direction_to_equirectangular``: row 0 the zenith as ours, the middle column looking along
    Blender's +X, longitude growing clockwise seen from above), (H, W, 3) float32 cd/m2, row 0
    at the top. The rows are the same polar angles as ours, so only the columns move."""
    from app.sky import bake_sky, north_east

    sky = scene_sky_settings(scene, settings)
    width, height = size
    ours = bake_sky(sky, (width, height)).image.astype(np.float64)
    north, east = north_east(sky.north_deg)
    # Blender's column j looks along phi = pi - 2 pi u (u = (j + 0.5) / W) in its axes:
    # (cos phi, sin phi, 0) there, (cos phi, 0, -sin phi) in ours (Blender (x, y, z) = ours
    # (x, -z, y)).
    u = (np.arange(width) + 0.5) / width
    phi = math.pi - 2.0 * math.pi * u
    horizontal = np.stack([np.cos(phi), np.zeros(width), -np.sin(phi)], axis=1)
    compass = np.arctan2(horizontal @ east, horizontal @ north)  # ours: 0 north, +90 east
    x = (compass / (2.0 * math.pi) + 0.5) * width - 0.5  # our column, fractional
    lo = np.floor(x).astype(int)
    t = (x - lo)[None, :, None]
    left, right = ours[:, lo % width], ours[:, (lo + 1) % width]
    return ((1.0 - t) * left + t * right).astype(np.float32)


def merged_arrays(scene: Scene) -> dict[str, np.ndarray]:
    """Every mesh as one triangle list with a material index per triangle."""
    pos, nrm, uvs, col, idx, mat = [], [], [], [], [], []
    base = 0
    for m in scene.meshes:
        n = m.positions.shape[0]
        pos.append(np.asarray(m.positions, np.float32))
        nrm.append(np.asarray(m.normals, np.float32))
        uvs.append(np.asarray(m.uvs, np.float32))
        col.append(
            np.asarray(m.colors, np.float32)[:, :3]
            if m.colors is not None
            else np.ones((n, 3), np.float32)
        )
        idx.append(np.asarray(m.indices, np.int64) + base)
        mat.append(np.full(m.indices.shape[0], m.material, np.int32))
        base += n

    def cat(parts: list[np.ndarray], shape: tuple[int, ...], dtype: Any) -> np.ndarray:
        return np.concatenate(parts).astype(dtype) if parts else np.zeros(shape, dtype)

    return {
        "positions": cat(pos, (0, 3), np.float32),
        "normals": cat(nrm, (0, 3), np.float32),
        "uvs": cat(uvs, (0, 2), np.float32),
        "colors": cat(col, (0, 3), np.float32),
        "indices": cat(idx, (0, 3), np.int32),
        "material": cat(mat, (0,), np.int32),
    }


@dataclass
class ReferenceJob:
    """Everything Cycles is told, as data (its digest names the cached reference)."""

    size: tuple[int, int]
    samples: int
    camera: dict[str, Any]
    lights: list[dict[str, Any]]
    sky: dict[str, Any] | None
    materials: list[dict[str, Any]]
    textures: list[dict[str, Any]]
    exposure: float
    denoise: bool = True
    threads: int = 0  # 0: Blender's choice (all cores)
    # Cycles' light path length: None its default (12, every bounce), 0 the direct light
    # alone (a camera ray's hit lit by the lamps, the sun and the sky, with shadows), N up to
    # N bounces. ``--reference-bounces``: full minus direct is Cycles' indirect light.
    max_bounces: int | None = None
    arrays: dict[str, np.ndarray] = field(default_factory=dict, repr=False)
    texture_images: list[np.ndarray] = field(default_factory=list, repr=False)

    def description(self) -> dict[str, Any]:
        d = asdict(self)
        d.pop("arrays")
        d.pop("texture_images")
        if d["max_bounces"] is None:
            d.pop("max_bounces")  # the full light path: the digest as before the option
        return d

    def digest(self, version: str | None) -> str:
        """A content hash of geometry, materials, textures, lights, sky, view, size, samples,
        the bpy version and the Cycles side's script (the display's exposure is not in it: it
        is applied afterwards)."""
        h = hashlib.sha256()
        d = self.description()
        d.pop("exposure")
        d.pop("threads")
        h.update(json.dumps(d, sort_keys=True).encode())
        h.update(str(version).encode())
        h.update(WORKER.read_bytes())  # a change to the Cycles side renders afresh
        for name in sorted(self.arrays):
            a = np.ascontiguousarray(self.arrays[name])
            h.update(name.encode() + str(a.shape).encode() + a.tobytes())
        for img in self.texture_images:
            h.update(str(img.shape).encode() + np.ascontiguousarray(img).tobytes())
        return h.hexdigest()[:24]


def material_for(m: Material) -> dict[str, Any]:
    """A material as Cycles' Principled BSDF is told it: the factors and every glTF map (base
    colour and emissive in sRGB, normal and metallic-roughness as data; the occlusion map has
    no counterpart, a path tracer finds the occlusion itself)."""
    return {
        "name": m.name,
        "base_color": [float(v) for v in m.base_color],
        "texture": m.texture,
        "roughness": float(m.roughness),
        "metallic": float(m.metallic),
        "emissive": [float(v) for v in m.emissive],
        "normal_texture": m.normal_texture,
        "normal_scale": float(m.normal_scale),
        "metallic_roughness_texture": m.metallic_roughness_texture,
        "emissive_texture": m.emissive_texture,
        "alpha_mode": m.alpha_mode,
        "alpha_cutoff": float(m.alpha_cutoff),
        # casts no shadow in our renderer (render/shadows.py casts(): glowing, not glass)
        "shadowless": bool(any(m.emissive)) and m.alpha_mode != "BLEND",
    }


def export(
    scene: Scene,
    settings: Settings,
    view: Viewpoint,
    size: tuple[int, int],
    samples: int,
    max_bounces: int | None = None,
) -> ReferenceJob:
    """The job for our left eye at ``size`` (one eye's width x height) seeing ``scene``;
    ``max_bounces`` limits Cycles' light paths (0: the direct light alone)."""
    arrays = merged_arrays(scene)
    sky = sky_for(scene, settings)
    if sky is not None:
        arrays["sky"] = sky_image(scene, settings)
    return ReferenceJob(
        size=(int(size[0]), int(size[1])),
        samples=int(samples),
        camera=eye_camera(settings, view, size),
        lights=lights_for(scene, settings),
        sky=sky,
        materials=[material_for(m) for m in scene.materials],
        textures=[{"name": t.name, "repeat": bool(t.repeat)} for t in scene.textures],
        exposure=fixed_exposure(settings),
        arrays=arrays,
        texture_images=[t.rgba for t in scene.textures],
        max_bounces=None if max_bounces is None else max(int(max_bounces), 0),
    )


def write_job(job: ReferenceJob, folder: Path) -> None:
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "job.json").write_text(json.dumps(job.description(), indent=1))
    save: Any = np.savez  # numpy's stub types the keyword arrays as its own options
    save(folder / "meshes.npz", **job.arrays)
    for i, rgba in enumerate(job.texture_images):
        atomic_write_png(folder / f"tex_{i}.png", np.ascontiguousarray(rgba, np.uint8))


# -- rendering and the cache -----------------------------------------------------------------------
@dataclass
class Reference:
    """One cached reference: linear radiance (cd/m2, row 0 at the top) and where it lies."""

    radiance: np.ndarray
    folder: Path
    digest: str
    cached: bool  # found in the cache (no render this time)
    render_s: float

    def image(self, exposure: float, curve: ToneCurve = aces) -> np.ndarray:
        return present(self.radiance, exposure, curve)


def _python() -> str:
    """The interpreter that has bpy (``$VRPREVIEW_BLENDER_PYTHON``, else this one)."""
    return os.environ.get("VRPREVIEW_BLENDER_PYTHON") or sys.executable


def render(
    job: ReferenceJob,
    cache: Path | None = None,
    note: Callable[[str], None] | None = None,
    job_curve: ToneCurve = aces,
) -> Reference:
    """The reference of ``job``, from the cache or rendered by Cycles (then cached)."""
    version = bpy_version()
    if version is None and not os.environ.get("VRPREVIEW_BLENDER_PYTHON"):
        raise CyclesError(
            "the reference renderer needs Blender's bpy package: pip install '.[reference]'"
        )
    digest = job.digest(version)
    root = cache or cache_dir()
    folder = root / digest
    npy = folder / "radiance.npy"
    if npy.exists():
        meta = json.loads((folder / "reference.json").read_text())
        return Reference(np.load(npy), folder, digest, True, float(meta.get("render_s", 0.0)))
    root.mkdir(parents=True, exist_ok=True)
    work = Path(tempfile.mkdtemp(prefix=f".{digest}-", dir=root))
    try:
        write_job(job, work)
        if note:
            note(f"rendering {job.size[0]}x{job.size[1]} at {job.samples} samples with Cycles")
        start = time.perf_counter()
        run = subprocess.run(
            [_python(), str(WORKER), str(work)], capture_output=True, text=True, check=False
        )
        elapsed = time.perf_counter() - start
        if run.returncode != 0 or not (work / "radiance.npy").exists():
            tail = (run.stderr or run.stdout).strip().splitlines()[-8:]
            raise CyclesError("Cycles failed:\n" + "\n".join(tail))
        timing = json.loads((work / "timing.json").read_text())
        radiance = np.load(work / "radiance.npy")
        for name in ("meshes.npz", *(p.name for p in work.glob("tex_*.png"))):
            (work / name).unlink(missing_ok=True)  # the job's copy of the scene: not kept
        atomic_write_png(work / "reference.png", present(radiance, job.exposure, job_curve))
        atomic_write_json(
            work / "reference.json",
            {"digest": digest, "bpy": version, "render_s": elapsed, **timing},
        )
        if folder.exists():  # another run finished first: keep its copy
            shutil.rmtree(work)
        else:
            os.replace(work, folder)
    except BaseException:
        shutil.rmtree(work, ignore_errors=True)
        raise
    return Reference(radiance, folder, digest, False, elapsed)


# -- our frame and the comparison --------------------------------------------------------------
@dataclass
class OurFrame:
    """Our left eye: what the present pass showed, the linear HDR it showed, and the display
    transform it used (the reference goes through the same)."""

    image: np.ndarray  # (H, W, 3) uint8 sRGB
    hdr: np.ndarray  # (H, W, 3) float32 cd/m2
    exposure: float
    curve: ToneCurve

    def shown(self, radiance: np.ndarray) -> np.ndarray:
        return present(radiance, self.exposure, self.curve)


@dataclass(frozen=True)
class Feature:
    """A feature as settings overrides: its frame with ``on`` against one with ``off``."""

    name: str
    label: str
    on: dict[str, Any]
    off: dict[str, Any]
    # The feature changes the scene, not only our picture of it (the sky lights the room):
    # both frames are compared with the reference rendered with ``on``.
    changes_reference: bool = False


# Features other branches bring (render.shadows, AO, normal maps, ...) are listed here by
# their keys; keys this build's Settings does not know are skipped with a note, so the table
# works before and after they merge. Add a row to add a feature.
FEATURES: tuple[Feature, ...] = (
    Feature("shadows", "Shadows", {"render.shadows": "soft"}, {"render.shadows": "off"}),
    Feature("sky", "Sun and sky", {"sky.enabled": True}, {"sky.enabled": False}, True),
    Feature("ao", "Ambient occlusion", {"render.ao": "screen"}, {"render.ao": "off"}),
    Feature(
        "normal_maps", "Normal maps", {"render.normal_maps": True}, {"render.normal_maps": False}
    ),
    Feature("indirect", "Indirect light", {"photons.enabled": "on"}, {"photons.enabled": "off"}),
    Feature(
        "ambient", "Ambient light", {}, {"render.ambient": 0.0, "render.ambient_estimate": False}
    ),
    Feature(
        "ambient_estimate",
        "Ambient from the lamps (not fixed)",
        {"render.ambient_estimate": True},
        {"render.ambient_estimate": False},
    ),
    Feature("cps", "Coarse pixel shading", {"cps.mode": "cps"}, {"cps.mode": "none"}),
)


def with_overrides(settings: Settings, overrides: dict[str, Any]) -> Settings:
    out = settings.copy()
    for key, value in overrides.items():
        out.set(key, value)
    return out


def usable(feature: Feature, settings: Settings) -> str | None:
    """None if both sides of ``feature`` apply to ``settings``, else why not."""
    try:
        with_overrides(settings, feature.on)
        with_overrides(settings, feature.off)
    except SettingsError as exc:
        return f"skipped: {exc}".split(" (known:")[0]
    return None


SETTLE_FRAMES = 3  # frames drawn per variant in a comparison, the last one kept


def our_frames(
    scene: Scene, view: Viewpoint, size: tuple[int, int], variants: dict[str, Settings]
) -> dict[str, OurFrame]:
    """Our left eye at ``size`` for each settings variant.

    One host and one session draw them all, as the window does: the session ticks once at
    the view (gaze at the centre, texture levels, the coarse-shading caps) and the settings
    are changed in place between frames, as the panels change them. Each variant's picture is
    the settled one, as a user sees it after a moment at the view: the sky's visibility baked
    (it lights the room through the windows only once baked), every shadow map drawn (the
    per-frame budget of shadow redraws lifted) and the last of ``SETTLE_FRAMES`` frames."""
    from app.paths import FIXED_DT
    from app.session import Session
    from render.offscreen import OffscreenHost  # GL only when a comparison runs

    out: dict[str, OurFrame] = {}
    if not variants:
        return out
    live = next(iter(variants.values())).copy()
    session = Session(live)
    session.set_scene(scene)
    with OffscreenHost(2 * size[0], size[1], live) as host:
        host.set_scene(scene)
        host.set_text_image(None)
        for name, settings in variants.items():
            for key in settings.keys():
                if live.get(key) != settings.get(key):
                    live.set(key, settings.get(key))
            live.set("render.shadow_updates_per_frame", 64)  # every shadow map at once
            if live.sky.enabled and host.renderer.gpu_scene is not None:
                with host.ctx:
                    host.renderer.daylight.wait_for_visibility(host.renderer.gpu_scene)
            for _ in range(SETTLE_FRAMES):
                session.walker.place(view.position, view.yaw_deg, view.pitch_deg)
                session.eye_size = size
                session.tick(FIXED_DT)
                img = host.draw(session.frame_input(*size))
            # the exposure the present pass applied (metered, with the exposure branch)
            scale = float(getattr(host.renderer, "_exposure_scale", 1.0))
            out[name] = OurFrame(
                img[:, : size[0]].copy(),
                host.read_hdr(0)[:, :, :3].copy(),
                scale * live.render.exposure,
                tone_curve(live),
            )
    return out


@dataclass
class FeatureRow:
    name: str
    label: str
    flip_on: float | None = None
    flip_off: float | None = None
    note: str = ""

    @property
    def helps(self) -> bool | None:
        if self.flip_on is None or self.flip_off is None:
            return None
        return self.flip_on < self.flip_off


@dataclass
class Comparison:
    scene: str
    view: dict[str, Any]
    size: tuple[int, int]
    samples: int
    reference: str  # the cached reference's folder
    flip_defaults: float
    mean_luminance_ours: float
    mean_luminance_reference: float
    features: list[FeatureRow]

    def to_dict(self) -> dict[str, Any]:
        d = asdict(self)
        for row, f in zip(d["features"], self.features):
            row["helps"] = f.helps
        return d

    def table(self) -> str:
        lines = [
            f"{self.scene} {self.size[0]}x{self.size[1]}, {self.samples} samples: FLIP "
            f"{self.flip_defaults:.3f} with the current settings (mean luminance ours "
            f"{self.mean_luminance_ours:.2f}, reference {self.mean_luminance_reference:.2f} "
            "cd/m2)",
            "| Feature | FLIP on | FLIP off | On is closer |",
            "|---|---|---|---|",
        ]
        for r in self.features:
            if r.helps is None:
                lines.append(f"| {r.label} | | | {r.note} |")
            else:
                lines.append(
                    f"| {r.label} | {r.flip_on:.3f} | {r.flip_off:.3f} | "
                    f"{'yes' if r.helps else 'no'} |"
                )
        return "\n".join(lines)


def without_gaze_ring(size: tuple[int, int], radius_px: float = 10.0) -> np.ndarray:
    """Every pixel but the gaze ring our overlay draws at the view's centre (the gaze of a
    frame with no mouse), which the reference has no counterpart of."""
    y, x = np.mgrid[0 : size[1], 0 : size[0]]
    return np.hypot(x + 0.5 - size[0] / 2, y + 0.5 - size[1] / 2) > radius_px


def ppd_of(settings: Settings, size: tuple[int, int]) -> float:
    cam = StereoCamera(settings.stereo)
    return metrics.pixels_per_degree(size[0], cam.horizontal_fov_deg(*size))


def luminance(rgb: np.ndarray) -> np.ndarray:
    return rgb[..., 0] * 0.2126 + rgb[..., 1] * 0.7152 + rgb[..., 2] * 0.0722


def compare(
    scene_name: str,
    scene: Scene,
    settings: Settings,
    view: Viewpoint,
    size: tuple[int, int],
    samples: int,
    features: list[str] | None = None,
    cache: Path | None = None,
    note: Callable[[str], None] | None = None,
    max_bounces: int | None = None,
) -> Comparison:
    """FLIP of our frame against the Cycles reference, with the settings as given and with
    each feature on and off."""
    chosen = [f for f in FEATURES if features is None or f.name in features]
    unknown = set(features or []) - {f.name for f in FEATURES}
    if unknown:
        raise ValueError(
            f"unknown feature {', '.join(sorted(unknown))} "
            f"(known: {', '.join(f.name for f in FEATURES)})"
        )
    ref = render(export(scene, settings, view, size, samples, max_bounces), cache, note)
    variants: dict[str, Settings] = {"defaults": settings}
    rows = []
    for f in chosen:
        why = usable(f, settings)
        label = f"{f.label} (reference with it on)" if f.changes_reference else f.label
        rows.append(FeatureRow(f.name, label, note=why or ""))
        if why is None:
            variants[f"{f.name}:on"] = with_overrides(settings, f.on)
            variants[f"{f.name}:off"] = with_overrides(settings, f.off)
    frames = our_frames(scene, view, size, variants)
    ppd = ppd_of(settings, size)

    keep = without_gaze_ring(size)
    references = {ref.digest: ref.radiance}

    def reference_for(overrides: dict[str, Any]) -> np.ndarray:
        job = export(scene, with_overrides(settings, overrides), view, size, samples, max_bounces)
        digest = job.digest(bpy_version())
        if digest not in references:
            references[digest] = render(job, cache, note).radiance
        return references[digest]

    def flip_of(name: str, radiance: np.ndarray = ref.radiance) -> float:
        ours = frames[name]  # the reference shown with our frame's exposure and curve
        return metrics.flip(ours.shown(radiance), ours.image, ppd, keep)

    for f, row in zip(chosen, rows):
        if not row.note:
            target = reference_for(f.on) if f.changes_reference else ref.radiance
            row.flip_on = flip_of(f"{row.name}:on", target)
            row.flip_off = flip_of(f"{row.name}:off", target)
    pos = view.position
    return Comparison(
        scene=scene_name,
        view={
            "position": [float(v) for v in pos],
            "yaw_deg": view.yaw_deg,
            "pitch_deg": view.pitch_deg,
        },
        size=size,
        samples=samples,
        reference=str(ref.folder),
        flip_defaults=flip_of("defaults"),
        mean_luminance_ours=float(luminance(frames["defaults"].hdr).mean()),
        mean_luminance_reference=float(luminance(ref.radiance).mean()),
        features=rows,
    )


# -- the commands ----------------------------------------------------------------------------------
COMMANDS = ("reference", "reference-compare")


def add_parsers(sub: Any, common: Callable[..., None]) -> None:
    """``vrpreview reference`` and ``vrpreview reference-compare`` (hooked in app/lab/cli.py)."""
    for name, text in (
        ("reference", "path-trace one view with Blender Cycles (cached): EXR/NPY + PNG"),
        (
            "reference-compare",
            "FLIP of our frame against the Cycles reference, each feature on and off",
        ),
    ):
        p = sub.add_parser(name, help=text)
        common(p, scene_required=True)
        p.add_argument("--view", default="spawn", help="spawn, or x,y,z,yaw,pitch (m, degrees)")
        p.add_argument("--size", default="640x720", help="one eye, WxH (the left eye)")
        p.add_argument("--samples", type=int, default=64, help="Cycles samples per pixel")
        p.add_argument("--out", default=None, help="PNG (reference) or JSON (compare) to write")
        p.add_argument(
            "--reference-bounces",
            type=int,
            default=None,
            help="Cycles' bounces (default: all; 0: the direct light alone)",
        )
        if name == "reference-compare":
            p.add_argument(
                "--features",
                default=None,
                help=f"comma-separated, of: {', '.join(f.name for f in FEATURES)} (all)",
            )


def run_command(args: Any, settings: Settings) -> int:
    from app import scenes
    from app.frame import parse_size
    from app.loaders import LoadOptions

    size = parse_size(args.size)
    if args.samples < 1:
        raise ValueError("--samples must be at least 1")
    scene = scenes.resolve(args.scene, LoadOptions.from_settings(settings.scene))
    view = parse_view(args.view, scene)

    def note(text: str) -> None:
        print(text, file=sys.stderr)

    try:
        if args.command == "reference":
            ref = render(
                export(scene, settings, view, size, args.samples, args.reference_bounces),
                note=note,
            )
            if args.out:
                shown = present(ref.radiance, fixed_exposure(settings), tone_curve(settings))
                atomic_write_png(args.out, shown)
                print(f"wrote {args.out}")
            how = "from the cache" if ref.cached else f"rendered in {ref.render_s:.0f} s"
            print(f"reference {ref.digest} ({how}): {ref.folder}")
            return 0
        features = args.features.split(",") if args.features else None
        result = compare(
            Path(args.scene).stem,
            scene,
            settings,
            view,
            size,
            args.samples,
            features,
            note=note,
            max_bounces=args.reference_bounces,
        )
    except CyclesError as exc:
        print(f"vrpreview: error: {exc}", file=sys.stderr)
        return 2
    print(result.table())
    if args.out:
        atomic_write_json(args.out, result.to_dict())
        print(f"wrote {args.out}")
    return 0
