"""glTF 2.0 files: the JSON document, and what trimesh drops from it (lights, scene options).

:mod:`app.loaders` calls :func:`read_gltf_json` first so a truncated or non-glTF file gets a
message naming the problem, then reads the geometry.
"""

from __future__ import annotations

import json
import math
import struct
from pathlib import Path
from typing import Any

import numpy as np

from app.errors import SceneLoadError
from app.scene import PointLight
from app.scene_builder import float_list, float_or

_GLB_MAGIC = b"glTF"
_GLB_JSON_CHUNK = 0x4E4F534A


def read_gltf_json(path: Path) -> dict[str, Any]:
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


def gltf_wants_indirect(doc: dict[str, Any] | None) -> bool:
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
# glTF lights (KHR_lights_punctual)
# --------------------------------------------------------------------------------------------


def gltf_lights(doc: dict[str, Any], warnings: list[str]) -> list[PointLight]:
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
