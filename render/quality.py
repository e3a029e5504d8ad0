"""The full-quality reference: the frame at full quality beside the live one, and its error.

:class:`FullQualityReference` is the one reference path. It draws a frame with
:func:`app.quality.full_quality` settings through a second renderer on the caller's GL context
(the window's, or the headless host's), into its own target, and measures a live image against
it (:func:`app.quality.measure`). The benchmark (and with it the study and the experiments)
hands it the converged photon map (see ``app.lab.reference``); the window's quality panel goes
through :class:`QualityProbe`, which draws the live frame once more (statistics text and heat map
hidden) and hands it the live photon map (tracing a converged map takes seconds).
"""

from __future__ import annotations

import moderngl
import numpy as np

from app.frame import FrameInput
from app.metrics import pixels_per_degree
from app.photon_map import PhotonMap
from app.quality import FrameErrors, full_quality, heat_map, measure, stereo_fovea
from app.scene import Scene
from app.settings import Settings
from render.renderer import Renderer


def read_frame(
    ctx: moderngl.Context, fbo: moderngl.Framebuffer, renderer: Renderer, frame: FrameInput
) -> np.ndarray:
    """Clear ``fbo``, render ``frame`` into it and read it back: (H, W, 3) uint8, row 0 at the
    top (the context current)."""
    fbo.use()
    fbo.clear(0.0, 0.0, 0.0, 1.0)
    renderer.render(frame, fbo)
    w, h = fbo.size
    data = fbo.read(components=3, alignment=1)
    return np.ascontiguousarray(np.flipud(np.frombuffer(data, np.uint8).reshape(h, w, 3)))


class FullQualityReference:
    """The frame at full quality on ``ctx`` (every call with that context current).

    ``converged_photons``: the reference gathers a converged photon map (which the caller
    traces and hands to :meth:`draw`) rather than the live one."""

    def __init__(
        self,
        ctx: moderngl.Context,
        converged_photons: bool = False,
        passes: tuple | None = None,
        stream_in: bool = False,
    ) -> None:
        """``passes``: the reference renderer's pass list (the renderer's own by default);
        ``stream_in``: huge texture sets arrive over the next frames, as in the live view."""
        self.ctx = ctx
        self.converged_photons = converged_photons
        self.passes = passes
        self.stream_in = stream_in
        self.renderer: Renderer | None = None
        self._scene: Scene | None = None
        self._color: moderngl.Texture | None = None
        self._fbo: moderngl.Framebuffer | None = None

    def settings_for(self, live: Settings) -> Settings:
        """The reference settings for the live ones (no statistics text)."""
        ref = full_quality(live, converged_photons=self.converged_photons)
        ref.render.overlay = False
        return ref

    def target(self, size: tuple[int, int]) -> moderngl.Framebuffer:
        """An offscreen colour target of ``size`` (whole side-by-side view), kept while the
        size stays."""
        if self._fbo is None or self._color is None or self._color.size != size:
            self._release_target()
            self._color = self.ctx.texture(size, 4)
            self._color.filter = (moderngl.NEAREST, moderngl.NEAREST)  # sampled texel for texel
            self._fbo = self.ctx.framebuffer([self._color])
        return self._fbo

    def _prepare(self, live: Settings, scene: Scene, photons: PhotonMap | None) -> Renderer:
        ref_settings = self.settings_for(live)
        if self.renderer is None:
            if self.passes is None:
                self.renderer = Renderer(self.ctx, ref_settings)
            else:
                self.renderer = Renderer(self.ctx, ref_settings, self.passes)
        self.renderer.settings = ref_settings
        if scene is not self._scene:
            self.renderer.set_scene(scene, stream_in=self.stream_in)
            self._scene = scene
        self.renderer.set_photons(photons)
        return self.renderer

    def draw(
        self, live: Settings, scene: Scene, photons: PhotonMap | None, frame: FrameInput
    ) -> np.ndarray:
        """``frame`` at full quality for the ``live`` settings, gathering ``photons``."""
        eye = frame.eyes[0]
        renderer = self._prepare(live, scene, photons)
        return read_frame(self.ctx, self.target((2 * eye.width, eye.height)), renderer, frame)

    def draw_texture(
        self, live: Settings, scene: Scene, photons: PhotonMap | None, frame: FrameInput
    ) -> moderngl.Texture:
        """``frame`` at full quality into the target, left on the GPU (no read-back)."""
        eye = frame.eyes[0]
        renderer = self._prepare(live, scene, photons)
        fbo = self.target((2 * eye.width, eye.height))
        fbo.use()
        fbo.clear(0.0, 0.0, 0.0, 1.0)
        renderer.render(frame, fbo)
        assert self._color is not None
        return self._color

    def pass_ms(self) -> dict[str, float]:
        """The reference's GPU times of its last frame."""
        return self.renderer.pass_ms() if self.renderer is not None else {}

    def object_ids(self, frame: FrameInput) -> np.ndarray:
        """Mesh index under each pixel of both eyes side by side (after :meth:`draw`)."""
        assert self.renderer is not None, "draw() first"
        return np.hstack(self.renderer.object_ids(frame))

    def measure(
        self,
        live: Settings,
        scene: Scene,
        photons: PhotonMap | None,
        frame: FrameInput,
        test: np.ndarray,
        ppd: float,
        gazed: int | None = None,
    ) -> tuple[FrameErrors, np.ndarray]:
        """The error of ``test`` (the live frame as shown) against full quality, for the
        frame, the fovea, the periphery and (``gazed``: a mesh index) the gazed object;
        and the reference image."""
        reference = self.draw(live, scene, photons, frame)
        regions = {"gazed": self.object_ids(frame) == gazed} if gazed is not None else {}
        fovea = stereo_fovea(live.cps, frame)
        return measure(reference, test, fovea, ppd, regions), reference

    @property
    def errors(self) -> list:
        return self.renderer.errors if self.renderer is not None else []

    def _release_target(self) -> None:
        for obj in (self._fbo, self._color):
            if obj is not None:
                obj.release()
        self._fbo = self._color = None

    def release(self) -> None:
        self._release_target()
        if self.renderer is not None:
            self.renderer.release()
            self.renderer = None
        self._scene = None


class QualityProbe:
    """The window's quality measurement: the live frame redrawn and read back, against
    :class:`FullQualityReference` with the live photon map."""

    def __init__(self, ctx: moderngl.Context) -> None:
        self.ctx = ctx
        self.reference = FullQualityReference(ctx, converged_photons=False)

    def measure(
        self,
        live: Renderer,
        scene: Scene,
        photons: PhotonMap | None,
        frame: FrameInput,
        horizontal_fov_deg: float,
    ) -> dict:
        """Error figures of the live settings against full quality for ``frame`` (the GL
        context current): frame / fovea / periphery figures (``FrameErrors.to_dict``), the
        two images and a heat map."""
        eye = frame.eyes[0]
        fbo = self.reference.target((2 * eye.width, eye.height))
        overlay = live.settings.render.overlay
        live.settings.render.overlay = False
        live.overlay.show_heat = False
        try:
            test = read_frame(self.ctx, fbo, live, frame)
        finally:
            live.settings.render.overlay = overlay
            live.overlay.show_heat = True
        ppd = pixels_per_degree(eye.width, horizontal_fov_deg)
        errors, reference = self.reference.measure(live.settings, scene, photons, frame, test, ppd)
        report = errors.to_dict()
        report.update(
            test=test,
            reference=reference,
            heat=heat_map(errors.flip_map),
            pixels_per_degree=ppd,
            errors=self.reference.errors,
        )
        return report

    def release(self) -> None:
        self.reference.release()
