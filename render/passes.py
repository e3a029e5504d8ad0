"""Render passes: small classes with named inputs and outputs, an ``enabled`` flag and a timer.

A frame is a short list of these (see ``Renderer.render``). Each pass owns the GL objects it
creates and releases them; none are created per frame.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass
from typing import Any

import moderngl
import numpy as np

from app.camera import EyeView, gl_bytes
from render.gpu_scene import GpuScene
from render.shaders import ShaderLibrary

log = logging.getLogger(__name__)
BACKGROUND = (0.02, 0.02, 0.025)
LIGHT_TILE = 16  # must match light_tiles.glsl
MAX_PER_TILE = 128
ALL_LIGHTS = 65535


class EyeTargets:
    """One eye's G-buffer and HDR colour, resized with the view."""

    def __init__(self, ctx: moderngl.Context, width: int, height: int) -> None:
        self.size = (width, height)
        self.albedo = ctx.texture(self.size, 4)  # rgb albedo, a metallic
        self.normal = ctx.texture(self.size, 4, dtype="f2")  # xyz normal, w roughness
        self.depth = ctx.depth_texture(self.size)
        self.color = ctx.texture(self.size, 4, dtype="f2")  # linear HDR radiance
        for t in (self.albedo, self.normal, self.depth, self.color):
            t.filter = (moderngl.NEAREST, moderngl.NEAREST)
            t.repeat_x = t.repeat_y = False
        self.gbuffer = ctx.framebuffer([self.albedo, self.normal], self.depth)
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
        for obj in (
            self.gbuffer,
            self.forward,
            self.albedo,
            self.normal,
            self.depth,
            self.color,
            self.tile_counts,
            self.tile_lists,
            *self.bounds_fbos,
            *self.bounds,
        ):
            obj.release()


# CPS detail visualisation (paper Fig. 2): finest unpainted, then blue, cyan, green, yellow, red.
CPS_LEVEL_COLOURS = (
    (1.0, 1.0, 1.0),
    (0.15, 0.35, 1.0),
    (0.0, 0.9, 0.9),
    (0.1, 0.85, 0.1),
    (1.0, 0.95, 0.0),
    (1.0, 0.1, 0.1),
)

# Level legend for the TCR tint: level 0 unpainted, then blue, cyan, green, yellow, orange, red.
LEVEL_TINTS = (
    (1.0, 1.0, 1.0),
    (0.15, 0.35, 1.0),
    (0.0, 0.9, 0.9),
    (0.1, 0.85, 0.1),
    (1.0, 0.95, 0.0),
    (1.0, 0.55, 0.0),
    (1.0, 0.1, 0.1),
)


def level_tint(level: int) -> tuple[float, float, float]:
    return LEVEL_TINTS[min(max(level, 0), len(LEVEL_TINTS) - 1)]


@dataclass
class FrameContext:
    """What every pass of one frame may read."""

    eyes: list[EyeView]
    targets: list[EyeTargets]
    scene: GpuScene
    light_scale: float
    ambient: float
    exposure: float
    out: moderngl.Framebuffer
    out_origin: tuple[int, int]  # lower-left of the stereo view inside ``out``
    gaze: tuple[float, float]
    gaze_fixed: bool
    levels: list[int] | None = None  # TCR level per mesh (None: full quality)
    tcr_mode: str = "clamp"
    tint: bool = False
    culled: bool = False  # tiled light lists are ready (LightCullPass ran this frame)
    level_maps: list[moderngl.Texture] | None = None  # CPS detail visualisation, per eye
    markers: list[list[tuple[int, int]]] | None = None  # per eye, pixels from the bottom-left
    indirect: list[moderngl.Texture] | None = None  # photon irradiance per eye (PhotonPass)
    # photons.fused: the photon map and the gather's defines, for the lighting shader itself
    fused_photons: tuple[Any, dict[str, object]] | None = None
    show_reuse: bool = False  # paint the right eye's reused / gathered indirect pixels


class RenderPass:
    name = "pass"

    def __init__(self, ctx: moderngl.Context, shaders: ShaderLibrary) -> None:
        self.ctx = ctx
        self.shaders = shaders
        self.enabled = True
        self._query = ctx.query(time=True)
        self.last_ms = 0.0
        self.samples = 0  # shaded samples in the last frame, where the pass knows them
        self._fullscreen_vaos: dict[int, moderngl.VertexArray] = {}

    def run(self, frame: FrameContext) -> None:
        if not self.enabled:
            self.last_ms = 0.0
            return
        with self._query:
            self.execute(frame)
        self.last_ms = self._query.elapsed / 1e6

    def execute(self, frame: FrameContext) -> None:
        raise NotImplementedError  # each pass defines its work

    def fullscreen(self, prog: moderngl.Program) -> None:
        """Draw one viewport-covering triangle with ``prog`` (no vertex buffer)."""
        vao = self._fullscreen_vaos.get(prog.glo)
        if vao is None:
            vao = self._fullscreen_vaos[prog.glo] = self.ctx.vertex_array(prog, [])
        vao.render(moderngl.TRIANGLES, vertices=3)

    def release(self) -> None:
        _release_query(self._query)
        for vao in self._fullscreen_vaos.values():
            vao.release()
        self._fullscreen_vaos.clear()


def _scene_uniforms(prog: moderngl.Program, frame: FrameContext) -> None:
    for name, value in (
        ("u_light_count", len(frame.scene.lights)),
        ("u_light_scale", frame.light_scale),
        ("u_ambient", frame.ambient),
    ):
        if name in prog:
            prog[name].value = value


def _draw_meshes(
    ctx: moderngl.Context, shaders: ShaderLibrary, frame: FrameContext, eye: EyeView, fragment: str
) -> None:
    """Draw every mesh for one eye with its material (texture and TCR mode as variants)."""
    streamer = frame.scene.streamer
    tcr = frame.levels is not None
    for index, mesh in enumerate(frame.scene.meshes):
        defines: dict[str, object] = {"HAS_TEXTURE": mesh.texture is not None}
        if tcr:
            defines["TCR_PAPER" if frame.tcr_mode == "paper" else "TCR_CLAMP"] = True
            defines["TCR_TINT"] = frame.tint
        prog = shaders.program("geometry.vert.glsl", fragment, defines)
        prog["u_view_projection"].write(gl_bytes(eye.view_projection))
        prog["u_base_color"].value = tuple(mesh.material.base_color)
        if "u_roughness" in prog:
            prog["u_roughness"].value = mesh.material.roughness
        if "u_metallic" in prog:
            prog["u_metallic"].value = mesh.material.metallic
        if "u_eye" in prog:
            prog["u_eye"].value = tuple(eye.position)
            _scene_uniforms(prog, frame)
        if "u_emissive" in prog:
            prog["u_emissive"].value = tuple(mesh.material.emissive)
        level = frame.levels[index] if frame.levels is not None else 0
        if mesh.texture is not None:
            resident = streamer.resident[mesh.texture]
            resident.tex.use(0)
            prog["u_albedo"].value = 0
            if "u_level" in prog:
                prog["u_level"].value = float(level - resident.base)
        if "u_tint" in prog:
            prog["u_tint"].value = level_tint(level)
        frame.scene.vao(prog, index).render(moderngl.TRIANGLES)


class GBufferPass(RenderPass):
    """Per eye: depth, world normal + roughness, albedo + metallic."""

    name = "gbuffer"

    def execute(self, frame: FrameContext) -> None:
        ctx = self.ctx
        ctx.enable(moderngl.DEPTH_TEST)
        ctx.disable(moderngl.CULL_FACE | moderngl.BLEND)
        for eye, tgt in zip(frame.eyes, frame.targets):
            tgt.gbuffer.use()
            tgt.gbuffer.clear(0.0, 0.0, 0.0, 0.0, depth=1.0)
            _draw_meshes(ctx, self.shaders, frame, eye, "gbuffer.frag.glsl")
        ctx.disable(moderngl.DEPTH_TEST)


class LightingPass(RenderPass):
    """Deferred lighting at full rate, in a compute shader (default) or a fragment shader."""

    name = "lighting"

    def __init__(self, ctx: moderngl.Context, shaders: ShaderLibrary) -> None:
        super().__init__(ctx, shaders)
        self.stage = "compute"

    def execute(self, frame: FrameContext) -> None:
        frame.scene.light_buffer.bind_to_uniform_block(0)
        defines = lighting_defines(frame)
        if self.stage == "compute":
            prog = self.shaders.compute("lighting.comp.glsl", defines)
        else:
            prog = self.shaders.program("fullscreen.vert.glsl", "lighting.frag.glsl", defines)
        _scene_uniforms(prog, frame)
        prog["u_background"].value = BACKGROUND
        self.samples = 0
        for eye, tgt in zip(frame.eyes, frame.targets):
            w, h = tgt.size
            deferred_inputs(prog, frame, eye, tgt)
            if self.stage == "compute":
                tgt.color.bind_to_image(0, read=False, write=True)
                prog.run(math.ceil(w / 8), math.ceil(h / 8))
            else:
                tgt.forward.use()
                self.fullscreen(prog)
            self.samples += w * h
        if self.stage == "compute":
            self.ctx.memory_barrier(
                moderngl.TEXTURE_FETCH_BARRIER_BIT | moderngl.SHADER_IMAGE_ACCESS_BARRIER_BIT
            )


def lighting_defines(frame: FrameContext) -> dict[str, object]:
    """The deferred.glsl variant this frame needs (tile lists, photon-map indirect light)."""
    defines: dict[str, object] = {
        "TILED_LIGHTS": frame.culled,
        "INDIRECT": frame.indirect is not None,
    }
    if frame.fused_photons is not None:
        defines.update(INDIRECT_FUSED=True, **frame.fused_photons[1])
    return defines


def deferred_inputs(
    prog: moderngl.Program, frame: FrameContext, eye: EyeView, tgt: EyeTargets
) -> None:
    """What deferred.glsl's light_texel reads for one eye: the G-buffer (units 1-3), the tile
    light lists, the indirect light (unit 8), the eye and the viewport size."""
    if frame.indirect is not None and "u_indirect" in prog:
        frame.indirect[frame.targets.index(tgt)].use(8)
        prog["u_indirect"].value = 8
    if frame.fused_photons is not None:
        frame.fused_photons[0].bind(prog)  # records and starts on units 8 and 9
    tgt.albedo.use(1)
    tgt.normal.use(2)
    tgt.depth.use(3)
    prog["u_gb_albedo"].value, prog["u_gb_normal"].value, prog["u_gb_depth"].value = 1, 2, 3
    use_tiles(prog, frame, tgt)
    prog["u_inv_view_projection"].write(gl_bytes(eye.inverse_view_projection))
    prog["u_eye"].value = tuple(eye.position)
    prog["u_size"].value = tgt.size


def use_tiles(prog: moderngl.Program, frame: FrameContext, tgt: EyeTargets) -> None:
    """Bind this eye's tiled light lists (units 6 and 7) when the program reads them."""
    if frame.culled and "u_tile_counts" in prog:
        tgt.tile_counts.use(6)
        tgt.tile_lists.use(7)
        prog["u_tile_counts"].value, prog["u_tile_lists"].value = 6, 7


class LightCullPass(RenderPass):
    """Per eye and 16x16 tile, the lights that can reach the tile's pixels (by range).

    Lighting then evaluates only those: in a 100-light room most lights cannot reach most of
    what one tile shows. ``evaluations()`` reports the light evaluations with and without."""

    name = "light_cull"

    def execute(self, frame: FrameContext) -> None:
        first = self.shaders.program(
            "fullscreen.vert.glsl", "depth_bounds.frag.glsl", {"FROM_DEPTH": True}
        )
        step = self.shaders.program("fullscreen.vert.glsl", "depth_bounds.frag.glsl")
        cull = self.shaders.compute("light_cull.comp.glsl")
        frame.scene.light_buffer.bind_to_uniform_block(0)
        cull["u_light_count"].value = len(frame.scene.lights)
        self.ctx.disable(moderngl.DEPTH_TEST | moderngl.BLEND)
        for eye, tgt in zip(frame.eyes, frame.targets):
            # Tile depth ranges: four 2x2 min/max reductions in the graphics pipeline (on
            # llvmpipe far cheaper than shared-memory atomics in a compute shader).
            src_size = tgt.size
            for level, fbo in enumerate(tgt.bounds_fbos):
                prog = first if level == 0 else step
                if level == 0:
                    tgt.depth.use(3)
                    prog["u_depth"].value = 3
                else:
                    tgt.bounds[level - 1].use(3)
                    prog["u_bounds"].value = 3
                prog["u_src_size"].value = src_size
                fbo.use()
                self.fullscreen(prog)
                src_size = tgt.bounds[level].size
            tgt.bounds[-1].use(3)
            cull["u_bounds"].value = 3
            tgt.tile_counts.bind_to_image(1, read=False, write=True)
            tgt.tile_lists.bind_to_image(2, read=False, write=True)
            cull["u_view"].write(gl_bytes(eye.view))
            cull["u_inv_projection"].write(gl_bytes(np.linalg.inv(eye.projection)))
            cull["u_size"].value = tgt.size
            cull["u_tiles"].value = tgt.tiles
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

    def execute(self, frame: FrameContext) -> None:
        emitters = [i for i, m in enumerate(frame.scene.meshes) if any(m.material.emissive)]
        if not emitters:
            return
        ctx = self.ctx
        ctx.memory_barrier(moderngl.FRAMEBUFFER_BARRIER_BIT)  # after the compute lighting
        ctx.enable(moderngl.DEPTH_TEST | moderngl.BLEND)
        ctx.depth_func = "<="
        ctx.blend_func = moderngl.ONE, moderngl.ONE
        prog = self.shaders.program("geometry.vert.glsl", "emissive.frag.glsl")
        for eye, tgt in zip(frame.eyes, frame.targets):
            tgt.forward.use()
            tgt.forward.depth_mask = False
            prog["u_view_projection"].write(gl_bytes(eye.view_projection))
            for index in emitters:
                prog["u_emissive"].value = tuple(frame.scene.meshes[index].material.emissive)
                frame.scene.vao(prog, index).render(moderngl.TRIANGLES)
            tgt.forward.depth_mask = True
        ctx.depth_func = "<"
        ctx.disable(moderngl.DEPTH_TEST | moderngl.BLEND)


class ForwardPass(RenderPass):
    """The baseline: geometry lit per fragment, straight into each eye's HDR target."""

    name = "forward"

    def __init__(self, ctx: moderngl.Context, shaders: ShaderLibrary) -> None:
        super().__init__(ctx, shaders)
        self._samples_query = ctx.query(samples=True)

    def execute(self, frame: FrameContext) -> None:
        ctx = self.ctx
        frame.scene.light_buffer.bind_to_uniform_block(0)
        ctx.enable(moderngl.DEPTH_TEST)
        ctx.disable(moderngl.CULL_FACE | moderngl.BLEND)
        with self._samples_query:
            for eye, tgt in zip(frame.eyes, frame.targets):
                tgt.forward.use()
                tgt.forward.clear(*BACKGROUND, 1.0, depth=1.0)
                _draw_meshes(ctx, self.shaders, frame, eye, "forward.frag.glsl")
        self.samples = int(self._samples_query.samples)
        ctx.disable(moderngl.DEPTH_TEST)

    def release(self) -> None:
        super().release()
        _release_query(self._samples_query)


class PresentPass(RenderPass):
    """Both eyes side by side into the output, tone-mapped and sRGB-encoded."""

    name = "present"

    def execute(self, frame: FrameContext) -> None:
        visualize = frame.level_maps is not None
        show_reuse = frame.show_reuse and frame.indirect is not None
        prog = self.shaders.program(
            "fullscreen.vert.glsl",
            "present.frag.glsl",
            {"VISUALIZE": visualize, "SHOW_REUSE": show_reuse},
        )
        if visualize:
            prog["u_levels"].value = 1
        if show_reuse:
            prog["u_indirect"].value = 2
        w, h = frame.targets[0].size
        frame.out.use()
        x, y = frame.out_origin
        self.ctx.disable(moderngl.DEPTH_TEST | moderngl.BLEND)
        prog["u_eye_color"].value = 0
        prog["u_exposure"].value = frame.exposure
        for index, tgt in enumerate(frame.targets):
            origin = (x + index * w, y)
            frame.out.viewport = (*origin, w, h)
            prog["u_origin"].value = origin
            tgt.color.use(0)
            if visualize:
                frame.level_maps[index].use(1)
            if show_reuse:
                frame.indirect[index].use(2)
                prog["u_paint_reuse"].value = index
            self.fullscreen(prog)
        frame.out.viewport = (x, y, 2 * w, h)


class OverlayPass(RenderPass):
    """Statistics text (drawn by the host into a small RGBA image) and the gaze marker.

    Only the pixels it covers are touched (scissor rectangles), so it costs next to nothing.
    """

    name = "overlay"
    MARKER = 12

    def __init__(self, ctx: moderngl.Context, shaders: ShaderLibrary) -> None:
        super().__init__(ctx, shaders)
        self.text_rgba: np.ndarray | None = None
        self._text_tex: moderngl.Texture | None = None
        self._dirty = False
        self.show_text = True
        self._heat_tex: moderngl.Texture | None = None
        self.show_heat = True  # off while the quality probe renders the frame it measures

    def set_heat_map(self, rgba: np.ndarray | None) -> None:
        """An (h, w, 4) uint8 error heat map over the whole view (row 0 at the top; drawn
        stretched to the view), or None to hide it."""
        if self._heat_tex is not None:
            self._heat_tex.release()
            self._heat_tex = None
        if rgba is not None:
            h, w = rgba.shape[:2]
            self._heat_tex = self.ctx.texture(
                (w, h), 4, np.ascontiguousarray(np.flipud(rgba)).tobytes()
            )
            self._heat_tex.filter = (moderngl.NEAREST, moderngl.NEAREST)

    def set_text_image(self, rgba: np.ndarray | None) -> None:
        """An (h, w, 4) uint8 image, row 0 at the top; None hides the text."""
        self.text_rgba = rgba
        self._dirty = True

    def _upload(self) -> None:
        if not self._dirty:
            return
        self._dirty = False
        img = self.text_rgba
        if img is None:
            return
        h, w = img.shape[:2]
        if self._text_tex is None or self._text_tex.size != (w, h):
            if self._text_tex is not None:
                self._text_tex.release()
            self._text_tex = self.ctx.texture((w, h), 4)
            self._text_tex.filter = (moderngl.NEAREST, moderngl.NEAREST)
        self._text_tex.write(np.ascontiguousarray(np.flipud(img)).tobytes())

    def execute(self, frame: FrameContext) -> None:
        self._upload()
        prog = self.shaders.program("fullscreen.vert.glsl", "overlay.frag.glsl")
        w, h = frame.targets[0].size
        x0, y0 = frame.out_origin
        frame.out.use()
        frame.out.viewport = (x0, y0, 2 * w, h)
        ctx = self.ctx
        ctx.enable(moderngl.BLEND)
        # Colour blends; destination alpha stays 1, or Qt composites the view as translucent.
        ctx.blend_func = (
            moderngl.SRC_ALPHA,
            moderngl.ONE_MINUS_SRC_ALPHA,
            moderngl.ZERO,
            moderngl.ONE,
        )
        if self._heat_tex is not None and self.show_heat:
            heat = self.shaders.program("fullscreen.vert.glsl", "heatmap.frag.glsl")
            self._heat_tex.use(0)
            heat["u_heat"].value = 0
            heat["u_origin"].value = (x0, y0)
            heat["u_view_size"].value = (2 * w, h)
            self.fullscreen(heat)
        show_text = self.show_text and self._text_tex is not None
        tw, th = self._text_tex.size if show_text else (0, 0)
        if show_text:
            self._text_tex.use(0)
        prog["u_text"].value = 0
        prog["u_text_size"].value = (tw, th)
        prog["u_view_size"].value = (2 * w, h)
        prog["u_origin"].value = (x0, y0)
        gu, gv = frame.gaze
        prog["u_gaze"].value = (gu, gv)
        prog["u_gaze_fixed"].value = int(frame.gaze_fixed)
        prog["u_show_text"].value = int(show_text)
        rects = []
        if show_text:
            rects.append((x0, y0 + h - th, tw, th))
        r = self.MARKER
        for e in (0, 1):
            cx = x0 + int((e + gu) * w)
            cy = y0 + int((1.0 - gv) * h)
            rects.append((cx - r, cy - r, 2 * r, 2 * r))
        for rect in rects:
            ctx.scissor = rect
            self.fullscreen(prog)
        ctx.scissor = None
        ctx.disable(moderngl.BLEND)
        for e, points in enumerate(frame.markers or []):  # edge-ray hits: small magenta squares
            for px, py in points:
                if -3 <= px <= w + 2 and -3 <= py <= h + 2:  # on the view's edge: kept inside
                    px, py = min(max(px, 2), w - 3), min(max(py, 2), h - 3)
                    frame.out.clear(
                        1.0, 0.0, 1.0, 1.0, viewport=(x0 + e * w + px - 2, y0 + py - 2, 5, 5)
                    )

    def release(self) -> None:
        super().release()
        if self._text_tex is not None:
            self._text_tex.release()
        self.set_heat_map(None)


def _release_query(query: moderngl.Query) -> None:
    # moderngl 5.x exposes no Query.release(); its glo is freed with the context.
    release = getattr(query, "release", None) or getattr(query.mglo, "release", None)
    if release is not None:
        release()


class ObjectIdPass(RenderPass):
    """Which mesh covers each pixel, per eye; on request only (error masks), not every frame."""

    name = "ids"

    def __init__(self, ctx: moderngl.Context, shaders: ShaderLibrary) -> None:
        super().__init__(ctx, shaders)
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

    def execute(self, frame: FrameContext) -> None:
        self._ensure(frame.targets[0].size)
        prog = self.shaders.program("geometry.vert.glsl", "ids.frag.glsl")
        self.ctx.enable(moderngl.DEPTH_TEST)
        self.ctx.disable(moderngl.BLEND)
        self.result = []
        for eye, (ids, _depth, fbo) in zip(frame.eyes, self._targets):
            fbo.use()
            fbo.clear(0.0, 0.0, 0.0, 0.0, depth=1.0)
            prog["u_view_projection"].write(gl_bytes(eye.view_projection))
            for index in range(len(frame.scene.meshes)):
                prog["u_id"].value = float(index + 1)
                frame.scene.vao(prog, index).render(moderngl.TRIANGLES)
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
