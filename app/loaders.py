"""Turn a glTF, GLB, OBJ or PLY file into a :class:`~app.scene.Scene` you can stand inside.

glTF and GLB are read by our own reader (:mod:`app.gltf_reader`: accessors decoded with numpy,
validated before allocation, sparse accessors, Draco, required extensions); trimesh parses OBJ and
PLY. Either way node transforms are baked so every mesh is in world space (Y up, metres),
materials become linear colours plus de-duplicated RGBA8 textures, and the viewer is placed where
a person would stand. :mod:`app.scene_builder` turns trimesh's scene into ours, :mod:`app.spawn`
finds where to stand (on the main floor at eye height, facing down the longest free direction;
outside a lone object) and :mod:`app.default_lights` lights a file without lights so the first
frame is never black.

Texture-coordinate contract (the renderer relies on it): ``Texture.rgba`` row 0 is the top row of
the image, and a mesh's ``uv`` follows OpenGL's bottom-left origin, i.e. ``v = 1`` is the top image
row and ``v = 1 - row / height``. The glTF reader flips glTF's top-left ``v`` into this convention
(``v = 1 - v_gltf``) and OBJ ``vt`` is authored in it, so OBJ uvs pass through unchanged
(values outside [0, 1] included: they mean repeat wrapping). A renderer that uploads row 0 first
must therefore sample at ``(u, 1 - v)`` or upload the rows bottom-up.

Loading is staged (read, place, repair, find where to stand, light) and reports progress through
:class:`~app.progress.Progress`, whose cancel flag stops it between steps. :func:`load_scene` is the
boundary: whatever goes wrong inside, the caller gets :class:`SceneLoadError` with the file name
and a plain sentence (the traceback goes to the log), or :class:`~app.progress.LoadCancelled`.

Every problem the user can fix (missing file, unsupported type, damaged data, no triangles)
raises :class:`SceneLoadError` with the file name in the message; problems that still leave
something to look at (a missing texture, NaN vertices, an unsupported light type) load anyway and
are listed in ``Scene.warnings``.
"""

from __future__ import annotations

import logging
import os
from dataclasses import dataclass
from pathlib import Path

from app.errors import SceneLoadError
from app.gltf_reader import read_gltf
from app.lod import attach_lods
from app.placement import finish_scene, place
from app.progress import LoadCancelled, Progress
from app.scene import Scene
from app.scene_builder import SceneBuilder
from app.settings import SceneSettings
from app.tessellate import MAX_EDGE_M, refine_scene
from app.trimesh_files import trimesh_load

log = logging.getLogger(__name__)

SUPPORTED_EXTENSIONS = (".gltf", ".glb", ".obj", ".ply")

__all__ = ["SUPPORTED_EXTENSIONS", "LoadCancelled", "LoadOptions", "SceneLoadError", "load_scene"]


@dataclass(frozen=True)
class LoadOptions:
    """What the ``scene.*`` settings ask of a load."""

    unit_scale: float | None = None  # metres per file unit; None: auto (the file's own units)
    max_texture_px: int = 8192  # longest texture side kept; larger ones are downscaled
    max_memory_mb: int = 8192  # a file needing more than this for geometry and textures is refused
    # Edges longer than this (metres) are split for the per-vertex light (app.tessellate);
    # 0: the file's triangles as they are (the reader's tests count them).
    split_edges_m: float = MAX_EDGE_M

    @classmethod
    def from_settings(cls, s: SceneSettings) -> LoadOptions:
        scale = None if s.unit_scale == "auto" else float(s.unit_scale)
        return cls(scale, int(s.max_texture_px), int(s.max_memory_mb))


# --------------------------------------------------------------------------------------------
# public entry point
# --------------------------------------------------------------------------------------------


def load_scene(
    path: str | os.PathLike[str],
    options: LoadOptions | None = None,
    progress: Progress | None = None,
) -> Scene:
    """Load ``path`` into a sanitized Scene with spawn, floor height and lights filled in.

    Raises :class:`SceneLoadError` for anything that leaves nothing to show, with a message to
    show the user as it is, and :class:`LoadCancelled` when ``progress`` was cancelled.
    """
    p = Path(path)
    try:
        return _load(p, options or LoadOptions(), progress or Progress())
    except (SceneLoadError, LoadCancelled):
        raise
    except MemoryError as exc:
        raise SceneLoadError(
            f"Cannot open '{p.name}': it needs more memory than this computer has free."
        ) from exc
    except RecursionError as exc:
        raise SceneLoadError(
            f"Cannot open '{p.name}': its structure is nested too deeply to be a real model."
        ) from exc
    except Exception as exc:  # noqa: BLE001 - the boundary: no loader bug reaches the user raw
        log.exception("loading %s failed", p)
        raise SceneLoadError(
            f"Cannot open '{p.name}': the file could not be read "
            f"(an unexpected {type(exc).__name__}; the details are in the log)."
        ) from exc


def _load(p: Path, options: LoadOptions, progress: Progress) -> Scene:
    _check_path(p)
    progress.report(0.0, f"Reading {p.name}")
    raw = _read(p, options, progress.span(0.0, 0.75))
    if raw.triangle_count == 0:
        raise SceneLoadError(
            f"Cannot show '{p.name}': it contains no triangles "
            "(it is empty, or holds only points or lines)."
        )
    progress.report(0.75, "Checking geometry")
    scene = place(raw, options.unit_scale).sanitized()
    if not scene.meshes:
        raise SceneLoadError(
            f"Cannot show '{p.name}': none of its triangles are valid "
            "(every vertex position is broken or every triangle is flat)."
        )
    if options.split_edges_m > 0:  # a vertex every half metre for the light kept per vertex
        scene = refine_scene(scene, options.split_edges_m)
    progress.report(0.85, "Finding where to stand")
    any_up = p.suffix.lower() not in (".gltf", ".glb")  # glTF is Y up by its definition
    scene = finish_scene(scene, options.unit_scale is None, progress, any_up)
    # Chunks and simplified levels for the renderer (app.lod), from the cache when it has them.
    lod_progress = progress.span(0.95, 1.0)
    attach_lods(scene.meshes, lod_progress.report)
    progress.report(1.0, "Done")
    return scene


def _check_path(p: Path) -> None:
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


def _read(p: Path, options: LoadOptions, progress: Progress) -> Scene:
    """The file as a Scene in world space (node transforms baked), not yet repaired."""
    ext = p.suffix.lower()
    if ext in (".gltf", ".glb"):
        return read_gltf(p, options.max_texture_px, options.max_memory_mb, progress)
    warnings: list[str] = []
    tm_scene = trimesh_load(p, options.max_memory_mb, warnings)
    progress.report(0.6, "Building meshes")
    builder = SceneBuilder(p, None, warnings, options.max_texture_px)
    builder.add_trimesh_scene(tm_scene)
    if ext == ".obj":
        builder.warn_missing_obj_textures()
    return Scene(
        name=p.stem,
        meshes=builder.meshes,
        materials=builder.materials,
        textures=builder.textures,
        lights=[],
        source=str(p),
        warnings=warnings,
        indirect=False,
    )
