"""Scene names the user can type: the built-in scenes, or a path to a model file."""

from __future__ import annotations

import os
import re
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from app.paths import SHOWROOM_STOP, CameraPath, PathKey, builtin_path, showroom_stop
from app.scene import Scene

if TYPE_CHECKING:
    from app.loaders import LoadOptions
    from app.progress import Progress


def _showroom(lights: int, indirect: bool = False) -> Callable[[], Scene]:
    def build() -> Scene:
        from assets.showroom import build_showroom

        scene = build_showroom(lights=lights)
        if indirect:  # this variant asks for photon-mapped indirect light (photons.enabled)
            scene.name = "showroom-gi"
            scene.indirect = True
        return scene

    return build


def _texture_test() -> Scene:
    from assets.showroom import build_texture_test_scene

    return build_texture_test_scene()


def _corridor() -> Scene:
    from assets.corridor import build_corridor

    return build_corridor()


def _tcr_cube() -> Scene:
    from assets.tcr_cube import build_tcr_cube

    return build_tcr_cube()


BUILTIN: dict[str, Callable[[], Scene]] = {
    "showroom": _showroom(4),
    "showroom-8": _showroom(8),  # issue 14's target: 8 shadowed lamps against unshadowed
    "showroom-100": _showroom(100),
    "showroom-gi": _showroom(4, indirect=True),
    "texture-test": _texture_test,
    "tcr-cube": _tcr_cube,
    "corridor": _corridor,
}
BUILTIN_PATHS = {
    "showroom": "showroom_walkthrough",
    "showroom-8": "showroom_walkthrough",
    "showroom-100": "showroom_walkthrough",
    "showroom-gi": "showroom_walkthrough",
    "tcr-cube": "tcr_cube_distance",
    "corridor": "corridor_walk",
}


def _generated_paths() -> dict[str, Callable[[], CameraPath]]:
    from assets import corridor, tcr_cube

    return {
        SHOWROOM_STOP: showroom_stop,
        "tcr_cube_distance": tcr_cube.distance_path,
        "tcr_cube_orbit": tcr_cube.orbit_path,
        "tcr_cube_gaze": tcr_cube.gaze_path,
        "corridor_walk": corridor.corridor_walk,
    }


def resolve_path(name_or_file: str | os.PathLike[str]) -> CameraPath:
    """A built-in path by name (e.g. tcr_cube_orbit, showroom_walkthrough), else a JSON file."""
    key = str(name_or_file)
    generated = _generated_paths()
    if key in generated:
        return generated[key]()
    if not Path(key).suffix and key in BUILTIN_PATHS.values():
        return builtin_path(key)
    return CameraPath.load(key)


def resolve(
    name_or_path: str | os.PathLike[str],
    options: LoadOptions | None = None,
    progress: Progress | None = None,
) -> Scene:
    """A built-in scene by name, else a model file (raises SceneLoadError if unusable)."""
    key = str(name_or_path)
    if key in BUILTIN:
        from app.lod import attach_lods
        from app.tessellate import refine_scene

        scene = BUILTIN[key]()
        refined = refine_scene(scene)  # as a file's: long edges split, and the split meshes
        split = [m for m, o in zip(refined.meshes, scene.meshes, strict=True) if m is not o]
        attach_lods(split)  # get levels (a wall's grid is two triangles again far away)
        return refined
    from app.loaders import load_scene

    return load_scene(Path(key).expanduser(), options, progress)


def default_path(scene: Scene) -> CameraPath:
    """The scene's walkthrough; loaded files get a slow look around from the spawn."""
    if scene.name in BUILTIN_PATHS and scene.source == "built-in":
        return resolve_path(BUILTIN_PATHS[scene.name])
    return look_around(scene)


def look_around(scene: Scene, seconds: float = 6.0) -> CameraPath:
    """Stand at the spawn, turn 30 degrees each way, the gaze sweeping, then hold a fixed gaze."""
    sp = scene.spawn
    yaw, pitch = sp.yaw_deg, sp.pitch_deg
    x, y, z = sp.position
    pos = (float(x), float(y), float(z))
    keys = [
        PathKey(0.0, pos, yaw, pitch, (0.5, 0.5)),
        PathKey(seconds * 0.25, pos, yaw + 30.0, pitch, (0.3, 0.45)),
        PathKey(seconds * 0.5, pos, yaw, pitch, (0.6, 0.5)),
        PathKey(seconds * 0.7, pos, yaw - 30.0, pitch, (0.7, 0.55), True),
        PathKey(seconds, pos, yaw, pitch, (0.5, 0.5), True),
    ]
    return CameraPath(keys, scene.name)


# -- the Samples menu ----------------------------------------------------------------------------

BUILTIN_LABELS: dict[str, str] = {
    "showroom": "Showroom",
    "showroom-8": "Showroom with 8 lights",
    "showroom-100": "Showroom with 100 lights",
    "showroom-gi": "Showroom with indirect light",
    "texture-test": "Texture test",
    "tcr-cube": "TCR test cube",
    "corridor": "Corridor walk",
}
SAMPLE_EXTENSIONS = (".glb", ".gltf", ".obj", ".ply")
_MAX_SAMPLE_DEPTH = 4  # folders below the scenes folder searched for models
_MAX_SAMPLES = 200  # a huge folder does not make a menu nobody can use


@dataclass(frozen=True)
class Sample:
    """A model file offered in the Samples menu: its group (the first folder under the scenes
    folder, "" for a file directly in it), a plain label and the file."""

    group: str
    label: str
    path: Path


def samples_folder(project_root: Path | None = None) -> Path | None:
    """The shared scenes folder: ``VRPREVIEW_SCENES``, else ``../shared/scenes`` beside the
    project, else beside the current folder; None when there is none."""
    env = os.environ.get("VRPREVIEW_SCENES")
    if env:
        folder = Path(env).expanduser()
        return folder if folder.is_dir() else None
    root = project_root or Path(__file__).resolve().parents[1]
    for base in (root, Path.cwd()):
        folder = (base / ".." / "shared" / "scenes").resolve()
        if folder.is_dir():
            return folder
    return None


def plain_name(stem: str) -> str:
    """A file or folder name as a designer would say it: 'living-room-2' -> 'Living room 2',
    'CesiumMilkTruck' -> 'Cesium milk truck', 'gltf-samples' -> 'glTF samples'."""
    words = re.sub(r"(?<=[a-z0-9])(?=[A-Z])", " ", stem.replace("_", " ").replace("-", " "))
    parts = [w if w.isupper() and len(w) > 1 else w.lower() for w in words.split()]
    parts = ["glTF" if p in ("gltf", "glb") else p for p in parts]
    if not parts:
        return stem
    first = parts[0]
    parts[0] = first if first == "glTF" or first.isupper() else first[:1].upper() + first[1:]
    return " ".join(parts)


def find_samples(folder: Path | None) -> list[Sample]:
    """The models under ``folder`` (.glb, .gltf, .obj, .ply), one per name in each group (a
    .glb preferred to the same model as .gltf), sorted by group and label. A missing or
    unreadable folder gives an empty list."""
    if folder is None or not folder.is_dir():
        return []
    found: dict[tuple[str, str], Path] = {}
    try:
        for dirpath, dirnames, filenames in os.walk(folder):
            here = Path(dirpath)
            rel = here.relative_to(folder)
            if len(rel.parts) >= _MAX_SAMPLE_DEPTH:
                dirnames.clear()
            dirnames[:] = sorted(d for d in dirnames if not d.startswith("."))
            for name in sorted(filenames):
                p = here / name
                ext = p.suffix.lower()
                if ext not in SAMPLE_EXTENSIONS:
                    continue
                group = plain_name(rel.parts[0]) if rel.parts else ""
                key = (group, plain_name(p.stem))
                old = found.get(key)
                if old is None or (
                    SAMPLE_EXTENSIONS.index(ext) < SAMPLE_EXTENSIONS.index(old.suffix.lower())
                ):
                    found[key] = p
            if len(found) >= _MAX_SAMPLES:
                break
    except OSError:
        return []
    return [Sample(g, label, p) for (g, label), p in sorted(found.items())]
