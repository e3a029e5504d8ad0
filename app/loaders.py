"""Turn a glTF, GLB, OBJ or PLY file into a :class:`~app.scene.Scene` you can stand inside.

trimesh does the parsing; this module decides what the result means for a walkable VR preview:
node transforms are baked so every mesh is in world space (Y up, metres), materials become linear
colours plus de-duplicated RGBA8 textures, and the viewer is placed where a person would stand.
This module reads the files and the glTF extras trimesh drops (samplers, lights, scene options);
:mod:`app.scene_builder` turns trimesh's scene into ours, :mod:`app.spawn` finds where to stand
(on the main floor at eye height, facing down the longest free direction; outside a lone object)
and :mod:`app.default_lights` lights a file without lights so the first frame is never black.

Texture-coordinate contract (the renderer relies on it): ``Texture.rgba`` row 0 is the top row of
the image, and a mesh's ``uv`` follows OpenGL's bottom-left origin, i.e. ``v = 1`` is the top image
row and ``v = 1 - row / height``. trimesh already flips glTF's top-left ``v`` into this convention
and OBJ ``vt`` is authored in it, so uvs pass through unchanged (values outside [0, 1] included:
they mean repeat wrapping). A renderer that uploads row 0 first must therefore sample at
``(u, 1 - v)`` or upload the rows bottom-up.

Every problem the user can fix (missing file, unsupported type, damaged data, no triangles)
raises :class:`SceneLoadError` with the file name in the message; problems that still leave
something to look at (a missing texture, NaN vertices, an unsupported light type) load anyway and
are listed in ``Scene.warnings``.
"""

from __future__ import annotations

import json
import logging
import math
import os
import struct
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from app.default_lights import default_lights
from app.raycast import RayCaster
from app.scene import PointLight, Scene
from app.scene_builder import SceneBuilder, float_list, float_or
from app.spawn import find_spawn

log = logging.getLogger(__name__)

SUPPORTED_EXTENSIONS = (".gltf", ".glb", ".obj", ".ply")

_GLB_MAGIC = b"glTF"
_GLB_JSON_CHUNK = 0x4E4F534A


class SceneLoadError(Exception):
    """A file that cannot become a scene; the message is meant for the person who picked it."""


# --------------------------------------------------------------------------------------------
# public entry point
# --------------------------------------------------------------------------------------------


def load_scene(path: str | os.PathLike[str]) -> Scene:
    """Load ``path`` into a sanitized Scene with spawn, floor height and lights filled in.

    Raises :class:`SceneLoadError` for anything that leaves nothing to show, so callers can show
    the message to the user as it is.
    """
    p = Path(path)
    if not p.exists():
        raise SceneLoadError(f"Cannot open '{p}': the file does not exist.")
    if not p.is_file():
        raise SceneLoadError(f"Cannot open '{p}': it is a folder, not a scene file.")
    ext = p.suffix.lower()
    if ext not in SUPPORTED_EXTENSIONS:
        kind = f"'{ext}' files are" if ext else "files without an extension are"
        raise SceneLoadError(
            f"Cannot open '{p.name}': {kind} not supported "
            f"(supported: {', '.join(SUPPORTED_EXTENSIONS)})."
        )

    warnings: list[str] = []
    gltf_doc = _read_gltf_json(p) if ext in (".gltf", ".glb") else None
    tm_scene = _trimesh_load(p)
    builder = SceneBuilder(p, gltf_doc, warnings)
    builder.add_trimesh_scene(tm_scene)
    if ext == ".obj":
        builder.warn_missing_obj_textures()
    lights = _gltf_lights(gltf_doc, warnings) if gltf_doc is not None else []

    raw = Scene(
        name=p.stem,
        meshes=builder.meshes,
        materials=builder.materials,
        textures=builder.textures,
        lights=lights,
        source=str(path),
        warnings=warnings,
    )
    if raw.triangle_count == 0:
        raise SceneLoadError(
            f"Cannot show '{p.name}': it contains no triangles "
            "(it is empty, or holds only points or lines)."
        )
    scene = raw.sanitized()
    if not scene.meshes:
        raise SceneLoadError(
            f"Cannot show '{p.name}': none of its triangles are valid "
            "(every vertex position is broken or every triangle is flat)."
        )

    caster = RayCaster(scene.triangles(), np.arange(scene.triangle_count))
    spawn = find_spawn(scene, caster)
    notes = list(scene.warnings)
    lights = scene.lights
    if not lights:
        lights = default_lights(scene, spawn, caster)
        notes.append(
            f"the file has no lights: added {len(lights)} default point "
            f"light{'s' if len(lights) != 1 else ''} so the scene is visible"
        )
    if spawn.floor_y is None:
        log.info("%s: no interior found, viewing it from outside", p.name)
    return replace(
        scene,
        spawn=spawn.viewpoint,
        floor_y=spawn.floor_y,
        lights=lights,
        warnings=notes,
        indirect=_gltf_wants_indirect(gltf_doc),
    ).sanitized()


def _gltf_wants_indirect(doc: dict[str, Any] | None) -> bool:
    """The scene option for photon-mapped indirect light: ``"extras": {"vrpreview":
    {"indirect": true}}`` on the glTF document or on its default scene."""
    if not isinstance(doc, dict):
        return False
    holders = [doc]
    scenes = doc.get("scenes")
    index = doc.get("scene", 0)
    if isinstance(scenes, list) and isinstance(index, int) and 0 <= index < len(scenes):
        holders.append(scenes[index])
    for holder in holders:
        extras = holder.get("extras") if isinstance(holder, dict) else None
        options = extras.get("vrpreview") if isinstance(extras, dict) else None
        if isinstance(options, dict) and options.get("indirect") is True:
            return True
    return False


# --------------------------------------------------------------------------------------------
# reading files
# --------------------------------------------------------------------------------------------


def _read_gltf_json(path: Path) -> dict[str, Any]:
    """The glTF JSON document, read by us because trimesh drops samplers and lights.

    Reading it first also turns a truncated or non-glTF file into a message that names the
    problem instead of whatever trimesh trips over later.
    """
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise SceneLoadError(f"Cannot read '{path.name}': {exc.strerror or exc}.") from exc
    if path.suffix.lower() == ".glb":
        if len(data) < 20 or data[:4] != _GLB_MAGIC:
            raise SceneLoadError(
                f"Cannot read '{path.name}': it is not a binary glTF (.glb) "
                "file (the glTF header is missing or damaged)."
            )
        version = struct.unpack_from("<I", data, 4)[0]
        if version != 2:
            raise SceneLoadError(
                f"Cannot read '{path.name}': only glTF 2.0 is supported "
                f"(this file says version {version})."
            )
        chunk_len, chunk_type = struct.unpack_from("<II", data, 12)
        if chunk_type != _GLB_JSON_CHUNK or 20 + chunk_len > len(data):
            raise SceneLoadError(
                f"Cannot read '{path.name}': the file is truncated or damaged "
                "(its JSON chunk is missing or cut short)."
            )
        text = data[20 : 20 + chunk_len]
    else:
        text = data
    try:
        doc = json.loads(text.decode("utf-8-sig"))
    except UnicodeDecodeError as exc:
        raise SceneLoadError(
            f"Cannot read '{path.name}': it is not a glTF file "
            "(the content is not UTF-8 JSON text)."
        ) from exc
    except json.JSONDecodeError as exc:
        raise SceneLoadError(
            f"Cannot read '{path.name}': its glTF JSON is invalid or truncated "
            f"({exc.msg} at line {exc.lineno}, column {exc.colno})."
        ) from exc
    if not isinstance(doc, dict):
        raise SceneLoadError(f"Cannot read '{path.name}': it is JSON but not a glTF document.")
    version = (
        str(doc.get("asset", {}).get("version", "2.0"))
        if isinstance(doc.get("asset"), dict)
        else "2.0"
    )
    if not version.startswith("2"):
        raise SceneLoadError(
            f"Cannot read '{path.name}': only glTF 2.0 is supported "
            f"(this file says version {version})."
        )
    return doc


def _trimesh_load(path: Path) -> Any:
    """trimesh's scene, with every parser failure turned into a message for the user.

    ``process=False`` keeps the data as authored: trimesh would otherwise merge vertices and
    silently drop NaN ones, and :meth:`Scene.sanitized` is where repairs are made and reported.
    """
    import trimesh

    try:
        return trimesh.load_scene(str(path), process=False)
    except FileNotFoundError as exc:
        missing = Path(exc.filename).name if exc.filename else str(exc)
        raise SceneLoadError(
            f"Cannot read '{path.name}': a file it needs is missing ({missing})."
        ) from exc
    except MemoryError as exc:
        raise SceneLoadError(
            f"Cannot read '{path.name}': it is too large for the available memory."
        ) from exc
    except Exception as exc:  # noqa: BLE001 - parsers raise anything on damaged input
        detail = str(exc).strip() or type(exc).__name__
        if isinstance(exc, (ImportError, UnicodeDecodeError)):
            # trimesh reaches for an optional text-encoding detector on undecodable bytes.
            detail = "its content is not readable text"
        if len(detail) > 200:
            detail = detail[:200] + "..."
        raise SceneLoadError(
            f"Cannot read '{path.name}': the file is damaged or not a valid "
            f"{path.suffix.lower().lstrip('.').upper()} file ({detail})."
        ) from exc


# --------------------------------------------------------------------------------------------
# glTF lights (KHR_lights_punctual)
# --------------------------------------------------------------------------------------------


def _gltf_lights(doc: dict[str, Any], warnings: list[str]) -> list[PointLight]:
    """Point and spot lights as point lights at their node's world position.

    glTF point intensity is in candela, which is what ``PointLight.intensity`` means (radiance
    scale at 1 m). A glTF light without a range reaches everything; ours must stop somewhere, so
    it stops where it has fallen to 1/1000 of its value at 1 m.
    """
    ext = (doc.get("extensions") or {}).get("KHR_lights_punctual") or {}
    defs = ext.get("lights") or []
    if not defs:
        return []
    world = _gltf_world_matrices(doc)
    nodes = doc.get("nodes") or []
    lights: list[PointLight] = []
    skipped: dict[str, int] = {}
    spots = 0
    for i, matrix in world.items():
        node = nodes[i]
        ref = ((node.get("extensions") or {}).get("KHR_lights_punctual") or {}).get("light")
        if ref is None:
            continue
        try:
            spec = defs[int(ref)]
        except (IndexError, TypeError, ValueError):
            warnings.append(f"node {i}: refers to light {ref}, which does not exist")
            continue
        kind = str(spec.get("type", "point"))
        if kind not in ("point", "spot"):
            skipped[kind] = skipped.get(kind, 0) + 1
            continue
        spots += kind == "spot"
        color = float_list(spec.get("color"), 3, 1.0)
        intensity = float_or(spec.get("intensity"), 1.0)
        rng = float_or(spec.get("range"), 0.0)
        if rng <= 0.0:
            rng = math.sqrt(max(intensity, 0.0) * 1000.0) + 1.0
        pos = matrix[:3, 3]
        lights.append(
            PointLight(
                (float(pos[0]), float(pos[1]), float(pos[2])),
                (color[0], color[1], color[2]),
                intensity,
                rng,
            )
        )
    if spots:
        warnings.append(
            f"{spots} spot light{'s are' if spots != 1 else ' is'} shown as a point light (no cone)"
        )
    for kind, count in skipped.items():
        warnings.append(f"{count} {kind} light{'s' if count != 1 else ''} not supported, ignored")
    return lights


def _gltf_world_matrices(doc: dict[str, Any]) -> dict[int, np.ndarray]:
    """World matrix of every node reachable from the default scene (cycles are cut)."""
    nodes = doc.get("nodes") or []
    scenes = doc.get("scenes") or []
    try:
        roots = list(scenes[int(doc.get("scene", 0))].get("nodes", []))
    except (IndexError, TypeError, ValueError, AttributeError):
        children = {c for n in nodes for c in (n.get("children") or [])}
        roots = [i for i in range(len(nodes)) if i not in children]
    world: dict[int, np.ndarray] = {}
    stack = [(int(r), np.eye(4)) for r in roots if isinstance(r, int) and 0 <= r < len(nodes)]
    while stack:
        i, parent = stack.pop()
        if i in world:
            continue
        m = parent @ _gltf_local_matrix(nodes[i])
        world[i] = m
        for c in nodes[i].get("children") or []:
            if isinstance(c, int) and 0 <= c < len(nodes) and c not in world:
                stack.append((c, m))
    return world


def _gltf_local_matrix(node: dict[str, Any]) -> np.ndarray:
    if "matrix" in node:
        values = float_list(node["matrix"], 16, 0.0)
        return np.asarray(values).reshape(4, 4).T  # glTF stores column-major
    t = float_list(node.get("translation"), 3, 0.0)
    x, y, z, w = (
        float_list(node.get("rotation"), 4, 0.0) if "rotation" in node else (0.0, 0.0, 0.0, 1.0)
    )
    s = float_list(node.get("scale"), 3, 1.0)
    norm = math.sqrt(x * x + y * y + z * z + w * w) or 1.0
    x, y, z, w = x / norm, y / norm, z / norm, w / norm
    rot = np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )
    m = np.eye(4)
    m[:3, :3] = rot * np.asarray(s)[None, :]
    m[:3, 3] = t
    return m
