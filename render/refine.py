"""Progressive refinement while the viewer rests: the accumulation pass.

While a frame is ``refining`` (``app.refine``: viewpoint and gaze at rest, sub-pixel jittered
projections, full quality asked for) this pass keeps a running mean of each eye's linear HDR
colour in an rgba32f texture (sample n: mix(mean, new, 1 / (n + 1)), per pixel) and writes
the mean back into ``hdr``, so the exposure meter and the presenter see it. The fovea takes
every sample and the periphery the ones ``app.refine.periphery_turn`` gives it: the fovea
converges first. Motion (a frame not refining, or sample 0) starts it afresh; the history is
not reprojected. Once refined (``hold``) the renderer skips the passes before this one and
the mean is shown as it is.

Indirect light: the photon gather runs at every jittered sample, so its noise over the
pixel is averaged too; the photon map itself is not re-traced (no progressive photon
mapping with a shrinking radius).
"""

from __future__ import annotations

import math

import moderngl

from app.refine import needed, periphery_turn
from render.pass_graph import FrameContext, RenderPass, Resources, bind_image, set_uniforms
from render.shaders import ShaderLibrary


class RefinePass(RenderPass):
    """The running mean of refining frames (see the module)."""

    name = "refine"
    reads = ("hdr",)
    writes = ("hdr",)

    def __init__(self, ctx: moderngl.Context, shaders: ShaderLibrary, res: Resources) -> None:
        super().__init__(ctx, shaders, res)
        self.accum: list[moderngl.Texture] = []
        self.samples_taken = 0  # samples in the mean (the fovea's count)
        self.valid = False  # the textures hold a mean of this view
        self.fovea_deg = 5.0

    def configure(self, settings, scene, frame) -> bool:
        self.fovea_deg = float(settings.cps.fovea_deg)
        on = bool(settings.render.refine) and bool(getattr(frame, "refining", False))
        if not on:
            self.valid = False
        return on

    def forget(self) -> None:
        """Start again at the next refining frame (scene, photons or targets changed)."""
        self.valid = False

    def holding(self, frame: FrameContext) -> bool:
        """This frame only shows the finished mean (the passes before may be skipped)."""
        return bool(
            self.valid
            and getattr(frame, "refining", False)
            and frame.refine_sample >= needed(frame.refine_target)
            and self._ready(frame)
        )

    def _ready(self, frame: FrameContext) -> bool:
        sizes = [t.size for t in self.res.targets]
        return len(self.accum) == len(sizes) and all(a.size == s for a, s in zip(self.accum, sizes))

    def _ensure(self) -> None:
        sizes = [t.size for t in self.res.targets]
        if len(self.accum) == len(sizes) and all(a.size == s for a, s in zip(self.accum, sizes)):
            return
        self._release_textures()
        self.accum = [self.ctx.texture(s, 4, dtype="f4") for s in sizes]
        for t in self.accum:
            t.filter = (moderngl.NEAREST, moderngl.NEAREST)
        self.valid = False

    def execute(self, frame: FrameContext, res: Resources) -> None:
        self._ensure()
        sample = int(frame.refine_sample)
        target = int(frame.refine_target)
        hold = self.valid and sample >= needed(target)
        restart = not self.valid or sample == 0
        if restart:
            hold = False
            self.samples_taken = 0
        prog = self.shaders.compute("refine_accumulate.comp.glsl")
        # After the lighting's image stores and the draws into the colour.
        self.ctx.memory_barrier(
            moderngl.SHADER_IMAGE_ACCESS_BARRIER_BIT | moderngl.FRAMEBUFFER_BARRIER_BIT
        )
        u, v = frame.gaze
        for eye, tgt, acc in zip(frame.eyes, res.targets, self.accum):
            w, h = tgt.size
            focal = float(eye.projection[1, 1]) * h / 2.0  # pixels per unit of tan(angle)
            radius = focal * math.tan(math.radians(min(max(self.fovea_deg, 0.0), 89.0)))
            set_uniforms(
                prog,
                {
                    "u_size": (w, h),
                    "u_restart": int(restart),
                    "u_hold": int(hold),
                    "u_periphery_turn": int(periphery_turn(sample, target)),
                    "u_gaze_px": (float(u) * w, (1.0 - float(v)) * h),
                    "u_fovea_px": float(radius),
                },
            )
            bind_image(tgt.color, "out", read=True, write=True)
            bind_image(acc, "accum", read=True, write=True)
            prog.run(math.ceil(w / 8), math.ceil(h / 8))
        self.ctx.memory_barrier(
            moderngl.TEXTURE_FETCH_BARRIER_BIT | moderngl.SHADER_IMAGE_ACCESS_BARRIER_BIT
        )
        if not hold:
            self.samples_taken += 1
        self.valid = True

    def _release_textures(self) -> None:
        for t in self.accum:
            t.release()
        self.accum = []

    def release(self) -> None:
        super().release()
        self._release_textures()
