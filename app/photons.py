"""Photon tracing (Jensen style): light paths from the scene's lights, stored at diffuse hits.

These kinds of light emit photons (shared out by their luminous power, largest remainder):

* **Point lights**, isotropically, with flux ``4 pi I color / n`` per photon (lumen for I
  candela). The renderer's direct light is the physical inverse square with a range window and
  a 10 cm floor (``E = I color window(d) / max(d^2, 0.01) cos``, ``app.scene.lamp_falloff``),
  so at a photon's first hit its flux is multiplied by ``window(d) d^2 / max(d^2, 0.01)`` (1
  for most hits): the first-hit photon density then equals the renderer's direct irradiance,
  and the indirect light it seeds matches what the renderer shows as direct light. That first
  hit is *not* stored (the direct part stays analytic in the renderer); later diffuse hits are.
* **Emissive triangles** (area lights: ``material.emissive`` is linear RGB radiance), sampled by
  ``area * luminance(emissive)``, a uniform point on the triangle and a cosine-weighted direction;
  the total power is ``pi * sum(A_i L_e_i)``. A triangle emits from its *front* face, the side its
  vertex normals point to (a window or a downlight set a few millimetres in front of a wall or
  ceiling would otherwise waste half its light into the wall behind it); where the vertex
  normals do not say (missing, or nearly perpendicular to the triangle), it emits from a side
  picked at random for each photon. The renderer has no analytic light from emissive surfaces, so
  every hit of these paths is stored, the first included.
* **Daylight** (``daylight=``, from ``sky.*``) and the scene's directional lights: the sun as a
  parallel beam and the sky through the openings that ``app.daylight_photons`` finds (lux over
  the beam's area: lumen, like the lamps' ``4 pi I``). A sun photon's first hit is not stored
  (the renderer draws the sun's direct light), a sky photon's is.

At each hit the surface is treated as Lambertian with reflectance ``rho = base_color.rgb *
(1 - metallic)``, times the mean linear colour of its texture and the mean of its vertex colours
if it has them (a per-mesh approximation: no per-texel lookup). The stored flux is the flux that
arrived (before ``rho``: the gather multiplies by the receiver's ``rho / pi``); Russian roulette
with ``p = clamp(max(rho), 0.05, 0.95)`` then decides whether the path goes on with flux
``flux * rho / p`` in a cosine-weighted direction about the geometric normal turned towards the
incoming ray (every surface is two-sided, as the renderer draws it). Specular reflection is not
traced: a metal's photons are stored where they land, then absorbed (its diffuse rho is 0).

Surfaces that cast no shadow in the renderer (``render/shadows.py casts``: glowing ones, such as
a pane that shows the sky beyond a window or a lamp's shade, and blended glass) let photons
through, as they let the renderer's direct light and the sky (``app/sky_light.py``) through: a
ray that hits one goes on behind it (:class:`_SeeThrough`). They still emit.

All random numbers come from ``np.random.default_rng(seed)`` in a fixed order and embree answers
are deterministic, so one seed and one scene give byte-identical photon maps.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from app.color import SRGB8_TO_LINEAR, srgb_to_linear
from app.daylight_photons import (
    STORE_SKY_FIRST_HIT,
    Beam,
    Daylight,
    DaylightSources,
    find_portal,
    scene_box,
    xyz,
)
from app.photon_map import PhotonMap, encode_directions
from app.raycast import RayCaster
from app.scene import LIGHT_MIN_DIST2, Material, Scene, lights_with_daylight

#: Photon paths traced together: one batched embree call per bounce for this many live rays.
CHUNK = 2**18
#: Rec. 709 luminance weights, to share photons between lights by visible power.
LUMA = np.array([0.2126, 0.7152, 0.0722])
#: Russian-roulette survival bounds (a bright wall still loses some paths; a dark one keeps a few).
P_MIN, P_MAX = 0.05, 0.95
#: Offset of a new ray's origin off its surface, in units of the scene's bounds diagonal.
OFFSET_SCALE = 1e-4
# A ray goes through at most this many see-through surfaces (both sides of a pane: 2 each).
PASS_THROUGH = 8
#: Vertex normals this close to the triangle's plane do not tell an emitter's front face.
FRONT_MIN_COS = 0.1


class TracingCancelled(Exception):
    """Raised by :func:`trace_photons` when its ``cancel`` callback returns True."""


def scene_scale(scene: Scene) -> float:
    """The diagonal of the scene's finite vertex bounds in metres; 1.0 if it has none."""
    pts = [np.asarray(m.positions, np.float64).reshape(-1, 3) for m in scene.meshes]
    pts = [p[np.isfinite(p).all(axis=1)] for p in pts]
    return _diagonal(np.concatenate(pts) if pts else np.zeros((0, 3)))


def trace_photons(
    scene: Scene,
    count: int,
    seed: int = 0,
    *,
    max_bounces: int = 8,
    progress: Callable[[float], None] | None = None,
    cancel: Callable[[], bool] | None = None,
    caster: RayCaster | None = None,
    daylight: Daylight | None = None,
) -> PhotonMap:
    """Trace ``count`` photon paths from the scene's lights and return the stored photons.

    With ``daylight`` (``app.daylight_photons.daylight_for(settings.sky)``) the sun and the sky
    shine in through the scene's openings too, and the scene's directional lights with them;
    the photons are shared between all sources by their power.

    ``max_bounces`` is the number of diffuse reflections a path may make (so at most
    ``max_bounces + 1`` hits). ``progress(fraction)`` is called after every batched bounce;
    ``cancel()`` is polled before each and raises :class:`TracingCancelled` when true. A
    ``caster`` built from ``scene.triangles()`` is reused (else one is built here).
    """
    count = max(int(count), 0)
    max_bounces = max(int(max_bounces), 0)
    notes: list[str] = []
    rng = np.random.default_rng(seed)

    tris, owner, vnormal = _scene_geometry(scene)
    finite = np.isfinite(tris).all(axis=(1, 2))
    if (~finite).any():
        notes.append(f"{int((~finite).sum())} triangles with non-finite vertices ignored")
    if caster is not None and not _caster_matches(caster, tris[finite]):
        notes.append("the given ray caster was not built from this scene's triangles; rebuilt")
        caster = None
    if caster is None:
        caster = RayCaster(tris, owner)
    geo = _Geometry.build(scene, caster, owner[finite], vnormal[finite], notes)
    caster = _SeeThrough.around(caster, _see_through_meshes(scene)[owner[finite]], geo.offset)
    sources = _light_sources(scene, geo, notes)
    day = _daylight_sources(scene, geo, caster, daylight, seed, notes)
    n_lamp = 0 if sources is None else len(sources.power_luma)
    power = np.concatenate(
        [np.zeros(0) if sources is None else sources.power_luma]
        + ([] if day is None else [day.power_luma])
    )
    if sources is None and day is not None:
        notes.remove("no light in the scene emits: empty photon map")
    if day is not None and not power.sum() > 0.0:
        notes.append("no light in the scene emits: empty photon map")
        day = None

    out_pos: list[np.ndarray] = [np.zeros((0, 3), np.float32)]
    out_pow: list[np.ndarray] = [np.zeros((0, 3), np.float32)]
    out_dir: list[np.ndarray] = [np.zeros(0, np.uint32)]

    def done(emitted: int) -> PhotonMap:
        _report(progress, 1.0)
        return PhotonMap(
            np.concatenate(out_pos),
            np.concatenate(out_pow),
            np.concatenate(out_dir),
            emitted,
            int(seed),
            notes,
        )

    if (sources is None and day is None) or count == 0:
        return done(0 if sources is None and day is None else count)
    if geo.tri.shape[0] == 0:
        notes.append("the scene has no geometry: every photon escapes")

    per_source = _allocate(power, count)
    if day is not None:
        shares = per_source[n_lamp:]
        notes.append(
            f"daylight: {int(shares[:-1].sum())} sun photons, {int(shares[-1])} sky photons "
            f"from {int(day.portal.open.sum())} of {day.portal.cells} window cells "
            f"({day.portal.total_area:.3g} m2)"
        )
    starved = int(((per_source == 0) & (power > 0)).sum())
    if starved:
        notes.append(f"{starved} light(s) too dim for a photon out of {count}; their light lost")
    bounds = np.concatenate([[0], np.cumsum(per_source)])
    batches = max(1, math.ceil(count / CHUNK))
    for b in range(batches):
        start, stop = b * CHUNK, min(count, (b + 1) * CHUNK)
        src = np.searchsorted(bounds, np.arange(start, stop), side="right") - 1
        o, d, flux, reach = _emit(sources, day, n_lamp, src, per_source, rng, geo)
        is_point = src < (0 if sources is None else sources.n_point)  # windowed first hits
        # The renderer draws the lamps' and the sun's direct light: their first hits not stored.
        is_beam = (src >= n_lamp) & (src < n_lamp + (0 if day is None else day.n_beams))
        sky_first = (src >= n_lamp) & ~is_beam
        for bounce in range(max_bounces + 1):
            if cancel is not None and cancel():
                raise TracingCancelled("photon tracing cancelled")
            dist, tri = caster.cast_triangles(o, d)
            alive = tri >= 0
            alive[alive] = geo.usable[tri[alive]]  # a degenerate triangle absorbs
            if bounce == 0:
                # The renderer's direct-light falloff, so the first hits match its direct light.
                alive &= ~is_point | (dist < reach)
                d2 = np.where(is_point, dist * dist, 0.0)
                with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
                    x = d2 / np.where(is_point, reach * reach, 1.0)
                    # lamp_falloff(d2) * d^2: the window (app.scene.range_window), and the
                    # 10 cm floor near the lamp
                    window = np.clip(1.0 - (x * x) ** 2, 0.0, 1.0) ** 2
                    factor = window * d2 / np.maximum(d2, LIGHT_MIN_DIST2)
                flux = np.where(is_point[:, None], flux * factor[:, None], flux)
                store = ~(is_point | is_beam | (sky_first & (not STORE_SKY_FIRST_HIT)))
            else:
                store = np.ones(len(o), bool)
            ok = np.isfinite(flux).all(axis=1) & (flux.max(axis=1, initial=0.0) > 0.0)
            alive &= ok
            o, d, flux, dist, tri, store = (
                o[alive],
                d[alive],
                flux[alive],
                dist[alive],
                tri[alive],
                store[alive],
            )
            p = o + d * dist[:, None]
            if store.any():
                out_pos.append(p[store].astype(np.float32))
                out_pow.append(flux[store].astype(np.float32))
                out_dir.append(encode_directions(d[store]))
            if bounce == max_bounces or len(o) == 0:
                _report(progress, (b + 1) / batches)
                break
            # Russian roulette on the diffuse reflectance, then a cosine-weighted bounce.
            rho = geo.rho[tri]
            keep = np.clip(rho.max(axis=1), P_MIN, P_MAX)
            u = rng.random((len(o), 3))
            survive = (u[:, 0] < keep) & (rho.max(axis=1) > 0.0)
            n = geo.normal[tri]
            n = np.where((np.einsum("ij,ij->i", n, d) > 0.0)[:, None], -n, n)
            flux = flux * rho / keep[:, None]
            d = _cosine_directions(n, u[:, 1], u[:, 2])
            o = p + n * geo.offset
            o, d, flux = o[survive], d[survive], flux[survive]
            _report(progress, (b + (bounce + 1) / (max_bounces + 1)) / batches)
    return done(count)


def _emit(
    sources: _Sources | None,
    day: DaylightSources | None,
    n_lamp: int,
    src: np.ndarray,
    per_source: np.ndarray,
    rng: np.random.Generator,
    geo: _Geometry,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """New paths of a batch (``src`` sorted): the lamps' first, then daylight's, in that order
    (a scene without daylight draws exactly the random numbers it drew before daylight)."""
    lamp = src < n_lamp
    parts = []
    if lamp.any():
        assert sources is not None
        parts.append(sources.emit(src[lamp], per_source[:n_lamp], rng, geo))
    if (~lamp).any():
        assert day is not None
        o, d, flux = day.emit(src[~lamp] - n_lamp, per_source[n_lamp:], rng)
        parts.append((o, d, flux, np.full(len(o), np.inf)))
    if len(parts) == 1:
        return parts[0]
    o, d, flux, reach = (np.concatenate(a) for a in zip(*parts, strict=True))
    return o, d, flux, reach


def _daylight_sources(
    scene: Scene,
    geo: _Geometry,
    caster: RayCaster,
    daylight: Daylight | None,
    seed: int,
    notes: list[str],
) -> DaylightSources | None:
    """The sun, the sky and the scene's directional lights through the scene's openings (with
    daylight on, the model's own suns give way to the sun by date and time)."""
    beams = [] if daylight is None else list(daylight.beams)
    for light in lights_with_daylight(scene.lights, daylight is not None):
        if light.kind != "directional":
            continue
        to = -np.asarray(light.direction, np.float64).reshape(-1)[:3]
        rgb = np.clip(np.asarray(light.color, np.float64).reshape(-1)[:3], 0.0, None)
        rgb = rgb * float(light.intensity)
        norm = float(np.linalg.norm(to)) if to.size == 3 else 0.0
        if not (np.isfinite(to).all() and norm > 0 and np.isfinite(rgb).all()):
            notes.append("a directional light with a non-finite direction or colour, skipped")
            continue
        if float(rgb @ LUMA) > 0.0:
            beams.append(Beam(xyz(to / norm), xyz(rgb)))
    if daylight is None and not beams:
        return None
    day = (
        Daylight(tuple(beams))
        if daylight is None
        else dataclasses.replace(daylight, beams=tuple(beams))
    )
    if day.dark:
        return None
    box = scene_box(geo.tri)
    if box is None:
        return None
    portal = find_portal(caster, box, np.asarray(scene.spawn.position, np.float64), seed)
    if not portal.open.any():
        notes.append("daylight: no window or opening found around the spawn point; no daylight")
        return None
    return DaylightSources.build(day, portal, caster)


def _report(progress: Callable[[float], None] | None, fraction: float) -> None:
    if progress is not None:
        progress(float(min(max(fraction, 0.0), 1.0)))


# -- geometry and materials -------------------------------------------------------------------


def _scene_geometry(scene: Scene) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Triangles (T, 3, 3) float64 in ``scene.triangles()`` order, owning mesh, mean vertex normal.

    Unlike ``scene.triangles()`` this tolerates out-of-range indices (that triangle becomes NaN
    and is dropped like any non-finite one) and missing normals (NaN normal: emits both sides).
    """
    tris, owner, vn = [], [], []
    for i, m in enumerate(scene.meshes):
        # float32 first, exactly as scene.triangles(), so a caster built from that matches.
        pos = np.asarray(m.positions, np.float32).reshape(-1, 3).astype(np.float64)
        idx = np.asarray(m.indices).reshape(-1, 3).astype(np.int64)
        bad = ((idx < 0) | (idx >= len(pos))).any(axis=1)
        safe = np.clip(idx, 0, max(len(pos) - 1, 0))
        t = pos[safe] if len(pos) else np.full(idx.shape + (3,), np.nan)
        t[bad] = np.nan
        normals = (
            np.asarray(m.normals, np.float64).reshape(-1, 3)
            if m.normals is not None
            else np.zeros((0, 3))
        )
        if normals.shape[0] == len(pos) and len(pos):
            nv = normals[safe].mean(axis=1)
        else:
            nv = np.full((len(idx), 3), np.nan)
        tris.append(t)
        owner.append(np.full(len(idx), i, np.int64))
        vn.append(nv)
    if not tris:
        return np.zeros((0, 3, 3)), np.zeros(0, np.int64), np.zeros((0, 3))
    return np.concatenate(tris), np.concatenate(owner), np.concatenate(vn)


def _caster_matches(caster: RayCaster, tris: np.ndarray) -> bool:
    return (
        getattr(caster, "source_index", None) is not None
        and caster.tri.shape == tris.shape
        and bool(np.array_equal(caster.tri, tris))
    )


def _diagonal(points: np.ndarray) -> float:
    if points.shape[0] == 0:
        return 1.0
    diag = float(np.linalg.norm(points.max(axis=0) - points.min(axis=0)))
    return diag if math.isfinite(diag) and diag > 0.0 else 1.0


def _see_through_meshes(scene: Scene) -> np.ndarray:
    """Per mesh: casts no shadow in the renderer (glowing or blended), so light goes through."""
    out = np.zeros(len(scene.meshes), bool)
    for i, m in enumerate(scene.meshes):
        if 0 <= m.material < len(scene.materials):
            mat = scene.materials[m.material]
            emissive = np.nan_to_num(np.asarray(mat.emissive, np.float64)[:3], nan=0.0)
            out[i] = bool((emissive > 0.0).any()) or mat.alpha_mode == "BLEND"
    return out


class _SeeThrough:
    """A ray caster that lets the see-through triangles (``passes``) through: a ray that hits
    one is cast again from just behind it, up to PASS_THROUGH times. Distances stay measured
    from the ray's origin along its unit direction."""

    def __init__(self, caster: RayCaster, passes: np.ndarray, offset: float) -> None:
        self.caster = caster
        self.passes = passes
        self.offset = max(float(offset), 1e-9)
        self.tri = caster.tri

    @staticmethod
    def around(caster: RayCaster, passes: np.ndarray, offset: float) -> RayCaster:
        """``caster`` itself when nothing is see-through (no second casts to pay for)."""
        if len(passes) != len(caster.tri) or not passes.any():
            return caster
        return _SeeThrough(caster, passes, offset)  # type: ignore[return-value]

    def cast_triangles(
        self, origins, directions, t_max: float = math.inf
    ) -> tuple[np.ndarray, np.ndarray]:
        o = np.asarray(origins, np.float64).reshape(-1, 3)
        d = np.asarray(directions, np.float64).reshape(-1, 3)
        dist, tri = self.caster.cast_triangles(o, d, t_max)
        norm = np.linalg.norm(d, axis=1)
        unit = d / np.where(norm > 0.0, norm, 1.0)[:, None]
        for _ in range(PASS_THROUGH):
            through = tri >= 0
            through[through] = self.passes[tri[through]]
            if not through.any():
                break
            idx = np.flatnonzero(through)
            start = dist[idx] + self.offset
            more, hit = self.caster.cast_triangles(o[idx] + unit[idx] * start[:, None], unit[idx])
            total = start + more
            ok = (hit >= 0) & (total <= t_max)
            dist[idx] = np.where(ok, total, np.inf)
            tri[idx] = np.where(ok, hit, -1)
        return dist, tri


@dataclass
class _Geometry:
    """Per-triangle data in the caster's (finite-filtered) triangle order."""

    tri: np.ndarray  # (T, 3, 3) float64
    normal: np.ndarray  # (T, 3) unit geometric normal (winding order), zero if degenerate
    area: np.ndarray  # (T,)
    usable: np.ndarray  # (T,) bool: has a normal (a degenerate triangle absorbs)
    rho: np.ndarray  # (T, 3) diffuse reflectance
    emissive: np.ndarray  # (T, 3) linear radiance
    front: np.ndarray  # (T,) +1 / -1 emitting side along ``normal``, 0 = both
    offset: float  # ray origin offset off a surface, metres

    @staticmethod
    def build(
        scene: Scene, caster: RayCaster, mesh: np.ndarray, vnormal: np.ndarray, notes: list[str]
    ) -> _Geometry:
        tri = caster.tri
        cross = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        length = np.linalg.norm(cross, axis=1)
        usable = np.isfinite(length) & (length > 1e-20)
        normal = np.where(usable[:, None], cross / np.where(usable, length, 1.0)[:, None], 0.0)
        area = np.where(usable, 0.5 * length, 0.0)
        rho_m, emit_m = _mesh_optics(scene, notes)
        rho = rho_m[mesh] if len(mesh) else np.zeros((0, 3))
        emissive = emit_m[mesh] if len(mesh) else np.zeros((0, 3))
        front = emitting_side(vnormal, normal)
        scale = _diagonal(tri.reshape(-1, 3))
        return _Geometry(
            tri, normal, area, usable, rho, emissive, front.astype(np.int8), OFFSET_SCALE * scale
        )


def emitting_side(vnormal: np.ndarray, normal: np.ndarray) -> np.ndarray:
    """Per triangle the side a glowing one emits from, +1 / -1 along its plane's unit
    ``normal`` or 0 for both: the side its mean vertex normal ``vnormal`` points to, both
    where that is missing (NaN) or lies in the plane."""
    vn = np.nan_to_num(np.asarray(vnormal, np.float64), nan=0.0)
    with np.errstate(invalid="ignore"):
        cos = np.einsum("ij,ij->i", vn, normal) / np.maximum(np.linalg.norm(vn, axis=1), 1e-20)
    return np.where(cos > FRONT_MIN_COS, 1, np.where(cos < -FRONT_MIN_COS, -1, 0))


def _mesh_optics(scene: Scene, notes: list[str]) -> tuple[np.ndarray, np.ndarray]:
    """Diffuse reflectance and emitted radiance (the emissive factor times the emissive map's
    mean) per mesh, (M, 3) each, finite and >= 0."""
    texture_mean: dict[object, np.ndarray] = {}
    rho = np.zeros((len(scene.meshes), 3))
    emit = np.zeros((len(scene.meshes), 3))
    for i, m in enumerate(scene.meshes):
        if 0 <= m.material < len(scene.materials):
            mat = scene.materials[m.material]
        else:
            notes.append(f"mesh '{m.name}': material {m.material} missing, default grey")
            mat = Material("default")
        base = _clean(mat.base_color[:3], 1.0)
        metallic = float(np.clip(np.nan_to_num(float(mat.metallic), nan=0.0), 0.0, 1.0))
        r = base * (1.0 - metallic)
        tex = mat.texture
        if tex is not None and 0 <= tex < len(scene.textures):
            if tex not in texture_mean:
                texture_mean[tex] = _texture_mean_linear(scene.textures[tex].rgba)
            r = r * texture_mean[tex]
        if m.colors is not None:
            c = np.asarray(m.colors, np.float64)
            if c.ndim == 2 and c.shape[1] >= 3 and c.shape[0]:
                with np.errstate(invalid="ignore"):
                    r = r * _clean(
                        np.nanmean(np.where(np.isfinite(c[:, :3]), c[:, :3], np.nan), axis=0), 1.0
                    )
        rho[i] = np.clip(r, 0.0, 1.0)
        glow = np.clip(
            np.nan_to_num(
                np.asarray(mat.emissive, np.float64)[:3], nan=0.0, posinf=0.0, neginf=0.0
            ),
            0.0,
            1e6,
        )
        et = mat.emissive_texture
        if glow.any() and et is not None and 0 <= et < len(scene.textures):
            if ("emissive", et) not in texture_mean:  # the map's mean (a bulb in a dark disc)
                texture_mean[("emissive", et)] = _texture_mean_linear(scene.textures[et].rgba)
            glow = glow * texture_mean[("emissive", et)]
        emit[i] = glow
    return rho, emit


def _clean(values, fallback: float) -> np.ndarray:
    v = np.asarray(values, np.float64).reshape(-1)[:3]
    v = np.where(np.isfinite(v), v, fallback)
    return np.clip(v, 0.0, 1.0)


def _texture_mean_linear(rgba: np.ndarray) -> np.ndarray:
    """Mean linear RGB of an sRGB texture (alpha ignored); white if unreadable."""
    a = np.asarray(rgba)
    if a.ndim == 2:
        a = a[:, :, None]
    if a.ndim != 3 or a.size == 0:
        return np.ones(3)
    rgb = a[:, :, :3] if a.shape[2] >= 3 else np.repeat(a[:, :, :1], 3, axis=2)
    if rgb.dtype == np.uint8:
        lin = SRGB8_TO_LINEAR[rgb]
    else:
        f = rgb.astype(np.float64)
        if np.issubdtype(rgb.dtype, np.integer):
            f = f / float(np.iinfo(rgb.dtype).max)
        f = np.clip(np.nan_to_num(f, nan=0.0), 0.0, 1.0)
        lin = srgb_to_linear(f)
    return lin.reshape(-1, 3).mean(axis=0)


# -- lights ------------------------------------------------------------------------------------


@dataclass
class _Sources:
    """Point lights (one source each), then all emissive triangles as one last source."""

    position: np.ndarray  # (P, 3) point-light positions
    flux: np.ndarray  # (P, 3) RGB power of each light's emission solid angle at full intensity
    reach: np.ndarray  # (P,) range in metres (inf allowed)
    area_tri: np.ndarray  # (E,) emissive triangle indices into the geometry
    area_cdf: np.ndarray  # (E,) cumulative area * luminance(L_e)
    power_luma: np.ndarray  # (P [+1],) luminance power per source: photons are shared by it
    # Spots (P, 3) axis and (P, 2) cos(outer) and 1 / (cos inner - cos outer); a point light:
    # axis +z, cos(outer) -1 (the whole sphere), scale 0 (no falloff).
    axis: np.ndarray | None = None
    cone: np.ndarray | None = None

    @property
    def n_point(self) -> int:
        return int(self.position.shape[0])

    def emit(
        self, src: np.ndarray, per_source: np.ndarray, rng: np.random.Generator, geo: _Geometry
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Origins, directions, flux and first-hit reach (point lights' range) of new paths."""
        m = len(src)
        u = rng.random((m, 6))  # direction (2), triangle, barycentrics (2), side
        o = np.zeros((m, 3))
        d = np.zeros((m, 3))
        flux = np.zeros((m, 3))
        reach = np.full(m, np.inf)
        pt = src < self.n_point
        if pt.any():
            s = src[pt]
            n_pt = int(np.count_nonzero(pt))
            axis = self.axis[s] if self.axis is not None else np.tile([0.0, 0.0, 1.0], (n_pt, 1))
            cone = self.cone[s] if self.cone is not None else np.tile([-1.0, 0.0], (n_pt, 1))
            # Uniform over the emission cone (a point light's: the sphere), weighted by the
            # spot's smooth falloff (glTF's, as the renderer's).
            z = 1.0 - u[pt, 0] * (1.0 - cone[:, 0])
            r = np.sqrt(np.clip(1.0 - z * z, 0.0, None))
            phi = 2.0 * np.pi * u[pt, 1]
            x, y = r * np.cos(phi), r * np.sin(phi)
            t_axis, s_axis = _basis(axis)
            d[pt] = t_axis * x[:, None] + s_axis * y[:, None] + axis * z[:, None]
            falloff = np.where(
                cone[:, 1] > 0.0, np.clip((z - cone[:, 0]) * cone[:, 1], 0.0, 1.0) ** 2, 1.0
            )
            o[pt] = self.position[s]
            flux[pt] = self.flux[s] * (falloff / per_source[s])[:, None]
            reach[pt] = self.reach[s]
        ar = ~pt
        if ar.any():
            total = self.area_cdf[-1]
            k = np.searchsorted(self.area_cdf, u[ar, 2] * total, side="right")
            t = self.area_tri[np.minimum(k, len(self.area_tri) - 1)]
            sq = np.sqrt(u[ar, 3])
            b1, b2 = sq * (1.0 - u[ar, 4]), sq * u[ar, 4]
            tri = geo.tri[t]
            point = (
                tri[:, 0]
                + b1[:, None] * (tri[:, 1] - tri[:, 0])
                + b2[:, None] * (tri[:, 2] - tri[:, 0])
            )
            side = geo.front[t].astype(np.float64)
            side = np.where(side == 0, np.where(u[ar, 5] < 0.5, -1.0, 1.0), side)
            n = geo.normal[t] * side[:, None]
            d[ar] = _cosine_directions(n, u[ar, 0], u[ar, 1])
            o[ar] = point + n * geo.offset
            # pdf of triangle t is A_t lum_t / total; its power is pi A_t L_e: flux per photon.
            le = geo.emissive[t]
            lum = np.maximum(le @ LUMA, 1e-300)
            flux[ar] = np.pi * le * (total / lum)[:, None] / per_source[self.n_point]
        return o, d, flux, reach


def _basis(n: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors completing unit normals ``n`` (N, 3) (Duff et al. 2017; +z: x, y)."""
    sign = np.where(n[:, 2] >= 0.0, 1.0, -1.0)
    a = -1.0 / (sign + n[:, 2])
    b = n[:, 0] * n[:, 1] * a
    t = np.stack([1.0 + sign * n[:, 0] ** 2 * a, sign * b, -sign * n[:, 0]], axis=1)
    s = np.stack([b, sign + n[:, 1] ** 2 * a, -n[:, 1]], axis=1)
    return t, s


def _light_sources(scene: Scene, geo: _Geometry, notes: list[str]) -> _Sources | None:
    pos, flux, reach, axes, cones = [], [], [], [], []
    for i, light in enumerate(scene.lights):
        if light.kind == "directional":
            continue  # a parallel beam through the openings (app.daylight_photons)
        p = np.asarray(light.position, np.float64).reshape(-1)[:3]
        c = np.asarray(light.color, np.float64).reshape(-1)[:3]
        inten, rng_m = float(light.intensity), float(light.range_m)
        if p.size < 3 or not np.isfinite(p).all():
            notes.append(f"light {i}: non-finite position, skipped")
            continue
        if c.size < 3 or not np.isfinite(c).all() or not math.isfinite(inten) or math.isnan(rng_m):
            notes.append(f"light {i}: non-finite colour, intensity or range, skipped")
            continue
        c = np.clip(c, 0.0, None)
        if inten <= 0.0 or rng_m <= 0.0 or float(c @ LUMA) <= 0.0:
            continue  # emits nothing: not worth a note (a light switched off)
        axis, cone = np.array([0.0, 0.0, 1.0]), np.array([-1.0, 0.0])
        if light.kind == "spot":
            a = np.asarray(light.direction, np.float64)
            norm = float(np.linalg.norm(a))
            axis = a / norm if norm > 1e-12 and math.isfinite(norm) else np.array([0.0, -1.0, 0.0])
            outer = math.radians(min(max(float(light.outer_cone_deg), 0.01), 90.0))
            inner = min(max(math.radians(float(light.inner_cone_deg)), 0.0), outer)
            cos_o = math.cos(outer)
            cone = np.array([cos_o, 1.0 / max(1e-3, math.cos(inner) - cos_o)])
        pos.append(p)
        flux.append(2.0 * np.pi * (1.0 - cone[0]) * inten * c)  # the cone's solid angle
        reach.append(rng_m)
        axes.append(axis)
        cones.append(cone)
    weight = geo.area * (geo.emissive @ LUMA) if len(geo.area) else np.zeros(0)
    weight = np.where(np.isfinite(weight), weight, 0.0)
    area_tri = np.flatnonzero(weight > 0.0)
    area_cdf = np.cumsum(weight[area_tri])
    luma = [float(f @ LUMA) for f in flux]
    if len(area_tri):
        luma.append(float(np.pi * area_cdf[-1]))
    if not luma or not np.isfinite(luma).all() or sum(luma) <= 0.0:
        notes.append("no light in the scene emits: empty photon map")
        return None
    return _Sources(
        np.reshape(pos, (-1, 3)),
        np.reshape(flux, (-1, 3)),
        np.asarray(reach),
        area_tri,
        area_cdf,
        np.asarray(luma),
        np.reshape(axes, (-1, 3)),
        np.reshape(cones, (-1, 2)),
    )


def _allocate(power: np.ndarray, count: int) -> np.ndarray:
    """Photons per source, proportional to power, by largest remainder (deterministic)."""
    share = power / power.sum() * count
    n = np.floor(share).astype(np.int64)
    rest = count - int(n.sum())
    if rest > 0:
        order = np.argsort(-(share - n), kind="stable")
        n[order[:rest]] += 1
    return n


def _cosine_directions(n: np.ndarray, u1: np.ndarray, u2: np.ndarray) -> np.ndarray:
    """Cosine-weighted unit directions about unit normals ``n`` (N, 3)."""
    r = np.sqrt(u1)
    phi = 2.0 * np.pi * u2
    x, y, z = r * np.cos(phi), r * np.sin(phi), np.sqrt(np.clip(1.0 - u1, 0.0, None))
    # Orthonormal basis without a branch on the normal (Duff et al. 2017).
    sign = np.where(n[:, 2] >= 0.0, 1.0, -1.0)
    a = -1.0 / (sign + n[:, 2])
    b = n[:, 0] * n[:, 1] * a
    t = np.stack([1.0 + sign * n[:, 0] ** 2 * a, sign * b, -sign * n[:, 0]], axis=1)
    s = np.stack([b, sign + n[:, 1] ** 2 * a, -n[:, 1]], axis=1)
    d = t * x[:, None] + s * y[:, None] + n * z[:, None]
    return d / np.maximum(np.linalg.norm(d, axis=1, keepdims=True), 1e-300)
