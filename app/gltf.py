"""glTF 2.0 files: the JSON document and GLB chunks, the node graph, lights and scene options.

:func:`read_gltf_file` refuses what makes a whole file unreadable (a damaged GLB, JSON nested too
deeply, a newer glTF, a required extension we cannot read) with a message naming the problem;
:mod:`app.gltf_reader` builds the geometry from what it returns. The node walk is iterative and
cuts cycles, so the lights here and the meshes there see the same world matrices.
"""

from __future__ import annotations

import json
import math
import re
import struct
from pathlib import Path
from typing import Any

import numpy as np

from app.errors import SceneLoadError
from app.gltf_accessors import Blob, as_dict, as_list, is_int
from app.scene import PointLight, Viewpoint
from app.scene_builder import float_list, float_or

_GLB_MAGIC = b"glTF"
_GLB_JSON_CHUNK = 0x4E4F534A
_GLB_BIN_CHUNK = 0x004E4942

# Extensions whose content this viewer reads (or safely approximates, with a warning), so a file
# that requires them can be opened. Anything else a file requires is refused by name.
SUPPORTED_REQUIRED_EXTENSIONS = frozenset(
    {
        "KHR_draco_mesh_compression",
        "KHR_materials_emissive_strength",
        "KHR_texture_transform",
        "KHR_lights_punctual",
        "KHR_materials_pbrSpecularGlossiness",
        "KHR_mesh_quantization",
        "KHR_materials_unlit",
        "KHR_materials_transmission",
        "EXT_texture_webp",  # Blender's "WebP" image format: Pillow decodes it
        "EXT_meshopt_compression",  # gltfpack, glTF-Transform: meshoptimizer decodes it
    }
)


def read_gltf_json(path: Path) -> dict[str, Any]:
    """The glTF JSON document (see :func:`read_gltf_file`)."""
    return read_gltf_file(path)[0]


def read_gltf_file(path: Path) -> tuple[dict[str, Any], Blob | None]:
    """The glTF JSON document and, for a GLB, its BIN chunk (buffer 0 when it has no uri).

    Everything that makes the whole file unreadable is refused here with a message naming the
    problem: a truncated or non-glTF file, damaged GLB chunks, JSON nested too deeply to be a
    model, a glTF version other than 2.x, or a required extension this viewer cannot read.
    """
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise SceneLoadError(f"Cannot read '{path.name}': {exc.strerror or exc}.") from exc
    binary: Blob | None = None
    if path.suffix.lower() == ".glb":
        text, binary = _glb_chunks(path, data)
    else:
        text = data
    doc = _parse_json(path, text)
    _check_asset(path, doc)
    _check_required_extensions(path, doc)
    return doc, binary


def _glb_chunks(path: Path, data: bytes) -> tuple[bytes, Blob | None]:
    """The JSON chunk and the first BIN chunk, every length checked against the file."""
    if len(data) < 20 or data[:4] != _GLB_MAGIC:
        raise SceneLoadError(
            f"Cannot read '{path.name}': it is not a binary glTF (.glb) "
            "file (the glTF header is missing or damaged)."
        )
    version, total = struct.unpack_from("<II", data, 4)
    if version != 2:
        raise SceneLoadError(
            f"Cannot read '{path.name}': only glTF 2.0 is supported "
            f"(this file says version {version})."
        )
    truncated = SceneLoadError(
        f"Cannot read '{path.name}': the file is truncated or damaged "
        "(its JSON chunk is missing or cut short)."
    )
    chunk_len, chunk_type = struct.unpack_from("<II", data, 12)
    if chunk_type != _GLB_JSON_CHUNK or 20 + chunk_len > len(data):
        raise truncated
    end = min(total, len(data)) if total >= 20 else len(data)
    text = data[20 : 20 + chunk_len]
    pos = 20 + chunk_len
    pos += (-pos) % 4  # chunks start 4-byte aligned (writers pad, a few forget)
    binary: Blob | None = None
    while pos + 8 <= end:
        length, kind = struct.unpack_from("<II", data, pos)
        if pos + 8 + length > len(data):
            raise SceneLoadError(
                f"Cannot read '{path.name}': the file is truncated "
                f"(a chunk claims {length} bytes, the file ends {len(data) - pos - 8} bytes later)."
            )
        if kind == _GLB_BIN_CHUNK and binary is None:
            binary = memoryview(data)[pos + 8 : pos + 8 + length]  # no copy of a large BIN
        pos += 8 + length
        pos += (-pos) % 4
    return text, binary


def _parse_json(path: Path, text: bytes) -> dict[str, Any]:
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
    except RecursionError as exc:
        raise SceneLoadError(
            f"Cannot read '{path.name}': its JSON is nested too deeply to be a real model."
        ) from exc
    if not isinstance(doc, dict):
        raise SceneLoadError(f"Cannot read '{path.name}': it is JSON but not a glTF document.")
    return doc


def _check_asset(path: Path, doc: dict[str, Any]) -> None:
    asset = as_dict(doc.get("asset"))
    version = str(asset.get("version", "2.0"))
    if not re.fullmatch(r"2(\.\d+)?", version.strip()):
        raise SceneLoadError(
            f"Cannot read '{path.name}': only glTF 2.0 is supported "
            f"(this file says version {version})."
        )
    min_version = asset.get("minVersion")
    if min_version is not None:
        match = re.fullmatch(r"(\d+)\.(\d+)", str(min_version).strip())
        if match is None or (int(match.group(1)), int(match.group(2))) > (2, 0):
            raise SceneLoadError(
                f"Cannot open '{path.name}': it needs glTF {min_version}, newer than the "
                "glTF 2.0 this viewer reads."
            )


def _check_required_extensions(path: Path, doc: dict[str, Any]) -> None:
    required = doc.get("extensionsRequired") or []
    if not isinstance(required, list):
        return
    for name in required:
        if str(name) not in SUPPORTED_REQUIRED_EXTENSIONS:
            raise SceneLoadError(
                f"Cannot open '{path.name}': it requires the glTF extension {name}, "
                "which this viewer cannot read."
            )


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
    """Point, spot and directional lights at their node's world position and orientation.

    glTF point and spot intensity is in candela and a directional light's in lux, which is what
    ``Light.intensity`` means for each kind. A spot and a directional light shine along their
    node's -Z; a spot's cone angles are glTF's half angles (defaults 0 and 45 degrees). A glTF
    light without a range reaches everything; ours must stop somewhere, so it stops where it has
    fallen to 1/1000 of its value at 1 m (a directional light has no range).
    """
    ext = (doc.get("extensions") or {}).get("KHR_lights_punctual") or {}
    defs = ext.get("lights") or []
    if not defs:
        return []
    world = _gltf_world_matrices(doc)
    nodes = doc.get("nodes") or []
    lights: list[PointLight] = []
    skipped: dict[str, int] = {}
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
        if not isinstance(spec, dict):
            warnings.append(f"node {i}: light {ref} is not a light description, ignored")
            continue
        kind = str(spec.get("type", "point"))
        if kind not in ("point", "spot", "directional"):
            skipped[kind] = skipped.get(kind, 0) + 1
            continue
        color = float_list(spec.get("color"), 3, 1.0)
        intensity = float_or(spec.get("intensity"), 1.0)
        rng = float_or(spec.get("range"), 0.0)
        if rng <= 0.0:
            rng = math.sqrt(max(intensity, 0.0) * 1000.0) + 1.0
        pos = matrix[:3, 3]
        axis = -np.asarray(matrix[:3, 2], np.float64)  # the node's -Z in world axes
        norm = float(np.linalg.norm(axis))
        if not (norm > 1e-12 and math.isfinite(norm)):
            warnings.append(f"node {i}: light has no direction (a zero scale), points down")
            axis, norm = np.array([0.0, -1.0, 0.0]), 1.0
        axis = axis / norm
        inner, outer = 0.0, 45.0
        if kind == "spot":
            cone = as_dict(spec.get("spot"))
            outer = math.degrees(float_or(cone.get("outerConeAngle"), math.pi / 4))
            inner = math.degrees(float_or(cone.get("innerConeAngle"), 0.0))
            if not 0.0 < outer <= 90.0 or not 0.0 <= inner < outer:
                warnings.append(
                    f"node {i}: spot cone {inner:.1f} to {outer:.1f} degrees is outside glTF's "
                    "rules (0 <= inner < outer <= 90), clamped"
                )
                outer = min(max(outer, 0.1), 90.0)
                inner = min(max(inner, 0.0), outer * 0.999)
        lights.append(
            PointLight(
                (float(pos[0]), float(pos[1]), float(pos[2])),
                (color[0], color[1], color[2]),
                intensity,
                rng,
                kind=kind,
                direction=(float(axis[0]), float(axis[1]), float(axis[2])),
                inner_cone_deg=inner,
                outer_cone_deg=outer,
            )
        )
    for kind, count in skipped.items():
        warnings.append(f"{count} {kind} light{'s' if count != 1 else ''} not supported, ignored")
    return lights


def gltf_camera_views(doc: dict[str, Any], warnings: list[str]) -> list[tuple[str, Viewpoint]]:
    """The views of the file's camera nodes (those a designer saved in Blender or SketchUp),
    named after the node (else the camera, else "Camera N"), in the node walk's order: the
    position, and the yaw and pitch each looks with (a camera looks down its own -Z; roll is
    dropped, the viewer stays upright). One with no usable position or direction is left
    out with a warning."""
    cameras = as_list(doc.get("cameras"))
    nodes = as_list(doc.get("nodes"))
    out: list[tuple[str, Viewpoint]] = []
    for index, matrix in gltf_node_walk(doc, []):
        node = as_dict(nodes[index])
        cam = node.get("camera")
        if not (is_int(cam) and 0 <= cam < len(cameras)):
            continue
        name = str(node.get("name") or as_dict(cameras[cam]).get("name") or "")
        name = name or f"Camera {len(out) + 1}"
        position = matrix[:3, 3]
        forward = -matrix[:3, 2]
        length = float(np.linalg.norm(forward))
        if not (np.isfinite(position).all() and np.isfinite(forward).all() and length > 1e-9):
            warnings.append(f"the file's camera '{name:.60}' has no usable position or direction")
            continue
        fx, fy, fz = forward / length
        yaw = math.degrees(math.atan2(-fx, -fz)) if abs(fy) < 1.0 - 1e-9 else 0.0
        pitch = math.degrees(math.asin(max(-1.0, min(1.0, fy))))
        x, y, z = (float(v) for v in position)
        out.append((name, Viewpoint((x, y, z), yaw, pitch)))
    return out


def _gltf_world_matrices(doc: dict[str, Any]) -> dict[int, np.ndarray]:
    """World matrix of every node reachable from the default scene (cycles are cut)."""
    return {node: matrix for node, matrix in gltf_node_walk(doc, [])}


def gltf_root_nodes(doc: dict[str, Any]) -> list[int]:
    """The default scene's root nodes; every parentless node when the scene is missing or bad."""
    nodes = as_list(doc.get("nodes"))
    scenes = doc.get("scenes")
    index = doc.get("scene", 0)
    if isinstance(scenes, list) and isinstance(index, int) and 0 <= index < len(scenes):
        scene = scenes[index]
        roots = scene.get("nodes") if isinstance(scene, dict) else None
        if isinstance(roots, list):
            return [r for r in roots if isinstance(r, int) and 0 <= r < len(nodes)]
    children = {
        c for n in nodes if isinstance(n, dict) for c in (n.get("children") or []) if is_int(c)
    }
    return [i for i in range(len(nodes)) if i not in children]


def gltf_node_walk(doc: dict[str, Any], warnings: list[str]) -> list[tuple[int, np.ndarray]]:
    """(node, world matrix) in depth-first order, children in file order.

    Iterative, so a 10,000-deep hierarchy is no problem; a node reached a second time (a cycle,
    or a child with two parents, both invalid glTF) is skipped with one warning.
    """
    nodes = as_list(doc.get("nodes"))
    seen: set[int] = set()
    cut = 0
    out: list[tuple[int, np.ndarray]] = []
    stack = [(r, np.eye(4)) for r in reversed(gltf_root_nodes(doc))]
    while stack:
        i, parent = stack.pop()
        if i in seen:
            cut += 1
            continue
        seen.add(i)
        node = as_dict(nodes[i])
        m = parent @ _gltf_local_matrix(node)
        out.append((i, m))
        children = node.get("children") or []
        for c in reversed(children if isinstance(children, list) else []):
            if is_int(c) and 0 <= c < len(nodes):
                stack.append((c, m))
    if cut:
        warnings.append(
            f"node graph: {cut} node reference{'s' if cut != 1 else ''} forming a cycle or "
            "giving a node a second parent ignored"
        )
    return out


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
