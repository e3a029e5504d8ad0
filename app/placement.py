"""Put a file's geometry where a person can stand in it: metres, and near the origin.

Readers hand meshes over with float64 positions in the file's own units; :func:`place` scales them
to metres and, for a model far from the origin (survey coordinates, a building placed in a city
model), subtracts an offset before the float32 cast, so a room a million metres out keeps its
millimetres. The offset is kept on the scene for display.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from app.scene import PointLight, Scene

# Beyond this distance from the origin (in metres) float32 spacing reaches a tenth of a
# millimetre, so the model is re-centred.
RECENTRE_BEYOND_M = 2048.0


def place(scene: Scene, unit_scale: float | None) -> Scene:
    """``scene`` scaled to metres (``None``: the file's units are metres) and re-centred if far."""
    scale = 1.0 if unit_scale is None else float(unit_scale)
    finite = [
        np.asarray(m.positions, np.float64)[np.isfinite(m.positions).all(axis=1)]
        for m in scene.meshes
    ]
    finite = [f for f in finite if len(f)]
    offset = np.zeros(3)
    if finite:
        lo = np.min([f.min(axis=0) for f in finite], axis=0) * scale
        hi = np.max([f.max(axis=0) for f in finite], axis=0) * scale
        centre = (lo + hi) / 2.0
        if np.abs(np.concatenate([lo, hi])).max() > RECENTRE_BEYOND_M:
            # Keep the floor's height: only the horizontal position (and a far height) moves.
            offset = np.array(
                [centre[0], centre[1] if abs(centre[1]) > RECENTRE_BEYOND_M else 0.0, centre[2]]
            )
    meshes = []
    with np.errstate(invalid="ignore", over="ignore"):
        for m in scene.meshes:
            pos = np.asarray(m.positions, np.float64) * scale - offset
            meshes.append(replace(m, positions=pos.astype(np.float32)))
    lights = [
        PointLight(
            tuple(float(v) for v in np.asarray(light.position) * scale - offset),  # type: ignore[arg-type]
            light.color,
            light.intensity,
            light.range_m * scale,
        )
        for light in scene.lights
    ]
    warnings = list(scene.warnings)
    if offset.any():
        warnings.append(
            "the model lies far from the origin: moved by "
            f"({0.0 - offset[0]:.1f}, {0.0 - offset[1]:.1f}, {0.0 - offset[2]:.1f}) m "
            "to keep its precision"
        )
    return replace(
        scene,
        meshes=meshes,
        lights=lights,
        unit_scale=scale,
        origin_offset=(float(offset[0]), float(offset[1]), float(offset[2])),
        warnings=warnings,
    )
