"""When a scene gets photon-mapped indirect light, and the photon map it gets.

Model only what a scene requires: no photon map is traced unless the scene asks for one
(``Scene.indirect``) or the user turns it on (``photons.enabled = on``). The map is traced again
only when what it depends on changes (the scene's geometry and lights, the photon count, the
seed, the path length); the radius and the gather variant only rebuild the grid on the GPU side,
and the dimmer scales the indirect light in the shader.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable

from app.photon_map import PhotonMap
from app.scene import Scene
from app.settings import PhotonSettings

log = logging.getLogger(__name__)


def wanted(settings: PhotonSettings, scene: Scene | None) -> bool:
    """Whether this scene gets indirect light under these settings."""
    if scene is None or settings.enabled == "off" or settings.photons <= 0:
        return False
    return settings.enabled == "on" or scene.indirect


def map_key(settings: PhotonSettings, scene: Scene) -> tuple:
    """Everything the traced photons depend on (the scene by identity: scenes are not edited in
    place; a reload is a new object; the cache holds the scene, so its id is not reused)."""
    return (id(scene), settings.photons, settings.seed, settings.max_bounces)


class PhotonCache:
    """The current scene's photon map, traced on demand and kept until its key changes."""

    def __init__(self) -> None:
        self.key: tuple | None = None
        self.map: PhotonMap | None = None
        self.scene: Scene | None = None  # held so that id(scene) in the key stays unique
        self.trace_ms = 0.0

    def current(self, settings: PhotonSettings, scene: Scene | None) -> PhotonMap | None:
        """The map for these settings if it is already traced (never traces)."""
        if not wanted(settings, scene):
            return None
        return self.map if self.key == map_key(settings, scene) else None

    def ensure(
        self,
        settings: PhotonSettings,
        scene: Scene | None,
        progress: Callable[[float], None] | None = None,
        cancel: Callable[[], bool] | None = None,
    ) -> PhotonMap | None:
        """Trace if needed (blocking; the window calls this from a worker thread)."""
        if not wanted(settings, scene):
            return None
        assert scene is not None
        key = map_key(settings, scene)
        if self.key != key:
            start = time.perf_counter()
            photons = trace(settings, scene, progress, cancel)
            self.store(key, scene, photons)
            self.trace_ms = (time.perf_counter() - start) * 1e3
        return self.map

    def store(self, key: tuple, scene: Scene, photons: PhotonMap) -> None:
        """Keep a map (traced here, or by the window's worker thread)."""
        self.key, self.scene, self.map = key, scene, photons


def trace(
    settings: PhotonSettings,
    scene: Scene,
    progress: Callable[[float], None] | None = None,
    cancel: Callable[[], bool] | None = None,
) -> PhotonMap:
    from app.photons import trace_photons  # embree is loaded only when photons are wanted

    start = time.perf_counter()
    photons = trace_photons(
        scene,
        settings.photons,
        settings.seed,
        max_bounces=settings.max_bounces,
        progress=progress,
        cancel=cancel,
    )
    log.info(
        "traced %d photon paths in %s: %d photons stored, %.0f ms",
        settings.photons,
        scene.name,
        len(photons),
        (time.perf_counter() - start) * 1e3,
    )
    return photons
