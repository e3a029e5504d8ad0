"""The quality probe: the current frame at full quality beside the live one, and its error.

The window's quality panel asks for it on a key: the live renderer draws the frame once more
(statistics text and heat map hidden) and a second renderer, made on first use with
:func:`app.quality.full_quality` settings, draws the reference; both are read back and compared
for the frame, the fovea and the periphery. The reference gathers the live photon map without
stereo reuse (tracing a converged map takes seconds; the benchmark's reference does that).
"""

from __future__ import annotations

import moderngl
import numpy as np

from app.frame import FrameInput
from app.metrics import pixels_per_degree
from app.photon_map import PhotonMap
from app.quality import full_quality, heat_map, measure, stereo_fovea
from app.scene import Scene
from render.renderer import Renderer


class QualityProbe:
    def __init__(self, ctx: moderngl.Context) -> None:
        self.ctx = ctx
        self.reference: Renderer | None = None
        self._scene: Scene | None = None
        self._color: moderngl.Texture | None = None
        self._fbo: moderngl.Framebuffer | None = None

    def _ensure_target(self, size: tuple[int, int]) -> moderngl.Framebuffer:
        if self._fbo is None or self._color is None or self._color.size != size:
            self._release_target()
            self._color = self.ctx.texture(size, 4)
            self._fbo = self.ctx.framebuffer([self._color])
        return self._fbo

    def _draw(self, renderer: Renderer, frame: FrameInput, size: tuple[int, int]) -> np.ndarray:
        fbo = self._ensure_target(size)
        fbo.use()
        fbo.clear(0.0, 0.0, 0.0, 1.0)
        renderer.render(frame, fbo)
        data = fbo.read(components=3, alignment=1)
        return np.ascontiguousarray(
            np.flipud(np.frombuffer(data, np.uint8).reshape(size[1], size[0], 3))
        )

    def measure(
        self,
        live: Renderer,
        scene: Scene,
        photons: PhotonMap | None,
        frame: FrameInput,
        horizontal_fov_deg: float,
    ) -> dict:
        """Error figures of the live settings against full quality for ``frame`` (the GL
        context current): frame / fovea / periphery metrics, the two images and a heat map."""
        eye = frame.eyes[0]
        size = (2 * eye.width, eye.height)
        ref_settings = full_quality(live.settings, converged_photons=False)
        ref_settings.render.overlay = False
        if self.reference is None:
            self.reference = Renderer(self.ctx, ref_settings)
        self.reference.settings = ref_settings
        if scene is not self._scene:
            self.reference.set_scene(scene)
            self._scene = scene
        self.reference.set_photons(photons)
        overlay = live.settings.render.overlay
        live.settings.render.overlay = False
        live.overlay.show_heat = False
        try:
            test = self._draw(live, frame, size)
        finally:
            live.settings.render.overlay = overlay
            live.overlay.show_heat = True
        reference = self._draw(self.reference, frame, size)
        ppd = pixels_per_degree(eye.width, horizontal_fov_deg)
        report = measure(reference, test, stereo_fovea(live.settings.cps, frame), ppd)
        report.update(
            test=test,
            reference=reference,
            heat=heat_map(report["flip_map"]),
            pixels_per_degree=ppd,
            errors=self.reference.errors,
        )
        return report

    def _release_target(self) -> None:
        for obj in (self._fbo, self._color):
            if obj is not None:
                obj.release()
        self._fbo = self._color = None

    def release(self) -> None:
        self._release_target()
        if self.reference is not None:
            self.reference.release()
            self.reference = None
        self._scene = None
