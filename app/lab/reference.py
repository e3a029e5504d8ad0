"""The lab's full-quality reference: :class:`render.quality.FullQualityReference` on the
benchmark host's context, with the converged photon map from an explicit cache.

One :class:`ConvergedPhotons` is shared by every run of an experiment or a study (tracing 4M
photon paths takes a while), instead of a module-global cache.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np

from app.frame import FrameInput
from app.indirect import trace, wanted
from app.photon_map import PhotonMap
from app.quality import FrameErrors
from app.scene import Scene
from app.settings import PhotonSettings, Settings

if TYPE_CHECKING:
    from render.offscreen import OffscreenHost


class ConvergedPhotons:
    """The converged photon map of one scene at a time (a 4M map is 128 MB), traced on first
    use and kept while the scene and the tracing settings stay."""

    def __init__(self, progress: Callable[[float], None] | None = None) -> None:
        self.progress = progress
        self.key: tuple | None = None
        self.map: PhotonMap | None = None
        self.traced = 0  # maps traced so far (the tests check the cache is used)

    def get(self, settings: PhotonSettings, scene_name: str, scene: Scene) -> PhotonMap | None:
        """The map the reference gathers for ``settings`` (already :func:`full_quality`), or
        None where the scene has no indirect light."""
        if not wanted(settings, scene):
            return None
        key = (scene_name, settings.photons, settings.seed, settings.max_bounces)
        if key != self.key:
            self.key, self.map = None, None  # drop the old map before tracing the next
            self.map = trace(settings, scene, self.progress)
            self.key = key
            self.traced += 1
        return self.map


class BenchReference:
    """Full quality for every compared frame of one benchmark run, drawn on ``host``'s
    context beside the timed renderer."""

    def __init__(
        self, host: OffscreenHost, scene_name: str, scene: Scene, converged: ConvergedPhotons
    ) -> None:
        self.host = host
        self.scene_name = scene_name
        self.scene = scene
        self.converged = converged
        from render.quality import FullQualityReference  # GL only when a run compares

        self.reference = FullQualityReference(host.ctx, converged_photons=True)

    def measure(
        self, live: Settings, frame: FrameInput, test: np.ndarray, ppd: float, gazed: int | None
    ) -> FrameErrors:
        """The error of the timed frame ``test`` against the same frame at full quality."""
        photons = self.converged.get(
            self.reference.settings_for(live).photons, self.scene_name, self.scene
        )
        with self.host.ctx:
            errors, _reference = self.reference.measure(
                live, self.scene, photons, frame, test, ppd, gazed
            )
        return errors

    @property
    def errors(self) -> list:
        return self.reference.errors

    def close(self) -> None:
        with self.host.ctx:
            self.reference.release()
