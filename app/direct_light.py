"""Light arriving straight from its source at points of a scene, on the CPU: what the even
light's estimate (``app.ambient``) bounces. The lamps' (with the renderer's falloff and spot
cone, or without its range window for their bounce), the sun's (shadow rays through the
scene's ray caster) and the open sky's (its irradiance for a normal, from the baked sky's
spherical harmonics)."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from app.raycast import RayCaster
from app.scene import LIGHT_MIN_DIST2, Light, lamp_falloff, range_window
from app.sky_model import sh_basis

LUMA = np.array([0.2126, 0.7152, 0.0722])


def bounce_falloff(d2: np.ndarray, range_m: float) -> np.ndarray:
    """A lamp's irradiance per candela for its bounced light: the physical inverse square
    with the renderer's 10 cm floor, without the range window (the renderer stops drawing a
    lamp's direct light there; its light goes on and comes back off the walls)."""
    del range_m
    return 1.0 / np.maximum(np.asarray(d2, np.float64), LIGHT_MIN_DIST2)


def direct(
    points: np.ndarray,
    normal: np.ndarray,
    lights: Sequence[Light],
    caster: RayCaster,
    eps: float,
    whole_lamp: bool = False,
) -> np.ndarray:
    """Direct irradiance (lux, luminance of the light's colour) on faces with ``normal``;
    ``whole_lamp``: without the range window (:func:`bounce_falloff`)."""
    return direct_rgb(points, normal, lights, caster, eps, whole_lamp) @ LUMA


def direct_rgb(
    points: np.ndarray,
    normal: np.ndarray,
    lights: Sequence[Light],
    caster: RayCaster,
    eps: float,
    whole_lamp: bool = False,
    drawn: np.ndarray | None = None,
) -> np.ndarray:
    """:func:`direct` in colour (N, 3): each light's colour times its intensity. ``drawn``
    (N, 3), with ``whole_lamp``: the part the renderer draws (within the range window) is
    added to it, from the same shadow rays."""
    out = np.zeros((points.shape[0], 3))
    for light in lights:
        rgb = np.asarray(light.color, np.float64).reshape(3) * float(light.intensity)
        lum = float(rgb @ LUMA)
        if not (math.isfinite(lum) and lum > 0.0 and np.isfinite(rgb).all()):
            continue
        rgb = np.maximum(rgb, 0.0)
        if light.kind == "directional":
            d = -np.asarray(light.direction, np.float64)
            d = d / max(float(np.linalg.norm(d)), 1e-12)
            cos = normal @ d
            lit = cos > 0.0
            if not lit.any():
                continue
            origin = points[lit] + normal[lit] * eps
            dist, _ = caster.cast_many(origin, np.broadcast_to(d, origin.shape))
            e = np.where(np.isinf(dist), cos[lit], 0.0)
            out[lit] += e[:, None] * rgb
            continue
        to_l = np.asarray(light.position, np.float64) - points
        d2 = np.einsum("ij,ij->i", to_l, to_l)
        dist_l = np.sqrt(d2)
        ldir = to_l / np.maximum(dist_l, 1e-9)[:, None]
        cos = np.einsum("ij,ij->i", normal, ldir)
        falloff = bounce_falloff if whole_lamp else lamp_falloff
        fall = falloff(d2, float(light.range_m)) * spot_cone(light, ldir)
        lit = (cos > 0.0) & (fall > 0.0)
        if not lit.any():
            continue
        origin = points[lit] + normal[lit] * eps
        hit, _ = caster.cast_many(origin, ldir[lit])
        seen = hit >= dist_l[lit] - 2.0 * eps
        out[lit] += np.where(seen, cos[lit] * fall[lit], 0.0)[:, None] * rgb
        if drawn is not None and whole_lamp:
            window = range_window(d2[lit], float(light.range_m))
            drawn[lit] += np.where(seen, cos[lit] * fall[lit] * window, 0.0)[:, None] * rgb
    return out


def sky_irradiance_rgb(normal: np.ndarray, sky_sh: np.ndarray) -> np.ndarray:
    """The open sky's irradiance (lux, RGB: its blue for the bounce's colour) on faces with
    ``normal``: pi SH(n)."""
    white = sh_basis(normal) @ np.asarray(sky_sh, np.float64).reshape(9, 3)
    return math.pi * np.maximum(white, 0.0)


def sky_irradiance(normal: np.ndarray, sky_sh: np.ndarray) -> np.ndarray:
    """:func:`sky_irradiance_rgb`'s luminance."""
    return sky_irradiance_rgb(normal, sky_sh) @ LUMA


def spot_cone(light: Light, to_light: np.ndarray) -> np.ndarray:
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


def cosine_direction(n: np.ndarray, u1: np.ndarray, u2: np.ndarray) -> np.ndarray:
    """A cosine-weighted unit direction about each unit normal ``n`` (N, 3)."""
    r = np.sqrt(u1)
    phi = 2.0 * math.pi * u2
    helper = np.where(np.abs(n[:, :1]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
    t = np.cross(n, helper)
    t /= np.maximum(np.linalg.norm(t, axis=1), 1e-12)[:, None]
    b = np.cross(n, t)
    z = np.sqrt(np.maximum(1.0 - u1, 0.0))
    return t * (r * np.cos(phi))[:, None] + b * (r * np.sin(phi))[:, None] + n * z[:, None]
