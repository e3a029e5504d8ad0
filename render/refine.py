"""Progressive refinement while the viewer rests: the accumulation pass.

While a frame is ``refining`` (``app.refine``: viewpoint and gaze at rest, sub-pixel jittered
projections, full quality asked for) this pass keeps a running mean of each eye's linear HDR
colour (sample n: mix(mean, new, 1 / (n + 1)), per pixel) and writes the mean back into
``hdr``, so the exposure meter and the presenter see it. The mean lives in two rgba32f
textures per eye used in turn (a ping-pong pair): one full-screen fragment draw reads this
frame's colour and the mean so far and writes the new mean into the other texture, a second
draw copies it into the colour (rgb only). No compute shader and no image stores: on llvmpipe
fragment passes are the faster path, and the earlier compute version crashed once in a long
test run.

The fovea takes every sample and the periphery the ones ``app.refine.periphery_turn`` gives
it: the fovea converges first. Motion (a frame not refining, or sample 0) starts it afresh;
the history is not reprojected (the session also starts again after the smallest turn or
step, ``app.refine.Refinement.observe``). Once refined (``hold``) the renderer skips the
passes before this one and the mean is shown as it is.

Indirect light: the photon gather runs at every jittered sample, so its noise over the
pixel is averaged too; the photon map itself is not re-traced (no progressive photon
mapping with a shrinking radius).
"""

from __future__ import annotations

import math

import moderngl

from app.refine import needed, periphery_turn
from render.pass_graph import FrameContext, RenderPass, Resources, bind_texture, set_uniforms
from render.shaders import ShaderLibrary


class _EyeMean:
    """One eye's ping-pong pair: ``means[current]`` holds the mean so far."""

    def __init__(self, ctx: moderngl.Context, size: tuple[int, int]) -> None:
        self.size = size
        self.means = [ctx.texture(size, 4, dtype="f4") for _ in range(2)]
        for t in self.means:
            t.filter = (moderngl.NEAREST, moderngl.NEAREST)
            t.repeat_x = t.repeat_y = False
        self.fbos = [ctx.framebuffer([t]) for t in self.means]
        self.current = 0

    def release(self) -> None:
        for fbo in self.fbos:
            fbo.release()
        for tex in self.means:
            tex.release()


class RefinePass(RenderPass):
    """The running mean of refining frames (see the module)."""

    name = "refine"
    reads = ("hdr",)
    writes = ("hdr",)

    def __init__(self, ctx: moderngl.Context, shaders: ShaderLibrary, res: Resources) -> None:
        super().__init__(ctx, shaders, res)
        self.eyes: list[_EyeMean] = []
        self.samples_taken = 0  # samples in the mean (the fovea's count)
        self.valid = False  # the textures hold a mean of this view
        self.fovea_deg = 5.0

    def configure(self, settings, scene, frame) -> bool:
        self.fovea_deg = float(settings.cps.fovea_deg)
        on = str(settings.render.refine) != "off" and bool(getattr(frame, "refining", False))
        if not on:
            self.valid = False
        return on

    def forget(self) -> None:
        """Start again at the next refining frame (scene, photons or targets changed)."""
        self.valid = False
        self.samples_taken = 0

    def holding(self, frame: FrameContext) -> bool:
        """This frame only shows the finished mean (the passes before may be skipped)."""
        return bool(
            self.valid
            and getattr(frame, "refining", False)
            and frame.refine_sample >= needed(frame.refine_target)
            and self._ready()
        )

    def _ready(self) -> bool:
        sizes = [t.size for t in self.res.targets]
        return len(self.eyes) == len(sizes) and all(e.size == s for e, s in zip(self.eyes, sizes))

    def _ensure(self) -> None:
        if self._ready():
            return
        self._release_textures()
        self.eyes = [_EyeMean(self.ctx, t.size) for t in self.res.targets]
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
        accumulate = self.shaders.program("fullscreen.vert.glsl", "refine_accumulate.frag.glsl")
        copy = self.shaders.program(
            "fullscreen.vert.glsl", "refine_accumulate.frag.glsl", {"COPY": True}
        )
        # After the lighting's image stores and the draws into the colour.
        self.ctx.memory_barrier(
            moderngl.SHADER_IMAGE_ACCESS_BARRIER_BIT
            | moderngl.FRAMEBUFFER_BARRIER_BIT
            | moderngl.TEXTURE_FETCH_BARRIER_BIT
        )
        self.ctx.disable(moderngl.DEPTH_TEST | moderngl.BLEND)
        u, v = frame.gaze
        for eye, tgt, mean in zip(frame.eyes, res.targets, self.eyes):
            w, h = tgt.size
            if not hold:
                focal = float(eye.projection[1, 1]) * h / 2.0  # pixels per unit of tan(angle)
                radius = focal * math.tan(math.radians(min(max(self.fovea_deg, 0.0), 89.0)))
                set_uniforms(
                    accumulate,
                    {
                        "u_restart": int(restart),
                        "u_hold": 0,
                        "u_periphery_turn": int(periphery_turn(sample, target)),
                        "u_gaze_px": (float(u) * w, (1.0 - float(v)) * h),
                        "u_fovea_px": float(radius),
                    },
                )
                bind_texture(accumulate, "current", tgt.color)
                bind_texture(accumulate, "history", mean.means[mean.current])
                nxt = 1 - mean.current
                mean.fbos[nxt].viewport = (0, 0, w, h)
                mean.fbos[nxt].use()
                self.fullscreen(accumulate)
                mean.current = nxt
            bind_texture(copy, "history", mean.means[mean.current])
            fbo = tgt.forward
            fbo.viewport = (0, 0, w, h)
            fbo.color_mask = (True, True, True, False)
            try:
                fbo.use()
                self.fullscreen(copy)
            finally:
                fbo.color_mask = (True, True, True, True)
        self.ctx.memory_barrier(moderngl.TEXTURE_FETCH_BARRIER_BIT)
        if not hold:
            self.samples_taken += 1
        self.valid = True

    def _release_textures(self) -> None:
        for e in self.eyes:
            e.release()
        self.eyes = []

    def release(self) -> None:
        super().release()
        self._release_textures()
