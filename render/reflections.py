"""Reflections on glossy surfaces, from the picture on screen (``render.reflections=screen``).

The ambient specular term (shading.glsl) reflects the even light: the same brightness from
every direction. A varnished floor in a path tracer mirrors what lies in its reflected
direction instead: the window's bright pane, the lamps' shades, the sunlit patch (issue 14's
"sheen of a varnished table"; against Cycles the daylit showroom's worst region was the floor
under the window, where Cycles shows the window's reflection). Per eye, after the opaque
picture and the sky are drawn and before glass:

1. the lit picture is copied (``ReflectTargets.source``) and its mipmaps built;
2. the glossy pixels (roughness below ``MAX_ROUGHNESS``) are marked in a depth mask, at full
   and at half size (reflect_mask.frag.glsl);
3. at half size, each glossy pixel's reflected ray is marched through the depth buffer
   (geometric steps out to about 10 m, then bisection); where it meets a surface on screen,
   the environment BRDF times (the picture there, blurred by the lobe's footprint, minus the
   even light the ambient term assumed) is what to add (reflections.frag.glsl);
4. that is enlarged bilinearly and added to the glossy pixels (reflect_apply.frag.glsl).

With daylight on, a ray that meets nothing on its way and whose direction lands on the sky
in the picture (an open window; the sky is infinitely far, so the point a direction tends to
on screen shows the sky in that direction) takes the sky there. Rough surfaces and rays that
leave the screen keep the even light. The masks matter on
llvmpipe, which shades every pixel of a block through both sides of a branch but skips a
block that the early depth test rejects whole: on the showroom at 2 x 640x720 the march at
full size without them cost 75 ms, more than the lighting. Deterministic (one ray per pixel,
no noise) and per eye. The deferred path only: the forward path has no G-buffer to march.
"""

from __future__ import annotations

import moderngl

from render.ambient_field import bind_field
from render.pass_graph import (
    BySize,
    FrameContext,
    RenderPass,
    Resources,
    bind_texture,
    release_all,
    set_uniforms,
)
from render.passes import deferred, scene_uniforms
from render.shadow_mask import depth_terms

MAX_ROUGHNESS = 0.6  # rougher surfaces keep the even light (their lobe is nearly uniform)
STEPS = 12  # geometric steps along the reflected ray
CONE = 1.0  # the lobe's half-width over roughness squared (radians; 0.5 measured alike)
MIP_LEVELS = 7  # the copy's blur levels: up to 64 pixels


def half_size(size: tuple[int, int]) -> tuple[int, int]:
    return max(1, (size[0] + 1) // 2), max(1, (size[1] + 1) // 2)


class ReflectTargets:
    """One eye's copy of the lit picture (with mipmaps), the glossy masks at full and half
    size, and the half-size reflections."""

    def __init__(self, ctx: moderngl.Context, size: tuple[int, int]) -> None:
        self.size = size
        self.source = ctx.texture(size, 4, dtype="f2")
        self.source.build_mipmaps(0, MIP_LEVELS - 1)  # the levels exist from here on
        self.source.filter = (moderngl.LINEAR_MIPMAP_LINEAR, moderngl.LINEAR)
        self.source.repeat_x = self.source.repeat_y = False
        self.fbo = ctx.framebuffer([self.source])
        self.mask = ctx.depth_texture(size)  # 0 on glossy pixels, 1 elsewhere
        self.mask_fbo = ctx.framebuffer(depth_attachment=self.mask)
        half = half_size(size)
        self.half = ctx.texture(half, 4, dtype="f2")
        self.half.filter = (moderngl.LINEAR, moderngl.LINEAR)
        self.half.repeat_x = self.half.repeat_y = False
        self.half_mask = ctx.depth_texture(half)
        self.half_mask_fbo = ctx.framebuffer(depth_attachment=self.half_mask)
        self.half_fbo = ctx.framebuffer([self.half], self.half_mask)
        # The eye's colour over the mask, for the colour texture it was made with: by the
        # object, not its GL name (the renderer remakes its targets, and GL reuses names,
        # while these targets are kept for their size).
        self._over: tuple[moderngl.Texture, moderngl.Framebuffer] | None = None

    def over(self, ctx: moderngl.Context, color: moderngl.Texture) -> moderngl.Framebuffer:
        """The eye's HDR colour with the full-size glossy mask as depth."""
        if self._over is None or self._over[0] is not color:
            if self._over is not None:
                self._over[1].release()
            self._over = (color, ctx.framebuffer([color], self.mask))
        return self._over[1]

    def release(self) -> None:
        objects: list[moderngl.Framebuffer | moderngl.Texture] = [
            *([self._over[1]] if self._over is not None else []),
            self.half_fbo,
            self.half_mask_fbo,
            self.half_mask,
            self.half,
            self.mask_fbo,
            self.mask,
            self.fbo,
            self.source,
        ]
        for obj in objects:
            obj.release()
        self._over = None


class ReflectionPass(RenderPass):
    """Per eye: the reflected picture on glossy surfaces, added to the HDR colour."""

    name = "reflections"
    reads = ("depth", "normal", "albedo", "hdr")
    optional_reads = ("sky",)  # with daylight: rays that leave through a window take the sky
    writes = ("hdr",)

    def __init__(self, ctx: moderngl.Context, shaders, res: Resources) -> None:
        super().__init__(ctx, shaders, res)
        self.targets: list[ReflectTargets] = []
        # The eyes' targets for the last sizes used, as the renderer keeps its own (BySize).
        self._by_size: BySize[list[ReflectTargets]] = BySize(
            lambda size: [ReflectTargets(self.ctx, size) for _ in range(2)], release_all
        )

    def configure(self, settings, scene, frame) -> bool:
        return deferred(settings) and settings.render.reflections == "screen"

    def _ensure(self, size: tuple[int, int]) -> None:
        self.targets = self._by_size.get(size)

    def execute(self, frame: FrameContext, res: Resources) -> None:
        ctx = self.ctx
        self._ensure(res.targets[0].size)
        trace = self.shaders.program(
            "fullscreen.vert.glsl",
            "reflections.frag.glsl",
            {
                "AMBIENT_FIELD": frame.ambient_field is not None,
                "REFLECT_SKY": res.written("sky") and res.get("sky") is not None,
                "REFLECT_STEPS": STEPS,
                "REFLECT_CONE": CONE,
                "REFLECT_MIPS": MIP_LEVELS,
            },
        )
        mask = self.shaders.program("fullscreen.vert.glsl", "reflect_mask.frag.glsl")
        apply = self.shaders.program("fullscreen.vert.glsl", "reflect_apply.frag.glsl")
        scene_uniforms(trace, frame)
        bind_field(trace, frame.ambient_field)
        set_uniforms(trace, {"u_max_roughness": MAX_ROUGHNESS})
        set_uniforms(mask, {"u_max_roughness": MAX_ROUGHNESS})
        ctx.memory_barrier(moderngl.FRAMEBUFFER_BARRIER_BIT | moderngl.TEXTURE_FETCH_BARRIER_BIT)
        ctx.disable(moderngl.BLEND | moderngl.CULL_FACE)
        ctx.enable(moderngl.DEPTH_TEST)
        self.samples = 0
        for eye, tgt, own in zip(frame.eyes, res.targets, self.targets):
            ctx.copy_framebuffer(own.fbo, tgt.forward)
            own.source.build_mipmaps(0, MIP_LEVELS - 1)
            # The glossy masks (depth 0 glossy, 1 not), written whatever lies there.
            ctx.depth_func = "1"
            bind_texture(mask, "gb_normal", tgt.normal)
            bind_texture(mask, "gb_depth", tgt.depth)
            for fbo, step in ((own.mask_fbo, 1), (own.half_mask_fbo, 2)):
                fbo.use()
                set_uniforms(mask, {"u_step": step})
                self.fullscreen(mask)
            # The trace at half size where the mask is nearer than the triangle's 0.5.
            ctx.depth_func = ">"
            own.half_fbo.depth_mask = False
            own.half_fbo.use()
            own.half_fbo.clear(0.0, 0.0, 0.0, 0.0)  # the colour only (the depth mask is off)
            bind_texture(trace, "gb_albedo", tgt.albedo)
            bind_texture(trace, "gb_normal", tgt.normal)
            bind_texture(trace, "gb_depth", tgt.depth)
            bind_texture(trace, "reflect_source", own.source)
            set_uniforms(
                trace,
                {
                    "u_view_projection": eye.view_projection,
                    "u_inv_view_projection": eye.inverse_view_projection,
                    "u_eye": tuple(eye.position),
                    "u_size": tgt.size,
                    "u_depth_terms": depth_terms(eye),
                },
            )
            self.fullscreen(trace)
            own.half_fbo.depth_mask = True
            # Added to the glossy pixels of the picture.
            fbo = own.over(ctx, tgt.color)
            fbo.depth_mask = False
            fbo.use()
            ctx.enable(moderngl.BLEND)
            ctx.blend_func = moderngl.ONE, moderngl.ONE
            bind_texture(apply, "reflect_half", own.half)
            set_uniforms(apply, {"u_size": tgt.size})
            self.fullscreen(apply)
            ctx.blend_func = moderngl.SRC_ALPHA, moderngl.ONE_MINUS_SRC_ALPHA
            ctx.disable(moderngl.BLEND)
            fbo.depth_mask = True
            self.samples += own.half.size[0] * own.half.size[1]
        ctx.depth_func = "<"
        ctx.disable(moderngl.DEPTH_TEST)

    def release(self) -> None:
        super().release()
        self._by_size.clear()
        self.targets = []
