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
from app.scene import Scene
from render.ab_split import ABSplitPass, SplitFrame, SplitView, technique_caption
from render.present import OverlayPass
from render.quality import FullQualityReference
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
        # The full-quality half: the quality probe's reference with the live photon map, its
        # own renderer without the overlay and the split.
        self.reference = FullQualityReference(
            ctx, converged_photons=False, passes=REFERENCE_PASSES, stream_in=stream_in
        )

    def draw_reference(self, live: Renderer, scene: Scene, frame: FrameInput) -> moderngl.Texture:
        """The full-quality frame for ``live``'s settings and photon map into the target."""
        return self.reference.draw_texture(live.settings, scene, live.photons.photons, frame)

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
        return self.reference.errors

    def pass_ms(self) -> dict[str, float]:
        """The full-quality half's GPU times of its last frame."""
        return self.reference.pass_ms()

    def release(self) -> None:
        self.reference.release()


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
