"""Scene names the user can type: the built-in scenes, or a path to a model file."""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

from app.paths import CameraPath, PathKey, builtin_path
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
    "showroom-100": _showroom(100),
    "showroom-gi": _showroom(4, indirect=True),
    "texture-test": _texture_test,
    "tcr-cube": _tcr_cube,
    "corridor": _corridor,
}
BUILTIN_PATHS = {
    "showroom": "showroom_walkthrough",
    "showroom-100": "showroom_walkthrough",
    "showroom-gi": "showroom_walkthrough",
    "tcr-cube": "tcr_cube_distance",
    "corridor": "corridor_walk",
}


def _generated_paths() -> dict[str, Callable[[], CameraPath]]:
    from assets import corridor, tcr_cube

    return {
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
        return BUILTIN[key]()
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
