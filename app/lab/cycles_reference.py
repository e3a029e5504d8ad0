"""An independent reference for "how it will look": our scene path-traced by Blender's Cycles.

``vrpreview reference`` exports a :class:`~app.scene.Scene` (meshes, materials, lamps, the sun
and the sky) and our left eye's camera into a job folder, renders it with Cycles on the CPU in
a separate process (:mod:`app.lab.blender_scene`, the ``bpy`` package: ``pip install
.[reference]``) and keeps the linear radiance in a cache keyed by a content hash.
``vrpreview reference-compare`` (:mod:`app.lab.reference_compare`) renders our frame of the
same view with each feature on and off and reports FLIP against the reference.

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
  two thirds). The reference keeps the lamps as they are, not as we cut them: the light past the
  range is the even light's to carry (``app.ambient``, "the lamps' light past their range"; the
  corridor's floor, 2.5 m under lamps of 3.05 m range, gets 80-89 % of its direct light so). A
  windowed reference (tried at stop 39, Light Falloff and math nodes) made that light look
  like an excess of ours.
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

from app.camera import StereoCamera, orientation
from app.fileio import atomic_write_json, atomic_write_png
from app.scene import Material, Scene, Viewpoint, lights_with_daylight
from app.settings import Settings

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
    lights = lights_with_daylight(scene.lights, settings.sky.enabled)
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


def merged_arrays(scene: Scene, daylight: bool = False) -> dict[str, np.ndarray]:
    """Every mesh as one triangle list with a material index per triangle; with ``daylight``
    (the sky on) without the panes standing for the sky (``Material.sky_standin``), as our
    frame draws it."""
    pos, nrm, uvs, col, idx, mat = [], [], [], [], [], []
    base = 0
    for m in scene.meshes:
        standin = 0 <= m.material < len(scene.materials) and scene.materials[m.material].sky_standin
        if daylight and standin:
            continue
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
    # Cycles' light path length: None the whole path (``blender_scene.FULL_BOUNCES``; Blender's
    # own default stops after 4 diffuse bounces), 0 the direct light alone (a camera ray's hit
    # lit by the lamps, the sun and the sky, with shadows), N up to N bounces.
    # ``--reference-bounces``: full minus direct is Cycles' indirect light.
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


def material_for(m: Material, unlit_gain: float = 1.0) -> dict[str, Any]:
    """A material as Cycles' Principled BSDF is told it: the factors and every glTF map (base
    colour and emissive in sRGB, normal and metallic-roughness as data; the occlusion map has
    no counterpart, a path tracer finds the occlusion itself). An unlit material glows as our
    frame shows it (``unlit_gain``: ``app.sky.unlit_gain``)."""
    gain = unlit_gain if m.unlit else 1.0
    return {
        "name": m.name,
        "base_color": [float(v) for v in m.base_color],
        "texture": m.texture,
        "roughness": float(m.roughness),
        "metallic": float(m.metallic),
        "emissive": [float(v) * gain for v in m.emissive],
        "normal_texture": m.normal_texture,
        "normal_scale": float(m.normal_scale),
        "metallic_roughness_texture": m.metallic_roughness_texture,
        "emissive_texture": m.emissive_texture,
        "alpha_mode": m.alpha_mode,
        "alpha_cutoff": float(m.alpha_cutoff),
        # casts no shadow in our renderer (render/shadows.py casts(): glowing, not glass)
        "shadowless": bool(any(m.emissive)) and m.alpha_mode != "BLEND",
        **({"unlit": True} if m.unlit else {}),  # (absent otherwise: cached references stay)
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
    from app.sky import bake_sky, unlit_gain

    sky = sky_for(scene, settings)
    arrays = merged_arrays(scene, daylight=sky is not None)
    gain = 1.0
    if sky is not None:
        arrays["sky"] = sky_image(scene, settings)
        gain = unlit_gain(bake_sky(scene_sky_settings(scene, settings)))
    return ReferenceJob(
        size=(int(size[0]), int(size[1])),
        samples=int(samples),
        camera=eye_camera(settings, view, size),
        lights=lights_for(scene, settings),
        sky=sky,
        materials=[material_for(m, gain) for m in scene.materials],
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
