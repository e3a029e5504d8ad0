"""Default point lights for a scene whose file has none, so the first frame is never black."""

from __future__ import annotations

import logging
import math

import numpy as np

from app.raycast import RayCaster
from app.scene import PointLight, Scene, lamp_falloff
from app.spawn import EYE_HEIGHT_M, SpawnResult

log = logging.getLogger(__name__)

_LIGHT_TARGET_RADIANCE = 1.0  # per default light, at a typical surface distance
_M_PER_LIGHT = 150.0  # floor area one default interior light is expected to cover (m^2)


def safe_default_lights(
    scene: Scene, spawn: SpawnResult, caster: RayCaster
) -> tuple[list[PointLight], list[str]]:
    """:func:`default_lights` that never raises: a failure gives one light above the centre."""
    try:
        return default_lights(scene, spawn, caster), []
    except Exception as exc:  # noqa: BLE001 - a lighting bug must not stop a load
        log.exception("default lights failed on %s", scene.name)
        lo, hi = (np.asarray(b, np.float64) for b in scene.bounds())
        lo, hi = np.nan_to_num(lo), np.nan_to_num(hi)
        diag = max(float(np.linalg.norm(hi - lo)), 1.0)
        centre = (lo + hi) / 2.0
        pos = (float(centre[0]), float(min(hi[1], centre[1] + diag / 4.0)), float(centre[2]))
        # unit irradiance at half the diagonal under the inverse square
        light = PointLight(pos, (1.0, 1.0, 1.0), float(diag * diag / 4.0), float(diag))
        return [light], [
            f"could not place the default lights (an unexpected {type(exc).__name__}; "
            "details in the log): added one light above the centre"
        ]


def default_lights(scene: Scene, spawn: SpawnResult, caster: RayCaster) -> list[PointLight]:
    """A few point lights so a file without lights is visible on the first frame.

    Interior: 1-4 lights spread over the floor level the viewer stands on, part way up to the
    ceiling. Object: a key light above and in front and a weaker fill beside the viewer.
    Intensity is set so a surface at a typical distance receives about unit irradiance under the
    renderer's physical falloff (``app.scene.lamp_falloff``: ``intensity / d^2`` times the range
    window), and the range is a few times that distance (at least a third of the scene) so the
    window does not cut it short.
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
        # Few hits (a light outside an object): the object's centre is where its light goes.
        centre_dist = float(np.linalg.norm(pos - (lo + hi) / 2.0))
        typical = float(np.median(hits)) if hits.size >= len(dirs) // 4 else centre_dist
        typical = max(typical, 0.1)
        rng = max(3.0 * typical, diag / 3.0)
        intensity = target / float(lamp_falloff(typical * typical, rng))
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
