"""Put a file's geometry where a person can stand in it: metres, and near the origin.

Readers hand meshes over with float64 positions in the file's own units; :func:`place` scales them
to metres and, for a model far from the origin (survey coordinates, a building placed in a city
model), subtracts an offset before the float32 cast, so a room a million metres out keeps its
millimetres. The offset is kept on the scene for display.
"""

from __future__ import annotations

import logging
import math
from dataclasses import replace

import numpy as np

from app.default_lights import safe_default_lights
from app.progress import Progress
from app.raycast import RayCaster
from app.scene import Scene
from app.spawn import SpawnResult, interior_spawn, safe_find_spawn

log = logging.getLogger(__name__)

# Beyond this distance from the origin (in metres) float32 spacing reaches a tenth of a
# millimetre, so the model is re-centred.
RECENTRE_BEYOND_M = 2048.0

# Plausible for a person (auto units): head room above the spawn up to this (a cathedral's nave
# is 30 m; a room in centimetres read as metres is 250 m and more), a whole model between these.
MAX_PLAUSIBLE_HEAD_ROOM_M = 40.0
MIN_PLAUSIBLE_MODEL_M = 0.5
MAX_PLAUSIBLE_MODEL_M = 2000.0
# A model with no room in metres this large is tried in these units (an interior found at one of
# them with a person's ceiling is what the file most likely meant).
_TRY_UNITS_BEYOND_M = 50.0
_UNITS = ((0.01, "centimetres"), (0.0254, "inches"), (0.001, "millimetres"), (0.3048, "feet"))
_ROOM_HEAD_ROOM_M = (2.0, 8.0)  # the head room a room in the right units has
_UNPLACEABLE = 1e15  # file units: larger coordinates are broken vertices, not a far model
_CAMERA_FLOOR_M = 3.0  # the floor under a file's camera: the first surface facing up this near


def place(scene: Scene, unit_scale: float | None) -> Scene:
    """``scene`` scaled to metres (``None``: the file's units are metres) and re-centred if far."""
    scale = 1.0 if unit_scale is None else float(unit_scale)
    # Vertices beyond float32's reach (a stray 1e300) cannot be kept anyway: Scene.sanitized
    # drops their triangles, so they must not drag the centre away from everything else.
    finite = [
        np.asarray(m.positions, np.float64)[
            (np.isfinite(m.positions) & (np.abs(m.positions) < _UNPLACEABLE)).all(axis=1)
        ]
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
    lights = []
    for light in scene.lights:
        x, y, z = (float(v) for v in np.asarray(light.position) * scale - offset)
        # kind, direction, cone and shadows kept
        lights.append(replace(light, position=(x, y, z), range_m=light.range_m * scale))
    cameras = []
    for name, view in scene.cameras:  # the file's cameras move with the model
        x, y, z = (float(v) for v in np.asarray(view.position) * scale - offset)
        cameras.append((name, replace(view, position=(x, y, z))))
    warnings = list(scene.warnings)
    if offset.any():
        dx, dy, dz = (0.0 - float(v) for v in offset)
        warnings.append(
            f"the model lies far from the origin: moved by ({dx:.1f}, {dy:.1f}, {dz:.1f}) m "
            "to keep its precision"
        )
    return replace(
        scene,
        meshes=meshes,
        lights=lights,
        unit_scale=scale,
        cameras=cameras,
        origin_offset=(float(offset[0]), float(offset[1]), float(offset[2])),
        warnings=warnings,
    )


def finish_scene(
    scene: Scene, auto_units: bool, progress: Progress | None = None, any_up: bool = False
) -> Scene:
    """Find where to stand, light a file without lights and check the units; never raises.

    ``scene`` is placed and sanitized; ``auto_units``: the units were not set (scene.unit_scale
    "auto"), so an implausible size is worth a warning saying what was assumed; ``any_up``:
    the file does not say which way is up (OBJ, PLY), so a model with no room to stand in
    that has one with its Z axis up is turned upright (:func:`z_up_turned`).
    """
    progress = progress or Progress()
    caster = RayCaster(scene.triangles(), np.arange(scene.triangle_count))
    spawn, notes = safe_find_spawn(scene, caster)
    storey = _ROOM_HEAD_ROOM_M
    if any_up and not (spawn.floor_y is not None and storey[0] <= spawn.head_room <= storey[1]):
        turned = z_up_turned(scene, spawn)
        if turned is not None:  # the search's room, found on the turned triangles
            scene, caster, spawn = turned
            notes = [
                "the model was lying on its side (modelled with Z up, as 3ds Max, Rhino or a "
                "scanner may save it): turned upright"
            ]
    notes = list(scene.warnings) + notes
    spawn = authored_spawn(scene, spawn, caster, notes)
    lights = scene.lights
    added = not lights
    if added:
        progress.report(0.95, "Adding lights")
        lights, light_notes = safe_default_lights(scene, spawn, caster)
        notes += light_notes
        notes.append(
            f"the file has no lights: added {len(lights)} default point "
            f"light{'s' if len(lights) != 1 else ''} so the scene is visible"
        )
    if auto_units:
        try:
            note = unit_warning(scene, spawn, caster)
        except Exception:  # noqa: BLE001 - a check must not stop a load
            log.exception("the units check failed on %s", scene.name)
            note = None
        if note:
            notes.append(note)
    if spawn.floor_y is None:
        log.info("%s: no interior found, viewing it from outside", scene.name)
    # The geometry was sanitized before the search: only what it added is checked again, and
    # the caster stays with the scene, so the session reuses it (one embree build per load).
    return replace(
        scene,
        spawn=spawn.viewpoint,
        floor_y=spawn.floor_y,
        lights=lights,
        lights_added=added or scene.lights_added,
        warnings=notes,
        ray_caster=caster,
    ).sanitized(geometry=False)


def authored_spawn(
    scene: Scene, found: SpawnResult, caster: RayCaster, notes: list[str]
) -> SpawnResult:
    """Where the viewer starts: the file's first camera (``scene.cameras``: the views its
    author saved) when it lies near the model, else the spawn search's ``found``. The floor
    under the camera is the first surface within 3 m below it (either way round: real files'
    floors are often wound upside down), else the search's."""
    if not scene.cameras:
        return found
    view = scene.cameras[0][1]
    p = np.asarray(view.position, np.float64)
    lo, hi = (np.asarray(b, np.float64) for b in scene.bounds())
    margin = max(float(np.linalg.norm(hi - lo)), 1.0)  # a camera framing the whole model
    if not (np.isfinite(p).all() and (p > lo - margin).all() and (p < hi + margin).all()):
        notes.append("the file's camera is far from the model: starting where one would stand")
        return found
    down, _ = caster.cast(p, (0.0, -1.0, 0.0), _CAMERA_FLOOR_M)
    floor = float(p[1] - down) if math.isfinite(down) else found.floor_y
    return replace(found, viewpoint=view, floor_y=floor)


def z_up_turned(scene: Scene, found: SpawnResult) -> tuple[Scene, RayCaster, SpawnResult] | None:
    """``scene`` turned from Z up to Y up (x, y, z -> x, z, -y: normals, tangents and lights
    alike) with its caster and the room found in it, when it holds a room a person stands in
    that way (a floor with head room of a storey, as the units check asks) and at least as
    much floor as the room ``found`` Y up, if any (a room read on its side stands on a wall,
    9 or 12 m high); else None. The turn only swaps and negates coordinates, so the turned
    scene's triangles are those the caster was built from."""
    turn = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])  # rows: new x, y, z
    try:
        tris = (scene.triangles().astype(np.float64) @ turn.T).astype(np.float32)
        caster = RayCaster(tris, np.arange(len(tris)))
        room = interior_spawn(tris, caster)
    except Exception:  # noqa: BLE001 - a guess must not stop a load
        log.exception("the Z-up check failed on %s", scene.name)
        return None
    lo_h, hi_h = _ROOM_HEAD_ROOM_M
    if room is None or not lo_h <= room.head_room <= hi_h:
        return None
    if found.floor_y is not None and _floor_area(room) < _floor_area(found):
        return None
    meshes = []
    for m in scene.meshes:
        tangents = m.tangents
        if tangents is not None:
            tangents = np.asarray(tangents, np.float32).copy()
            tangents[:, :3] = tangents[:, :3] @ turn.T
        meshes.append(
            replace(
                m,
                positions=(np.asarray(m.positions, np.float64) @ turn.T).astype(np.float32),
                normals=(np.asarray(m.normals, np.float64) @ turn.T).astype(np.float32),
                tangents=tangents,
                lod=None,
            )
        )

    def turned3(v) -> tuple[float, float, float]:
        x, y, z = (float(c) for c in turn @ np.asarray(v, np.float64))
        return x, y, z

    lights = [
        replace(lt, position=turned3(lt.position), direction=turned3(lt.direction))
        for lt in scene.lights
    ]
    turned = replace(scene, meshes=meshes, lights=lights, ray_caster=None, ambient_probe=None)
    return turned, caster, room


def _floor_area(found: SpawnResult) -> float:
    """The walkable floor a spawn search found (its level's points times their cell)."""
    return len(found.level_points) * float(found.cell_area)


def unit_warning(scene: Scene, spawn: SpawnResult, caster: RayCaster | None = None) -> str | None:
    """A sentence when the model, taken as metres, is implausible for a person, else None.

    ``caster``: built from ``scene.triangles()`` (built here when needed and not given).
    """
    assumed = "the file's units were taken as metres"
    ceiling = None
    if spawn.floor_y is not None:
        head = spawn.head_room
        if not (math.isfinite(head) and head > MAX_PLAUSIBLE_HEAD_ROOM_M):
            return None  # a room a person fits in: whatever the rest of the file holds
        ceiling = f"the room's ceiling is {head:.0f} m high: {assumed}"
        unit = _unit_for(head, _ROOM_HEAD_ROOM_M)
        if unit is not None:
            return ceiling + _advice(unit)
    lo, hi = (np.asarray(b, np.float64) for b in scene.bounds())
    size = float(np.max(hi - lo))
    if not math.isfinite(size) or size <= 0.0:
        return None
    if ceiling is None and size > _TRY_UNITS_BEYOND_M:
        tris = scene.triangles().astype(np.float64)
        base = caster if caster is not None else RayCaster(tris)
        for factor, name in _UNITS:
            room = interior_spawn(tris * factor, _ScaledCaster(base, factor))
            lo_h, hi_h = _ROOM_HEAD_ROOM_M
            if room is not None and lo_h <= room.head_room <= hi_h:
                return (
                    f"no room to stand in was found with {assumed}; read as {name} it is "
                    f"a room {room.head_room:.1f} m high" + _advice((factor, name))
                )
    if size > MAX_PLAUSIBLE_MODEL_M:
        unit = _unit_for(size, (1.0, 500.0))
        return f"the model is {size / 1000.0:.0f} km across: {assumed}" + _advice(unit)
    if size < MIN_PLAUSIBLE_MODEL_M:
        return (
            f"the model is only {size * 100.0:.1f} cm across: {assumed}; if it is a room or "
            "a building, its units are larger: set scene.unit_scale to the metres per unit"
        )
    return None if ceiling is None else ceiling + _advice(None)


class _ScaledCaster(RayCaster):
    """``base``'s scene scaled by ``factor`` about the origin, without building another BVH."""

    def __init__(self, base: RayCaster, factor: float) -> None:  # shares base: no super()
        self.base = base
        self.factor = float(factor)
        self._tri32 = base._tri32
        self._tri64 = None
        self._dropped = base._dropped
        self.source_index = base.source_index
        self.owner = base.owner
        self._embree = None

    def cast_triangles(
        self, origins, directions, t_max: float = math.inf
    ) -> tuple[np.ndarray, np.ndarray]:
        o = np.asarray(origins, np.float64) / self.factor
        dist, tri = self.base.cast_triangles(o, directions, t_max / self.factor)
        return dist * self.factor, tri


def _unit_for(length: float, plausible: tuple[float, float]) -> tuple[float, str] | None:
    """The first of the usual units that brings ``length`` into the plausible range."""
    for factor, name in _UNITS:
        if plausible[0] <= length * factor <= plausible[1]:
            return factor, name
    return None


def _advice(unit: tuple[float, str] | None) -> str:
    if unit is None:
        return "; set scene.unit_scale to the metres per file unit"
    factor, name = unit
    return f"; if it was modelled in {name}, set scene.unit_scale to {factor:g}"
