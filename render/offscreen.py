"""Headless host: the same renderer into an offscreen texture; ``draw()`` returns pixels.

Benchmarks, ``vrpreview render``, the no-display demo and the tests all use this host.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from app.frame import FrameInput
from app.indirect import PhotonService
from app.scene import Scene
from app.settings import Settings
from render.context import create_headless
from render.renderer import Renderer


class OffscreenHost:
    def __init__(
        self,
        width: int,
        height: int,
        settings: Settings | None = None,
        trace_progress: Callable[[float], None] | None = None,
    ) -> None:
        """``width`` x ``height`` is the whole side-by-side view (each eye is width/2).

        A scene that wants indirect light gets its photon map traced here, blocking, before
        its first frame (``trace_progress`` hears the fraction done)."""
        self.width = max(2, int(width) // 2 * 2)
        self.height = max(1, int(height))
        self.settings = settings or Settings()
        self.photon_cache = PhotonService(sky=lambda: self.settings.sky)
        # The photon map grown as the window grows it while the viewer stands (traced at once,
        # blocking); off: the map as traced, so frames, benches and tests stay as they were.
        self.grow_photons = False
        self.trace_progress = trace_progress
        self.scene: Scene | None = None
        self.ctx = create_headless()
        with self.ctx:
            self.renderer = Renderer(self.ctx, self.settings)
            self.color = self.ctx.texture((self.width, self.height), 4)
            self.fbo = self.ctx.framebuffer([self.color])

    @property
    def eye_size(self) -> tuple[int, int]:
        return self.width // 2, self.height

    def set_scene(self, scene: Scene | None, stream_in: bool = False) -> None:
        self.scene = scene
        with self.ctx:
            self.renderer.set_scene(scene, stream_in=stream_in)
        self.sync_photons()

    def sync_photons(self) -> None:
        """Trace the photon map if the scene or the photon settings now ask for a new one
        (a no-op when nothing changed); called before every frame."""
        photons = self.photon_cache.ensure(
            self.settings.photons, self.scene, self.trace_progress, refined=self.grow_photons
        )
        with self.ctx:
            self.renderer.set_photons(photons)

    def set_text_image(self, rgba: np.ndarray | None) -> None:
        self.renderer.overlay.set_text_image(rgba)

    def draw(self, frame: FrameInput) -> np.ndarray:
        """Render one stereo frame; (H, W, 3) uint8 with row 0 at the top."""
        self.sync_photons()
        with self.ctx:
            self.fbo.use()
            self.fbo.clear(0.0, 0.0, 0.0, 1.0)
            self.renderer.render(frame, self.fbo)
        return self.read_pixels()

    def warm_variants(self, frame: FrameInput) -> None:
        """While the governor holds a frame rate: compile every program its knobs may turn
        to now (``Renderer.warm_variants``), not one a frame as the window does."""
        if self.renderer.governor.budget_ms > 0:
            with self.ctx:
                self.renderer.warm_variants(frame, None)

    def render_only(self, frame: FrameInput) -> None:
        """Render and wait for the GPU, without reading pixels back (for timing)."""
        self.sync_photons()
        with self.ctx:
            self.fbo.use()
            self.renderer.render(frame, self.fbo)
            self.ctx.finish()

    def read_pixels(self) -> np.ndarray:
        """The last rendered frame (draw or render_only) as (H, W, 3) uint8, row 0 at the top;
        no new render, so stateful passes (the temporal filter) are not stepped again."""
        with self.ctx:
            data = self.fbo.read(components=3, alignment=1)
        img = np.frombuffer(data, np.uint8).reshape(self.height, self.width, 3)
        return np.ascontiguousarray(np.flipud(img))

    def object_ids(self, frame: FrameInput) -> list[np.ndarray]:
        with self.ctx:
            return self.renderer.object_ids(frame)

    def cps_stats(self) -> dict:
        with self.ctx:
            return self.renderer.cps_stats()

    def shaded_samples(self) -> int:
        with self.ctx:
            return self.renderer.shaded_samples()

    def read_hdr(self, eye: int) -> np.ndarray:
        with self.ctx:
            return self.renderer.read_hdr(eye)

    def close(self) -> None:
        with self.ctx:
            self.renderer.release()
            self.fbo.release()
            self.color.release()
        self.ctx.release()

    def __enter__(self) -> OffscreenHost:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
