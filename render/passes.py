"""Render passes of the frame: each declares what it reads and writes (``render.pass_graph``),
owns its on/off rule (``configure``) and the GL objects it creates; none are made per frame.
The CPS passes live in ``render.cps``, the photon pass in ``render.photons``, the present and
overlay passes in ``render.present``.
"""

from __future__ import annotations

import logging
import math

import moderngl
import numpy as np

from app.camera import EyeView, gl_bytes
from render.ambient_field import bind_field
from render.constants import (
    ALL_LIGHTS,
    CPS_LEVEL_COLOURS,  # noqa: F401 - re-exported (ui.cps_panel, tests)
    LEVEL_TINTS,
    LIGHT_TILE,
    MAX_PER_TILE,
)
from render.gpu_scene import GpuScene
from render.materials import alpha_mask_defines, material_defines
from render.pass_graph import (
    FrameContext,
    RenderPass,
    Resources,
    bind_image,
    bind_texture,
    has,
    release_query,
    set_uniforms,
    uniform,
)
from render.shaders import ShaderLibrary

log = logging.getLogger(__name__)
BACKGROUND = (0.02, 0.02, 0.025)
CULL_MIN_LIGHTS = 8  # light culling runs for scenes with more lights than this


class EyeTargets:
    """One eye's G-buffer and HDR colour, resized with the view."""

    def __init__(self, ctx: moderngl.Context, width: int, height: int) -> None:
        self.size = (width, height)
        self.albedo = ctx.texture(self.size, 4)  # rgb albedo, a metallic
        self.normal = ctx.texture(self.size, 4, dtype="f2")  # xyz normal, w roughness
        self.depth = ctx.depth_texture(self.size)
        self.color = ctx.texture(self.size, 4, dtype="f2")  # linear HDR radiance
        self.sky = ctx.texture(self.size, 1)  # the share of the sky the surface sees
        for t in (self.albedo, self.normal, self.depth, self.color, self.sky):
            t.filter = (moderngl.NEAREST, moderngl.NEAREST)
            t.repeat_x = t.repeat_y = False
        self.gbuffer = ctx.framebuffer([self.albedo, self.normal, self.sky], self.depth)
        self.forward = ctx.framebuffer([self.color], self.depth)
        # Tiled light culling: a light count per 16x16 tile and each tile's list of lights.
        self.tiles = (-(-width // LIGHT_TILE), -(-height // LIGHT_TILE))
        self.tile_counts = ctx.texture(self.tiles, 1, dtype="u2")
        self.tile_lists = ctx.texture((self.tiles[0] * MAX_PER_TILE, self.tiles[1]), 1, dtype="u2")
        # Depth bounds halved four times (16 = 2^4): the last level has one texel per tile.
        self.bounds = []
        w, h = width, height
        for _ in range(4):
            w, h = -(-w // 2), -(-h // 2)
            self.bounds.append(ctx.texture((w, h), 2, dtype="f4"))
        self.bounds_fbos = [ctx.framebuffer([t]) for t in self.bounds]
        for t in (self.tile_counts, self.tile_lists, *self.bounds):
            t.filter = (moderngl.NEAREST, moderngl.NEAREST)

    def release(self) -> None:
        objects: list[moderngl.Framebuffer | moderngl.Texture] = [
            self.gbuffer,
            self.forward,
            self.albedo,
            self.normal,
            self.depth,
            self.color,
            self.sky,
            self.tile_counts,
            self.tile_lists,
            *self.bounds_fbos,
            *self.bounds,
        ]
        for obj in objects:
            obj.release()


def level_tint(level: int) -> tuple[float, float, float]:
    return LEVEL_TINTS[min(max(level, 0), len(LEVEL_TINTS) - 1)]


def deferred(settings) -> bool:
    return settings.render.path == "deferred"


def scene_uniforms(prog: moderngl.Program | moderngl.ComputeShader, frame: FrameContext) -> None:
    """The lights' count and scale and the ambient term. Optional: the geometry passes share
    this with variants (G-buffer, emissive) that shade nothing, so lack them."""
    set_uniforms(
        prog,
        {},
        optional={
            "u_light_count": len(frame.scene.lights),
            "u_light_scale": frame.light_scale,
            "u_ambient": frame.ambient,
            "u_ambient_gradient": tuple(frame.ambient_gradient),
            "u_occluder_return": frame.occluder_return,
        },
    )
    bind_field(prog, frame.ambient_field)


def _draw_meshes(
    ctx: moderngl.Context,
    shaders: ShaderLibrary,
    frame: FrameContext,
    eye: EyeView,
    fragment: str,
    order: list[int] | None = None,
    ao: moderngl.Texture | None = None,
    sky=None,
) -> int:
    """Draw meshes for one eye with their materials (maps, alpha mode and TCR mode as
    variants): ``order``, or every mesh that is not blended (the blend pass draws those);
    ``ao``: the eye's ambient occlusion the forward path shades with (render/ao.py). Only
    the chunks inside the eye's frustum are drawn; returns the triangles drawn."""
    scene = frame.scene
    drawn = 0
    streamer = scene.streamer
    tcr = frame.levels is not None

    def variant(defines: dict[str, object]) -> moderngl.Program:
        if not frame.normal_maps:  # render.normal_maps off: the flat variant, no map sampled
            defines.pop("HAS_TANGENTS", None)
        if ao is not None:
            defines["AO"] = True
        if sky is not None:  # the forward path's daylight (render.sky)
            defines["SKY"] = True
        if frame.ambient_field is not None and fragment == "forward.frag.glsl":
            defines["AMBIENT_FIELD"] = True  # the forward and blend paths shade
        if tcr:
            defines["TCR_PAPER" if frame.tcr_mode == "paper" else "TCR_CLAMP"] = True
            defines["TCR_TINT"] = frame.tint
        prog = shaders.program("geometry.vert.glsl", fragment, defines)
        uniform(prog, "u_view_projection").write(gl_bytes(eye.view_projection))
        if has(prog, "u_eye"):  # the forward and blend paths: they light the fragments themselves
            uniform(prog, "u_eye").value = tuple(eye.position)
            scene_uniforms(prog, frame)
            if sky is not None:
                sky.bind(prog)
        if ao is not None:
            bind_texture(prog, "ao", ao)
        return prog

    if order is None:
        # Merged groups (render.gpu_scene.GpuGroup): their per-object levels and tints come
        # from the object table; the meshes left standalone are drawn one by one below.
        if scene.groups:
            scene.write_object_table(frame.levels)
        for g in scene.shown_groups():
            group = scene.groups[g]
            if group.blended:  # the blend pass draws those, sorted
                continue
            prog = variant({**material_defines(group), "OBJECT_TABLE": True})
            scene.bind_group_material(prog, g)
            drawn += scene.draw_group(scene.group_vao(prog, g), g, eye.view_projection, eye)
        order = [i for i in scene.shown_standalone() if not scene.meshes[i].blended]
    else:
        order = [i for i in order if scene.shown(scene.meshes[i].material)]
        if scene.groups:
            scene.write_object_table(frame.levels)
    k = 0
    while k < len(order):
        index = order[k]
        g = scene.group_of.get(index, -1)
        if g >= 0:  # a run of one merged group's meshes in the order given: one draw
            run = [index]
            while k + len(run) < len(order) and scene.group_of.get(order[k + len(run)]) == g:
                run.append(order[k + len(run)])
            k += len(run)
            prog = variant({**material_defines(scene.groups[g]), "OBJECT_TABLE": True})
            scene.bind_group_material(prog, g)
            vao = scene.group_vao(prog, g)
            drawn += scene.draw_members(vao, run, eye.view_projection, eye)
            continue
        k += 1
        mesh = scene.meshes[index]
        prog = variant(material_defines(mesh))
        scene.bind_material(prog, index)
        level = frame.levels[index] if frame.levels is not None else 0
        if mesh.texture is not None:
            resident = streamer.resident[mesh.texture]
            # Only the TCR variants sample a chosen pyramid level.
            set_uniforms(prog, {}, optional={"u_level": float(level - resident.base)})
        # Only the TCR_TINT variant paints the level.
        set_uniforms(prog, {}, optional={"u_tint": level_tint(level)})
        drawn += scene.draw(scene.vao(prog, index), index, eye.view_projection, eye)
    return drawn


class GBufferPass(RenderPass):
    """Per eye: depth, world normal + roughness, albedo + metallic."""

    name = "gbuffer"
    writes = ("depth", "normal", "albedo")

    def configure(self, settings, scene, frame) -> bool:
        return deferred(settings)

    def execute(self, frame: FrameContext, res: Resources) -> None:
        ctx = self.ctx
        ctx.enable(moderngl.DEPTH_TEST)
        ctx.disable(moderngl.CULL_FACE | moderngl.BLEND)
        for eye, tgt in zip(frame.eyes, res.targets):
            tgt.gbuffer.use()
            tgt.gbuffer.clear(0.0, 0.0, 0.0, 0.0, depth=1.0)
            calls, ranges = frame.scene.draw_calls, frame.scene.draw_ranges
            drawn = _draw_meshes(ctx, self.shaders, frame, eye, "gbuffer.frag.glsl")
            frame.scene.drawn[eye.index] = drawn
            frame.scene.calls[eye.index] = frame.scene.draw_calls - calls
            frame.scene.ranges[eye.index] = frame.scene.draw_ranges - ranges
        ctx.disable(moderngl.DEPTH_TEST)


# What the deferred lighting uses when an earlier pass made it (deferred.glsl variants).
LIGHTING_EXTRAS = ("tile_lists", "indirect", "photon_map", "ao", "sky", "shadow_mask")


class LightingPass(RenderPass):
    """Deferred lighting at full rate, in a fragment shader (default: about a tenth faster on
    llvmpipe) or a compute shader (the CPS paper's)."""

    name = "lighting"
    reads = ("depth", "normal", "albedo")
    optional_reads = LIGHTING_EXTRAS
    writes = ("hdr",)

    def __init__(self, ctx: moderngl.Context, shaders: ShaderLibrary, res: Resources) -> None:
        super().__init__(ctx, shaders, res)
        self.stage = "compute"

    def configure(self, settings, scene, frame) -> bool:
        self.stage = settings.render.lighting
        # Full rate unless coarse pixel shading lights the blocks (the masks need it too).
        return deferred(settings) and settings.cps.mode != "cps"

    def execute(self, frame: FrameContext, res: Resources) -> None:
        frame.scene.light_buffer.bind_to_uniform_block(0)
        defines = lighting_defines(res, frame)
        prog: moderngl.Program | moderngl.ComputeShader
        if self.stage == "compute":
            prog = self.shaders.compute("lighting.comp.glsl", defines)
        else:
            prog = self.shaders.program("fullscreen.vert.glsl", "lighting.frag.glsl", defines)
        scene_uniforms(prog, frame)
        uniform(prog, "u_background").value = BACKGROUND
        self.samples = 0
        for index, (eye, tgt) in enumerate(zip(frame.eyes, res.targets)):
            w, h = tgt.size
            deferred_inputs(prog, res, eye, index)
            if isinstance(prog, moderngl.ComputeShader):  # the compute stage
                bind_image(tgt.color, "out")
                prog.run(math.ceil(w / 8), math.ceil(h / 8))
            else:
                tgt.forward.use()
                self.fullscreen(prog)
            self.samples += w * h
        if self.stage == "compute":
            self.ctx.memory_barrier(
                moderngl.TEXTURE_FETCH_BARRIER_BIT | moderngl.SHADER_IMAGE_ACCESS_BARRIER_BIT
            )


def lighting_defines(res: Resources, frame: FrameContext) -> dict[str, object]:
    """The deferred.glsl variant this frame needs (tile lists, photon-map indirect light,
    the even light by place)."""
    fused = res.get("photon_map")
    defines: dict[str, object] = {
        "AMBIENT_FIELD": frame.ambient_field is not None,
        "TILED_LIGHTS": res.written("tile_lists"),
        "INDIRECT": res.get("indirect") is not None,
        "AO": res.get("ao") is not None,  # ambient occlusion (render/ao.py)
        "SKY": res.get("sky") is not None,
    }
    if fused is not None:
        defines.update(INDIRECT_FUSED=True, **fused[1])
    mask = res.get("shadow_mask")  # render/shadow_mask.py
    if mask is not None:
        defines.update(mask.defines())
    return defines


def deferred_inputs(
    prog: moderngl.Program | moderngl.ComputeShader, res: Resources, eye: EyeView, index: int
) -> None:
    """What deferred.glsl's light_texel reads for one eye: the G-buffer, the tile light lists,
    the indirect light, the eye and the viewport size (units from TEXTURE_UNITS)."""
    tgt = res.targets[index]
    indirect = res.get("indirect")
    if indirect is not None:
        bind_texture(prog, "indirect", indirect[index])
    fused = res.get("photon_map")
    if fused is not None:
        fused[0].bind(prog)  # records and starts (pm_records, pm_starts)
    bind_texture(prog, "gb_albedo", tgt.albedo)
    bind_texture(prog, "gb_normal", tgt.normal)
    bind_texture(prog, "gb_depth", tgt.depth)
    if res.get("sky") is not None:
        res.get("sky").bind(prog)
        bind_texture(prog, "gb_sky", tgt.sky)
    use_tiles(prog, res, index)
    if res.get("ao") is not None:
        bind_texture(prog, "ao", res.get("ao")[index])
    if res.get("shadow_mask") is not None:
        res.get("shadow_mask").bind(prog, eye, index)
    set_uniforms(
        prog,
        {
            "u_inv_view_projection": eye.inverse_view_projection,
            "u_eye": tuple(eye.position),
            "u_size": tgt.size,
        },
    )


def use_tiles(prog: moderngl.Program | moderngl.ComputeShader, res: Resources, index: int) -> None:
    """Bind this eye's tiled light lists when light culling ran this frame."""
    if res.written("tile_lists"):
        tgt = res.targets[index]
        bind_texture(prog, "tile_counts", tgt.tile_counts)
        bind_texture(prog, "tile_lists", tgt.tile_lists)


class LightCullPass(RenderPass):
    """Per eye and 16x16 tile, the lights that can reach the tile's pixels (by range).

    Lighting then evaluates only those: in a 100-light room most lights cannot reach most of
    what one tile shows. ``evaluations()`` reports the light evaluations with and without."""

    name = "light_cull"
    reads = ("depth",)
    writes = ("tile_lists",)

    def configure(self, settings, scene, frame) -> bool:
        # With a handful of lights the culling pass costs more than it saves.
        return (
            deferred(settings)
            and settings.render.light_culling
            and len(scene.lights) > CULL_MIN_LIGHTS
        )

    def execute(self, frame: FrameContext, res: Resources) -> None:
        first = self.shaders.program(
            "fullscreen.vert.glsl", "depth_bounds.frag.glsl", {"FROM_DEPTH": True}
        )
        step = self.shaders.program("fullscreen.vert.glsl", "depth_bounds.frag.glsl")
        cull = self.shaders.compute("light_cull.comp.glsl")
        frame.scene.light_buffer.bind_to_uniform_block(0)
        uniform(cull, "u_light_count").value = len(frame.scene.lights)
        self.ctx.disable(moderngl.DEPTH_TEST | moderngl.BLEND)
        for eye, tgt in zip(frame.eyes, res.targets):
            # Tile depth ranges: four 2x2 min/max reductions in the graphics pipeline (on
            # llvmpipe far cheaper than shared-memory atomics in a compute shader).
            src_size = tgt.size
            for level, fbo in enumerate(tgt.bounds_fbos):
                if level == 0:
                    prog = first
                    bind_texture(prog, "depth", tgt.depth)
                else:
                    prog = step
                    bind_texture(prog, "bounds", tgt.bounds[level - 1])
                uniform(prog, "u_src_size").value = src_size
                fbo.use()
                self.fullscreen(prog)
                src_size = tgt.bounds[level].size
            bind_texture(cull, "bounds", tgt.bounds[-1])
            bind_image(tgt.tile_counts, "counts")
            bind_image(tgt.tile_lists, "lists")
            set_uniforms(
                cull,
                {
                    "u_view": eye.view,
                    "u_inv_projection": np.linalg.inv(eye.projection),
                    "u_size": tgt.size,
                    "u_tiles": tgt.tiles,
                },
            )
            cull.run(-(-tgt.tiles[0] // 8), -(-tgt.tiles[1] // 8))
        self.ctx.memory_barrier(
            moderngl.TEXTURE_FETCH_BARRIER_BIT | moderngl.SHADER_IMAGE_ACCESS_BARRIER_BIT
        )

    @staticmethod
    def evaluations(targets: list[EyeTargets], light_count: int) -> dict[str, int]:
        """Light evaluations of full-rate lighting last frame: with the tile lists, and with
        every light at every lit pixel (read back: on request only)."""
        culled = everything = 0
        for tgt in targets:
            w, h = tgt.size
            depth = np.frombuffer(tgt.depth.read(), np.float32).reshape(h, w)
            lit = depth < 1.0
            tx, ty = tgt.tiles
            pad = np.zeros((ty * LIGHT_TILE, tx * LIGHT_TILE), bool)
            pad[:h, :w] = lit
            per_tile = pad.reshape(ty, LIGHT_TILE, tx, LIGHT_TILE).sum(axis=(1, 3))
            counts = np.frombuffer(tgt.tile_counts.read(alignment=1), np.uint16)
            counts = counts.reshape(ty, tx).astype(np.int64)
            counts[counts == ALL_LIGHTS] = light_count
            culled += int((counts * per_tile).sum())
            everything += int(lit.sum()) * light_count
        return {"culled": culled, "all": everything}


class EmissivePass(RenderPass):
    """Deferred path: add the glow of emissive meshes on top of the lit image."""

    name = "emissive"
    reads = ("depth", "hdr")
    writes = ("hdr",)
    adds_to_hdr = True  # blended ONE, ONE: the colour under it is not read (render.cps fold)

    def configure(self, settings, scene, frame) -> bool:
        return deferred(settings)

    @staticmethod
    def emitters(scene: GpuScene) -> tuple[list[int], list[int]]:
        """The standalone meshes and the merged groups that glow (blended ones are the blend
        pass's)."""
        meshes = [
            i
            for i in scene.shown_standalone()
            if any(scene.meshes[i].material.emissive) and not scene.meshes[i].blended
        ]
        groups = [
            g
            for g in scene.shown_groups()
            if any(scene.groups[g].material.emissive) and not scene.groups[g].blended
        ]
        return meshes, groups

    def adds_light(self, scene: GpuScene) -> bool:
        """Whether this frame adds anything to the colour."""
        return any(self.emitters(scene))

    def execute(self, frame: FrameContext, res: Resources) -> None:
        scene = frame.scene
        emitters, groups = self.emitters(scene)
        if not emitters and not groups:
            return
        ctx = self.ctx
        ctx.memory_barrier(moderngl.FRAMEBUFFER_BARRIER_BIT)  # after the compute lighting
        ctx.enable(moderngl.DEPTH_TEST | moderngl.BLEND)
        ctx.depth_func = "<="
        ctx.blend_func = moderngl.ONE, moderngl.ONE
        for eye, tgt in zip(frame.eyes, res.targets):
            tgt.forward.use()
            tgt.forward.depth_mask = False
            for g in groups:
                group = scene.groups[g]
                defines = {
                    **alpha_mask_defines(group),
                    "HAS_EMISSIVE_MAP": "emissive_map" in (group.maps or {}),
                    "UNLIT": group.material.unlit,
                    "OBJECT_TABLE": True,
                }
                prog = self.shaders.program(
                    "geometry.vert.glsl",
                    "emissive.frag.glsl",
                    {k: v for k, v in defines.items() if v},
                )
                uniform(prog, "u_view_projection").write(gl_bytes(eye.view_projection))
                scene.bind_group_material(prog, g)
                scene.draw_group(scene.group_vao(prog, g), g, eye.view_projection, eye)
            for index in emitters:
                mesh = scene.meshes[index]
                defines = {
                    **alpha_mask_defines(mesh),
                    "HAS_EMISSIVE_MAP": "emissive_map" in (mesh.maps or {}),
                    "UNLIT": mesh.material.unlit,
                }
                prog = self.shaders.program(
                    "geometry.vert.glsl",
                    "emissive.frag.glsl",
                    {k: v for k, v in defines.items() if v},
                )
                uniform(prog, "u_view_projection").write(gl_bytes(eye.view_projection))
                scene.bind_material(prog, index)
                scene.draw(scene.vao(prog, index), index, eye.view_projection, eye)
            tgt.forward.depth_mask = True
        ctx.depth_func = "<"
        ctx.disable(moderngl.DEPTH_TEST | moderngl.BLEND)


class ForwardPass(RenderPass):
    """The baseline: geometry lit per fragment, straight into each eye's HDR target."""

    name = "forward"
    optional_reads = ("ao", "sky")
    writes = ("depth", "hdr")

    def __init__(self, ctx: moderngl.Context, shaders: ShaderLibrary, res: Resources) -> None:
        super().__init__(ctx, shaders, res)
        self._samples_query = ctx.query(samples=True)

    def configure(self, settings, scene, frame) -> bool:
        return not deferred(settings)

    def execute(self, frame: FrameContext, res: Resources) -> None:
        ctx = self.ctx
        frame.scene.light_buffer.bind_to_uniform_block(0)
        ctx.enable(moderngl.DEPTH_TEST)
        ctx.disable(moderngl.CULL_FACE | moderngl.BLEND)
        ao = res.get("ao")
        with self._samples_query:
            for index, (eye, tgt) in enumerate(zip(frame.eyes, res.targets)):
                tgt.forward.use()
                tgt.forward.clear(*BACKGROUND, 1.0, depth=1.0)
                eye_ao = ao[index] if ao is not None else None
                calls, ranges = frame.scene.draw_calls, frame.scene.draw_ranges
                frame.scene.drawn[eye.index] = _draw_meshes(
                    ctx,
                    self.shaders,
                    frame,
                    eye,
                    "forward.frag.glsl",
                    ao=eye_ao,
                    sky=res.get("sky"),
                )
                frame.scene.calls[eye.index] = frame.scene.draw_calls - calls
                frame.scene.ranges[eye.index] = frame.scene.draw_ranges - ranges
        self.samples = int(self._samples_query.samples)
        ctx.disable(moderngl.DEPTH_TEST)

    def release(self) -> None:
        super().release()
        release_query(self._samples_query)


class BlendPass(RenderPass):
    """Blended (glass) meshes over the lit opaque picture of either path: sorted back to front
    per mesh (by the distance of its bounding-box centre to the eye), lit per fragment with the
    forward path's light loop, depth-tested against the opaque depth but not writing it. Runs
    after the lighting and emissive passes (and a sky drawn into the background), before the
    presenter."""

    name = "blend"
    reads = ("depth", "hdr")
    optional_reads = ("sky",)  # daylight on glass too
    writes = ("hdr",)

    def configure(self, settings, scene, frame) -> bool:
        return any(m.blended for m in scene.meshes)

    def execute(self, frame: FrameContext, res: Resources) -> None:
        ctx = self.ctx
        scene = frame.scene
        blended = [i for i, m in enumerate(scene.meshes) if m.blended]
        ctx.memory_barrier(moderngl.FRAMEBUFFER_BARRIER_BIT)  # after the compute lighting
        scene.light_buffer.bind_to_uniform_block(0)
        ctx.enable(moderngl.DEPTH_TEST | moderngl.BLEND)
        ctx.disable(moderngl.CULL_FACE)
        # Colour over what is behind; the target's alpha is left alone.
        ctx.blend_func = (  # type: ignore[assignment]
            moderngl.SRC_ALPHA,
            moderngl.ONE_MINUS_SRC_ALPHA,
            moderngl.ZERO,
            moderngl.ONE,
        )
        for eye, tgt in zip(frame.eyes, res.targets):
            order = back_to_front(scene, blended, eye.position)
            tgt.forward.use()
            tgt.forward.depth_mask = False
            _draw_meshes(
                ctx, self.shaders, frame, eye, "forward.frag.glsl", order, sky=res.get("sky")
            )
            tgt.forward.depth_mask = True
        ctx.blend_func = moderngl.SRC_ALPHA, moderngl.ONE_MINUS_SRC_ALPHA
        ctx.disable(moderngl.DEPTH_TEST | moderngl.BLEND)


def back_to_front(scene, indices: list[int], eye: np.ndarray) -> list[int]:
    """Mesh indices ordered farthest first (by bounding-box centre); ties by index."""
    if not indices:
        return []
    centres = np.array([scene.meshes[i].centre for i in indices], np.float64)
    far = -np.sum((centres - np.asarray(eye, np.float64)) ** 2, axis=1)
    return [indices[k] for k in np.lexsort((np.asarray(indices), far))]


class ObjectIdPass(RenderPass):
    """Which mesh covers each pixel, per eye; on request only (error masks), not every frame."""

    name = "ids"

    def __init__(self, ctx: moderngl.Context, shaders: ShaderLibrary, res: Resources) -> None:
        super().__init__(ctx, shaders, res)
        self._targets: list[tuple[moderngl.Texture, moderngl.Texture, moderngl.Framebuffer]] = []
        self.result: list[np.ndarray] = []

    def _ensure(self, size: tuple[int, int]) -> None:
        if self._targets and self._targets[0][0].size == size:
            return
        self._release_targets()
        for _ in range(2):
            ids = self.ctx.texture(size, 1, dtype="f4")
            depth = self.ctx.depth_texture(size)
            self._targets.append((ids, depth, self.ctx.framebuffer([ids], depth)))

    def execute(self, frame: FrameContext, res: Resources) -> None:
        self._ensure(frame.view_size or res.targets[0].size)  # window pixels, at any scale
        self.ctx.enable(moderngl.DEPTH_TEST)
        self.ctx.disable(moderngl.BLEND)
        self.result = []
        scene = frame.scene
        for eye, (ids, _depth, fbo) in zip(frame.eyes, self._targets):
            fbo.use()
            fbo.clear(0.0, 0.0, 0.0, 0.0, depth=1.0)
            for g in scene.shown_groups():  # the mesh index comes per vertex
                group = scene.groups[g]
                defines = {**alpha_mask_defines(group), "OBJECT_TABLE": True}
                prog = self.shaders.program("geometry.vert.glsl", "ids.frag.glsl", defines)
                set_uniforms(prog, {"u_view_projection": eye.view_projection})
                scene.bind_group_material(prog, g, ("albedo",))
                scene.draw_group(scene.group_vao(prog, g), g, eye.view_projection, eye)
            for index in scene.shown_standalone():
                mesh = scene.meshes[index]
                # Masked materials are cut out here too: a hole shows what lies behind.
                prog = self.shaders.program(
                    "geometry.vert.glsl", "ids.frag.glsl", alpha_mask_defines(mesh)
                )
                set_uniforms(prog, {"u_view_projection": eye.view_projection})
                scene.bind_material(prog, index, ("albedo",))
                uniform(prog, "u_id").value = float(index + 1)
                scene.draw(scene.vao(prog, index), index, eye.view_projection, eye)
            data = np.frombuffer(ids.read(), np.float32).reshape(ids.size[1], ids.size[0])
            self.result.append(np.flipud(data).astype(np.int32) - 1)
        self.ctx.disable(moderngl.DEPTH_TEST)

    def _release_targets(self) -> None:
        for ids, depth, fbo in self._targets:
            fbo.release()
            ids.release()
            depth.release()
        self._targets.clear()

    def release(self) -> None:
        super().release()
        self._release_targets()
