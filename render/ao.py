"""Ambient occlusion of the ambient term: each eye's occlusion image, read by every lighting path.

``render.ao`` picks the method:

- ``screen``: rays marched against the depth buffer at half resolution (ao_screen.frag.glsl)
  from the G-buffer's depth and normals, a 2x2 average that takes out its fixed 2x2 turn
  pattern (ao_blur.frag.glsl), then a bilateral upsample to full resolution
  (ao_upsample.frag.glsl). No time, no noise: the same picture every frame.
- ``baked``: the occlusion ``app.ao_bake`` casts per vertex (in the background, the first
  time a scene is drawn this way), drawn as a vertex attribute
  (ao_vertex.frag.glsl) into the same image, depth-tested against the G-buffer.

The forward method has no G-buffer: the pass then draws its own depth and normals first
(PREPASS). The lighting multiplies only the ambient term by the image (ao.glsl), never the
lamps. With photon-mapped indirect light the bounce light replaces the even ambient estimate,
so the pass leaves no image and the ambient term stays as it was.

The default is ``off``: on the showroom at 2x640x720 the screen method costs 43 ms of a 161 ms
frame (with soft shadows). Its reach and strength default to 0.3 m and 50 %: against Blender
Cycles (``vrpreview reference-compare``) that brings five of the six views of
docs/reference_flip.md closer (by 0.0003-0.0013); the living room's is 0.0005 further, as it
darkens the gap between its sofa and table where our frame is already at half of Cycles'
light. At 0.75 m and 100 % four views were further: the even light by place already darkens
a room's far corners. Of the two methods,
``screen`` is the one to choose: against per-pixel ray-traced occlusion (embree, 128 rays, the same
0.75 m reach) it is closer on both the showroom and a shared interior, and it does not depend
on how finely a model is cut into triangles: the showroom's shell is two triangles a wall, so
no per-vertex bake can shade its corners. It costs about as much as the deferred lighting on
llvmpipe (half resolution, 8 rays of 4 steps); the bake costs little on small scenes but
draws the geometry once more per eye, as dear as the G-buffer on a 380,000-triangle room.
Figures: the branch's report (issue 14).
"""

from __future__ import annotations

import moderngl
import numpy as np

from app.camera import EyeView
from render.pass_graph import (
    BySize,
    FrameContext,
    RenderPass,
    Resources,
    bind_texture,
    release_all,
    set_uniforms,
)
from render.shaders import ShaderLibrary

AO_DIRECTIONS = 8  # rays per half-resolution pixel
AO_STEPS = 4  # depth-buffer steps per ray


class AoTargets:
    """One eye's occlusion images: full resolution (the lighting's input), half resolution
    (the screen method's raw result and distance), and the forward method's own depth and
    normals."""

    def __init__(self, ctx: moderngl.Context, size: tuple[int, int]) -> None:
        self.size = size
        w, h = size
        self.ao = ctx.texture(size, 1, dtype="f1")
        half = (max(1, (w + 1) // 2), max(1, (h + 1) // 2))
        self.raw = ctx.texture(half, 2, dtype="f4")
        self.blurred = ctx.texture(half, 2, dtype="f4")
        self.depth = ctx.depth_texture(size)
        self.normal = ctx.texture(size, 4, dtype="f2")
        for t in (self.ao, self.raw, self.blurred, self.depth, self.normal):
            t.filter = (moderngl.NEAREST, moderngl.NEAREST)
            t.repeat_x = t.repeat_y = False
        self.ao_fbo = ctx.framebuffer([self.ao])
        self.raw_fbo = ctx.framebuffer([self.raw])
        self.blurred_fbo = ctx.framebuffer([self.blurred])
        self.prepass_fbo = ctx.framebuffer([self.ao, self.normal], self.depth)
        self._over: dict[int, moderngl.Framebuffer] = {}  # ao over a G-buffer depth, by glo

    def over_depth(self, ctx: moderngl.Context, depth: moderngl.Texture) -> moderngl.Framebuffer:
        """The occlusion image with ``depth`` (the G-buffer's) as depth attachment."""
        fbo = self._over.get(depth.glo)
        if fbo is None:
            for old in self._over.values():  # the G-buffer was resized: one at a time
                old.release()
            self._over = {depth.glo: ctx.framebuffer([self.ao], depth)}
            fbo = self._over[depth.glo]
        return fbo

    def release(self) -> None:
        objects: list[moderngl.Framebuffer | moderngl.Texture] = [
            *self._over.values(),
            self.ao_fbo,
            self.raw_fbo,
            self.blurred_fbo,
            self.prepass_fbo,
            self.ao,
            self.raw,
            self.blurred,
            self.depth,
            self.normal,
        ]
        for obj in objects:
            obj.release()
        self._over.clear()


class AmbientOcclusionPass(RenderPass):
    """Per eye: the ambient term's occlusion (1 open, 0 buried), mixed with the strength."""

    name = "ao"
    reads: tuple[str, ...] = ("depth", "normal")
    optional_reads = ("indirect", "photon_map")
    writes = ("ao",)

    def __init__(self, ctx: moderngl.Context, shaders: ShaderLibrary, res: Resources) -> None:
        super().__init__(ctx, shaders, res)
        self.method = "off"
        self.deferred = True
        self.radius_m = 0.75
        self.strength = 1.0
        self.targets: list[AoTargets] = []
        self._by_size: BySize[list[AoTargets]] = BySize(
            lambda size: [AoTargets(self.ctx, size) for _ in range(2)], release_all
        )
        self.skipped_for_indirect = False  # last frame: the photons' bounce light was on

    def configure(self, settings, scene, frame) -> bool:
        r = settings.render
        self.method = r.ao
        self.deferred = r.path == "deferred"
        self.radius_m = float(r.ao_radius_m)
        self.strength = float(r.ao_strength)
        self.reads = ("depth", "normal") if self.deferred else ()
        return self.method in ("screen", "baked")

    def _ensure(self, size: tuple[int, int]) -> None:
        self.targets = self._by_size.get(size)

    def execute(self, frame: FrameContext, res: Resources) -> None:
        self.skipped_for_indirect = (
            res.get("indirect") is not None or res.get("photon_map") is not None
        )
        if self.skipped_for_indirect:
            return  # the bounce light stands in for the ambient estimate: no image
        self._ensure(res.targets[0].size)
        ctx = self.ctx
        ctx.disable(moderngl.BLEND | moderngl.CULL_FACE)
        for index, (eye, tgt, own) in enumerate(zip(frame.eyes, res.targets, self.targets)):
            if self.deferred:
                depth, normal = tgt.depth, tgt.normal
                if self.method == "baked":
                    self._draw_baked(frame, eye, index, own.over_depth(ctx, tgt.depth), False)
            else:
                depth, normal = own.depth, own.normal
                self._draw_baked(frame, eye, index, own.prepass_fbo, True)
            if self.method == "screen":
                self._screen(eye, own, depth, normal)
        ctx.disable(moderngl.DEPTH_TEST)
        res.put("ao", [t.ao for t in self.targets])

    def _draw_baked(
        self,
        frame: FrameContext,
        eye: EyeView,
        index: int,
        fbo: moderngl.Framebuffer,
        prepass: bool,
    ) -> None:
        """The baked occlusion of the visible surfaces into ``fbo`` (``prepass``: with its own
        depth and normals; otherwise over the G-buffer's depth, which is left as it is)."""
        ctx = self.ctx
        baked = self.method == "baked"
        prog = self.shaders.program(
            "geometry.vert.glsl", "ao_vertex.frag.glsl", {"AO_BAKED": baked, "PREPASS": prepass}
        )
        if prepass:
            fbo.clear(1.0, 0.0, 0.0, 0.0, depth=1.0)
        else:
            self.targets[index].ao_fbo.clear(1.0, 0.0, 0.0, 0.0)  # not the G-buffer's depth
            fbo.depth_mask = False
        fbo.use()
        ctx.enable(moderngl.DEPTH_TEST)
        ctx.depth_func = "<=" if not prepass else "<"
        set_uniforms(prog, {"u_view_projection": eye.view_projection})
        set_uniforms(prog, {}, optional={"u_ao_strength": self.strength})
        scene = frame.scene
        for g in scene.shown_groups():  # merged meshes (render.gpu_scene.GpuGroup)
            vao = scene.group_ao_vao(prog, g) if baked else scene.group_vao(prog, g)
            scene.draw_group(vao, g, eye.view_projection, eye)
        for mesh in scene.shown_standalone():
            vao = scene.ao_vao(prog, mesh) if baked else scene.vao(prog, mesh)
            scene.draw(vao, mesh, eye.view_projection, eye)
        if not prepass:
            fbo.depth_mask = True
            ctx.depth_func = "<"
        ctx.disable(moderngl.DEPTH_TEST)

    def _screen(
        self, eye: EyeView, own: AoTargets, depth: moderngl.Texture, normal: moderngl.Texture
    ) -> None:
        defines: dict[str, object] = {"AO_DIRECTIONS": AO_DIRECTIONS, "AO_STEPS": AO_STEPS}
        trace = self.shaders.program("fullscreen.vert.glsl", "ao_screen.frag.glsl", defines)
        proj = eye.projection
        common = {
            "u_depth_a": float(proj[2, 2]),
            "u_depth_b": float(proj[2, 3]),
        }
        own.raw_fbo.use()
        bind_texture(trace, "ao_depth", depth)
        bind_texture(trace, "ao_normal", normal)
        set_uniforms(
            trace,
            {
                **common,
                "u_view_projection": eye.view_projection,
                "u_inv_view_projection": eye.inverse_view_projection,
                "u_radius": self.radius_m,
                "u_size": own.size,
            },
        )
        self.fullscreen(trace)
        blur = self.shaders.program("fullscreen.vert.glsl", "ao_blur.frag.glsl")
        own.blurred_fbo.use()
        bind_texture(blur, "ao_raw", own.raw)
        self.fullscreen(blur)
        up = self.shaders.program("fullscreen.vert.glsl", "ao_upsample.frag.glsl")
        own.ao_fbo.use()
        bind_texture(up, "ao_raw", own.blurred)
        bind_texture(up, "ao_depth", depth)
        set_uniforms(up, {**common, "u_ao_strength": self.strength})
        self.fullscreen(up)

    def read(self, eye: int) -> np.ndarray:
        """One eye's occlusion image (H, W) float32 in [0, 1], row 0 at the top (tests)."""
        tex = self.targets[eye].ao
        data = np.frombuffer(tex.read(alignment=1), np.uint8).reshape(tex.size[1], tex.size[0])
        return np.flipud(data.astype(np.float32) / 255.0)

    def release(self) -> None:
        super().release()
        self._by_size.clear()
        self.targets = []
