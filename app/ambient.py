"""The ambient term estimated from the light the lamps send round the room.

Setting ``render.ambient_estimate``. One constant ambient (``render.ambient``) is the same in a
dim corridor and a sunlit room. A path tracer's indirect light is the lamps' light bounced off
walls and furniture, and for the even part of it a room behaves like an enclosure (the
split-flux method of lighting design): the light leaving the surfaces after the first bounce is
``rho E_direct`` summed over their area, it lands on the faces that see the room (a face's
closure ``c``: the share of its hemisphere that meets the scene, 1 inside a room, 0 on a wall's
outer face, less in an open model), and each further bounce keeps a share ``rho c`` of it, so

    E_indirect = E_1 / (1 - k),  E_1 = B_1 sum(A c^2) / sum(A c),
    B_1 = sum(A rho E_direct c) / sum(A c),  k = sum(A rho c^2) / sum(A c)

(a face receives ``c`` times the mean exitance of what it sees, and the faces that see the
scene are the ones a viewer inside it sees, so they are weighted by ``c`` too)

and the ambient radiance scale the shaders take (``u_ambient``: ``albedo * u_ambient`` is the
radiance a surface sends back) is ``E_indirect / pi``.

The direct irradiance is the renderer's (``app.scene.lamp_falloff``, the spot cone, the sun's
cosine), with shadows: a point sees a lamp only when the ray caster finds nothing in between.
Points are spread over the scene's surface by area (seeded, so the same scene gives the same
value); the reflectances are the photon tracer's (``app.photons``: base colour x texture mean x
vertex colours x (1 - metallic)).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from app.photons import _mesh_optics, _scene_geometry
from app.raycast import RayCaster
from app.scene import Light, Scene, lamp_falloff
from app.sky_light import occluders

LUMA = np.array([0.2126, 0.7152, 0.0722])
SAMPLES = 2048  # surface points (the estimate moves by about 1 % between seeds)
CLOSURE_RAYS = 4  # cosine-weighted rays per face that measure how much of the scene it sees
SEED = 14
#: A bounce keeps at most this share (a white closed box would otherwise diverge).
MAX_KEPT = 0.95


@dataclass(frozen=True)
class AmbientEstimate:
    """The estimate and what it is made of (luminance, lux and cd/m2)."""

    ambient: float  # u_ambient: the radiance of a white surface from the even indirect light
    direct_mean_lux: float  # mean direct irradiance over the faces that see the scene
    first_bounce_lux: float  # mean irradiance of the first bounce on those faces
    mean_albedo: float  # area-weighted mean reflectance (luminance)
    closure: float  # mean share of the scene a face sees (1: every face inside a room)


NONE = AmbientEstimate(0.0, 0.0, 0.0, 0.0, 0.0)


def estimate_ambient(
    scene: Scene,
    lights: Sequence[Light] | None = None,
    caster: RayCaster | None = None,
    samples: int = SAMPLES,
    seed: int = SEED,
) -> AmbientEstimate:
    """The even indirect light of ``scene`` under ``lights`` (the scene's own by default).

    An empty scene, one without lights, or one whose every surface is black gives 0 (no light
    comes back), never an error."""
    lights = list(scene.lights if lights is None else lights)
    if not lights:
        return NONE
    return AmbientProbe(scene, caster, samples, seed).estimate(lights)


class AmbientProbe:
    """What the estimate needs of a scene alone, found once: surface points spread by area,
    their reflectance and how much of the scene each of their two faces sees. ``estimate``
    then casts only the lamps' shadow rays, so a moving sun costs a few milliseconds."""

    def __init__(
        self,
        scene: Scene,
        caster: RayCaster | None = None,
        samples: int = SAMPLES,
        seed: int = SEED,
    ) -> None:
        self.points = np.zeros((0, 3))
        self.mean_albedo = 0.0
        tris, owner, _vn = _scene_geometry(scene)
        if tris.shape[0] == 0:
            return
        # Rays meet what hides light in the renderer: glowing panes and glass let it through
        # (app.sky_light.occluders); the given caster serves when nothing is left out.
        blocking = occluders(scene)
        if caster is None or blocking.shape[0] != tris.shape[0]:
            cached = getattr(scene, "ray_caster", None)
            whole = blocking.shape[0] == tris.shape[0] and isinstance(cached, RayCaster)
            caster = cached if whole and isinstance(cached, RayCaster) else RayCaster(blocking)
        self.caster: RayCaster = caster
        finite = np.isfinite(tris).all(axis=(1, 2))
        tris, owner = tris[finite], owner[finite]
        cross = np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0])
        length = np.linalg.norm(cross, axis=1)
        area = 0.5 * length
        if tris.shape[0] == 0 or not np.isfinite(area).all() or area.sum() <= 0.0:
            return
        normal = cross / np.maximum(length, 1e-30)[:, None]
        rho_mesh, _emit = _mesh_optics(scene, [])
        rho = rho_mesh[owner] @ LUMA
        self.mean_albedo = float((rho * area).sum() / area.sum())

        rng = np.random.default_rng(seed)
        pick = rng.choice(len(area), size=samples, p=area / area.sum())
        u, v = rng.random(samples), rng.random(samples)
        su = np.sqrt(u)
        b1, b2 = su * (1.0 - v), su * v
        t = tris[pick]
        self.points = (
            t[:, 0] + b1[:, None] * (t[:, 1] - t[:, 0]) + b2[:, None] * (t[:, 2] - t[:, 0])
        )
        self.normal = normal[pick]
        self.rho = rho[pick]
        diag = float(np.linalg.norm(tris.reshape(-1, 3).max(0) - tris.reshape(-1, 3).min(0)))
        self.eps = 1e-4 * max(diag, 1e-3)
        # Every surface is two-sided (as the renderer draws it): each face sees the scene by
        # its closure c (a wall's inner face 1, its outer face 0, a table top in between).
        self.closure = [
            _closure(self.points, self.normal * side, caster, self.eps, rng) for side in (1.0, -1.0)
        ]

    def estimate(
        self, lights: Sequence[Light], sky_sh: np.ndarray | None = None
    ) -> AmbientEstimate:
        """The estimate under ``lights``: each face takes the lamps' light from its own side.
        A face receives c times the mean exitance of what it sees (reciprocity), and what it
        sees is weighted by c too: B_1 = sum(A rho E c) / sum(A c), E_1 = B_1 sum(A c^2) /
        sum(A c); each further bounce keeps sum(A rho c^2) / sum(A c).

        ``sky_sh``: the sky's light (``app.sky.SkyBake.sh``, light leaving a white surface per
        normal, cd/m2) with daylight on; a face then also takes pi SH(n) times the share of
        its rays that leave the scene (1 - c), and that light bounces as the lamps' does."""
        if not len(self.points) or (not lights and sky_sh is None):
            return AmbientEstimate(0.0, 0.0, 0.0, self.mean_albedo, 0.0)
        r = self.rho
        sent = seen = seen2 = kept_sum = direct_sum = 0.0
        for side, c in zip((1.0, -1.0), self.closure, strict=True):
            e = _direct(self.points, self.normal * side, lights, self.caster, self.eps)
            if sky_sh is not None:
                e = e + _sky_irradiance(self.normal * side, sky_sh) * (1.0 - c)
            sent += float((r * e * c).sum())
            seen += float(c.sum())
            seen2 += float((c * c).sum())
            kept_sum += float((r * c * c).sum())
            direct_sum += float((e * c).sum())
        if seen <= 0.0:  # nothing sees anything: an open sheet, no light comes back
            return AmbientEstimate(0.0, 0.0, 0.0, self.mean_albedo, 0.0)
        first = sent / seen * (seen2 / seen)
        kept = min(kept_sum / seen, MAX_KEPT)
        indirect = first / (1.0 - kept)
        closure = seen / (2.0 * len(self.points))
        return AmbientEstimate(
            indirect / math.pi, direct_sum / seen, first, self.mean_albedo, closure
        )


def _direct(
    points: np.ndarray,
    normal: np.ndarray,
    lights: Sequence[Light],
    caster: RayCaster,
    eps: float,
) -> np.ndarray:
    """Direct irradiance (lux, luminance of the light's colour) on faces with ``normal``."""
    out = np.zeros(points.shape[0])
    for light in lights:
        lum = float(np.asarray(light.color, np.float64) @ LUMA) * float(light.intensity)
        if not (math.isfinite(lum) and lum > 0.0):
            continue
        if light.kind == "directional":
            d = -np.asarray(light.direction, np.float64)
            d = d / max(float(np.linalg.norm(d)), 1e-12)
            cos = normal @ d
            lit = cos > 0.0
            if not lit.any():
                continue
            origin = points[lit] + normal[lit] * eps
            dist, _ = caster.cast_many(origin, np.broadcast_to(d, origin.shape))
            e = np.where(np.isinf(dist), lum * cos[lit], 0.0)
            out[lit] += e
            continue
        to_l = np.asarray(light.position, np.float64) - points
        d2 = np.einsum("ij,ij->i", to_l, to_l)
        dist_l = np.sqrt(d2)
        ldir = to_l / np.maximum(dist_l, 1e-9)[:, None]
        cos = np.einsum("ij,ij->i", normal, ldir)
        fall = lamp_falloff(d2, float(light.range_m)) * _cone(light, ldir)
        lit = (cos > 0.0) & (fall > 0.0)
        if not lit.any():
            continue
        origin = points[lit] + normal[lit] * eps
        hit, _ = caster.cast_many(origin, ldir[lit])
        seen = hit >= dist_l[lit] - 2.0 * eps
        out[lit] += np.where(seen, lum * cos[lit] * fall[lit], 0.0)
    return out


def _sky_irradiance(normal: np.ndarray, sky_sh: np.ndarray) -> np.ndarray:
    """The open sky's irradiance (lux, luminance) on faces with ``normal``: pi SH(n)."""
    from app.sky_model import sh_basis

    white = sh_basis(normal) @ np.asarray(sky_sh, np.float64).reshape(9, 3)
    return math.pi * np.maximum(white @ LUMA, 0.0)


def _cone(light: Light, to_light: np.ndarray) -> np.ndarray:
    """glTF's smooth spot falloff (render/shaders/shadows.glsl spot_cone); 1 for a point."""
    if light.kind != "spot":
        return np.ones(to_light.shape[0])
    axis = np.asarray(light.direction, np.float64)
    axis = axis / max(float(np.linalg.norm(axis)), 1e-12)
    outer = min(max(float(light.outer_cone_deg), 0.0), 90.0)
    inner = min(max(float(light.inner_cone_deg), 0.0), outer)
    cos_o, cos_i = math.cos(math.radians(outer)), math.cos(math.radians(inner))
    t = np.clip(((-to_light) @ axis - cos_o) / max(1e-3, cos_i - cos_o), 0.0, 1.0)
    return t * t


def _closure(
    points: np.ndarray, normal: np.ndarray, caster: RayCaster, eps: float, rng: np.random.Generator
) -> np.ndarray:
    """Per face, the share of cosine-weighted rays along ``normal`` that hit the scene."""
    hits = np.zeros(len(points))
    for _ in range(CLOSURE_RAYS):
        d = _cosine(normal, rng.random(len(points)), rng.random(len(points)))
        dist, _ = caster.cast_many(points + normal * eps, d)
        hits += np.isfinite(dist)
    return hits / CLOSURE_RAYS


def _cosine(n: np.ndarray, u1: np.ndarray, u2: np.ndarray) -> np.ndarray:
    r = np.sqrt(u1)
    phi = 2.0 * math.pi * u2
    helper = np.where(np.abs(n[:, :1]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
    t = np.cross(n, helper)
    t /= np.maximum(np.linalg.norm(t, axis=1), 1e-12)[:, None]
    b = np.cross(n, t)
    z = np.sqrt(np.maximum(1.0 - u1, 0.0))
    return t * (r * np.cos(phi))[:, None] + b * (r * np.sin(phi))[:, None] + n * z[:, None]


def probe_for(scene: Scene, caster: RayCaster | None = None) -> AmbientProbe:
    """``scene``'s probe, found once and kept on it (``Scene.ambient_probe``): the window's
    loader finds it on its worker thread (0.2 s for the showroom, 1.6 s for a 380k-triangle
    room), the renderer then only reads it."""
    probe = scene.ambient_probe
    if not isinstance(probe, AmbientProbe):
        probe = AmbientProbe(scene, caster)
        scene.ambient_probe = probe
    return probe
