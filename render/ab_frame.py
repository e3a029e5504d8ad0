"""The presenter's A/B frame on one GL context: the live frame with the technique, split with
the same frame at full quality (both from the same camera, gaze and frame input).

The full quality is the quality probe's (``app.quality.full_quality`` with the live photon
map, as :class:`render.quality.FullQualityReference` draws it): TCR off, CPS ``none``, photons
gathered per eye without reuse, everything else as live. It is drawn by a second renderer
into a target as big as the view, without the overlay (the live frame's overlay pass draws
the gaze marker and statistics once, over both halves), then :class:`render.ab_split.
ABSplitPass` composites it in the live frame. Both hosts use it: the Qt view
(``ui.presenter``) and the headless host (:func:`draw_offscreen`).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import moderngl
import numpy as np

from app.frame import FrameInput
from app.quality import full_quality
from app.scene import Scene
from app.settings import Settings
from render.ab_split import ABSplitPass, SplitFrame, SplitView, technique_caption
from render.passes import OverlayPass
from render.renderer import PASS_TYPES, Renderer

if TYPE_CHECKING:
    from render.offscreen import OffscreenHost

# The full-quality half: the frame without the overlay and without a split of its own.
REFERENCE_PASSES = tuple(t for t in PASS_TYPES if t not in (OverlayPass, ABSplitPass))


class ABFrame:
    """Draws A/B frames on ``ctx`` (every call with that context current).

    ``stream_in``: huge texture sets arrive over the next frames, as in the live view (see
    :class:`render.texture_stream.TextureStreamer`), so turning the split on never freezes the
    window; the full-quality half is then at its finest once they are in."""

    def __init__(self, ctx: moderngl.Context, stream_in: bool = False) -> None:
        self.ctx = ctx
        self.stream_in = stream_in
        self.renderer: Renderer | None = None  # the full-quality half's own renderer
        self._scene: Scene | None = None
        self._color: moderngl.Texture | None = None
        self._fbo: moderngl.Framebuffer | None = None

    @staticmethod
    def reference_settings(live: Settings) -> Settings:
        """The full-quality half's settings for the live ones (the live photon map)."""
        return full_quality(live, converged_photons=False)

    def _target(self, size: tuple[int, int]) -> moderngl.Framebuffer:
        if self._fbo is None or self._color is None or self._color.size != size:
            self._release_target()
            self._color = self.ctx.texture(size, 4)
            self._color.filter = (moderngl.NEAREST, moderngl.NEAREST)
            self._fbo = self.ctx.framebuffer([self._color])
        return self._fbo

    def draw_reference(self, live: Renderer, scene: Scene, frame: FrameInput) -> moderngl.Texture:
        """The full-quality frame for ``live``'s settings and photon map into the target."""
        settings = self.reference_settings(live.settings)
        if self.renderer is None:
            self.renderer = Renderer(self.ctx, settings, REFERENCE_PASSES)
        self.renderer.settings = settings
        if scene is not self._scene:
            self.renderer.set_scene(scene, stream_in=self.stream_in)
            self._scene = scene
        self.renderer.set_photons(live.photons.photons)
        eye = frame.eyes[0]
        fbo = self._target((2 * eye.width, eye.height))
        fbo.use()
        fbo.clear(0.0, 0.0, 0.0, 1.0)
        self.renderer.render(frame, fbo)
        assert self._color is not None
        return self._color

    def render(
        self,
        live: Renderer,
        scene: Scene,
        frame: FrameInput,
        out: moderngl.Framebuffer,
        view: SplitView,
        origin: tuple[int, int] = (0, 0),
    ) -> None:
        """The A/B frame into ``out`` at ``origin`` (which the caller has cleared); the left
        caption says what the live settings change (when ``view.left`` is empty)."""
        reference = self.draw_reference(live, scene, frame)
        if not view.left:
            has_photons = live.photons.photons is not None
            view = SplitView(
                view.divider, technique_caption(live.settings, has_photons), view.right
            )
        out.use()
        live.render(frame, out, origin, split=SplitFrame(reference, view))

    @property
    def errors(self) -> list[str]:
        return self.renderer.errors if self.renderer is not None else []

    def pass_ms(self) -> dict[str, float]:
        """The full-quality half's GPU times of its last frame."""
        return self.renderer.pass_ms() if self.renderer is not None else {}

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


def draw_offscreen(
    host: OffscreenHost, ab: ABFrame, frame: FrameInput, view: SplitView
) -> np.ndarray:
    """One A/B frame on the headless host: (H, W, 3) uint8, row 0 at the top."""
    if host.scene is None:
        raise ValueError("the headless host has no scene: set_scene first")
    host.sync_photons()
    with host.ctx:
        host.fbo.use()
        host.fbo.clear(0.0, 0.0, 0.0, 1.0)
        ab.render(host.renderer, host.scene, frame, host.fbo, view)
    return host.read_pixels()
