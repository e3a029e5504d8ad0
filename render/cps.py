"""Coarse pixel shading (SPEC C): level map, coarse lighting, reconstruction, masks, temporal.

The deferred frame becomes, per eye::

    G-buffer -> level map (half resolution, one texel per 2x2 block)
             -> lighting at block rate  (fragment: a pass per level into an atlas;
                                         compute: multi-level or single dispatch)
             -> filter (none / ordinary bilinear / hierarchical) -> [temporal] -> eye colour

The masks (black, blur) instead run the ordinary full-rate lighting and darken or blur the
periphery where CPS would lower the detail. The formulas live in the shaders (cps_*.glsl) and,
as a numpy reference the tests compare against, in ``app/cps.py``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import moderngl
import numpy as np

from app.camera import EyeView
from app.cps import MAX_LEVEL
from app.settings import CpsSettings
from render.pass_graph import (
    BySize,
    FrameContext,
    RenderPass,
    Resources,
    bind_image,
    bind_texture,
    release_all,
    set_uniforms,
    uniform,
)
from render.passes import (
    BACKGROUND,
    LIGHTING_EXTRAS,
    EyeTargets,
    deferred,
    deferred_inputs,
    lighting_defines,
    scene_uniforms,
)
from render.shaders import ShaderLibrary


@dataclass
class CpsFrame:
    """What the coarse shading needs besides the G-buffer, per eye."""

    settings: CpsSettings
    caps: list[tuple[float, float, float]]  # side caps per eye: left, right, bottom
    frame_index: int = 0  # alternation of the temporal filter
    hits: list[np.ndarray] = field(default_factory=list)  # edge-ray hits (world), drawn if shown


def cps_mode(settings) -> str:
    """The CPS mode this frame runs: CPS and the masks need the deferred path."""
    return settings.cps.mode if deferred(settings) else "none"


def atlas_layout(width: int, height: int) -> tuple[tuple[int, int], list[tuple[int, int]]]:
    """Atlas size and the lower-left corner of each level's rectangle (level s is
    ceil(W / 2^s) x ceil(H / 2^s)): level 0 at the origin, the others side by side above it."""
    offsets = [(0, 0)]
    x = 0
    for s in range(1, MAX_LEVEL + 1):
        offsets.append((x, height))
        x += -(-width // (1 << s))
    return (max(width, x), height + -(-height // 2)), offsets


def gaze_view_dir(eye: EyeView, gaze: tuple[float, float]) -> tuple[float, float, float]:
    """View-space unit ray of this eye through the gaze point (clamped into the viewport)."""
    u = min(1.0, max(0.0, gaze[0] if math.isfinite(gaze[0]) else 0.5))
    v = min(1.0, max(0.0, gaze[1] if math.isfinite(gaze[1]) else 0.5))
    p = np.linalg.inv(eye.projection) @ np.array([2 * u - 1, 1 - 2 * v, -1.0, 1.0])
    d = p[:3] / p[3]
    d /= np.linalg.norm(d)
    return float(d[0]), float(d[1]), float(d[2])


def fovea_rect(
    eye: EyeView, gaze: tuple[float, float], caps: tuple[float, float, float], s: CpsSettings
) -> tuple[int, int, int, int] | None:
    """A pixel rectangle (x, y, w, h from the bottom-left) holding every full-rate (level 0)
    pixel of this eye, or None when that can be anywhere.

    With both side caps at least 1 the cap is >= 1 everywhere, so a pixel stays at level 0
    only if its 2x2 block's centre lies within the fovea: inside a cone of fovea_deg around
    the gaze ray (plus a degree and a few pixels of margin). The fragment pipeline's level-0
    pass is scissored to it: a full-screen pass that discards nearly everything is not free on
    llvmpipe.
    """
    if s.max_level < 1 or min(caps[0], caps[1]) < 1:
        return None
    half = math.radians(s.fovea_deg + 1.0)
    if not math.isfinite(half) or half >= math.radians(75.0):
        return None
    g = np.array(gaze_view_dir(eye, gaze))
    a = np.cross(g, (0.0, 1.0, 0.0))
    if np.linalg.norm(a) < 1e-6:
        a = np.cross(g, (1.0, 0.0, 0.0))
    a /= np.linalg.norm(a)
    b = np.cross(g, a)
    t = np.linspace(0.0, 2.0 * math.pi, 64, endpoint=False)
    dirs = math.cos(half) * g[None, :] + math.sin(half) * (
        np.cos(t)[:, None] * a + np.sin(t)[:, None] * b
    )
    if (dirs[:, 2] >= -1e-3).any():  # part of the cone is beside or behind the eye
        return None
    clip = np.c_[dirs, np.ones(len(dirs))] @ eye.projection.T
    ndc = clip[:, :2] / clip[:, 3:4]
    px = (ndc * 0.5 + 0.5) * np.array([eye.width, eye.height])
    margin = 4 + 0.02 * max(eye.width, eye.height)  # chords between the samples, 2x2 blocks
    x0 = max(0, int(math.floor(px[:, 0].min() - margin)))
    y0 = max(0, int(math.floor(px[:, 1].min() - margin)))
    x1 = min(eye.width, int(math.ceil(px[:, 0].max() + margin)))
    y1 = min(eye.height, int(math.ceil(px[:, 1].max() + margin)))
    if x1 <= x0 or y1 <= y0:
        return (0, 0, 0, 0)
    return (x0, y0, x1 - x0, y1 - y0)


def detail_uniforms(
    prog: moderngl.Program,
    eye: EyeView,
    gaze: tuple[float, float],
    caps: tuple[float, float, float],
    s: CpsSettings,
) -> None:
    set_uniforms(
        prog,
        {
            "u_size": (eye.width, eye.height),
            "u_inv_projection": np.linalg.inv(eye.projection),
            "u_gaze_dir": gaze_view_dir(eye, gaze),
            "u_caps": tuple(float(c) for c in caps),
            "u_fovea_deg": float(s.fovea_deg),
            "u_deg_per_level": float(s.deg_per_level),
            "u_max_level": int(min(max(s.max_level, 0), MAX_LEVEL)),
        },
    )


class CpsEyeTargets:
    """One eye's CPS textures, made with the eye targets' size."""

    def __init__(self, ctx: moderngl.Context, eye: EyeTargets) -> None:
        width, height = eye.size
        self.eye = eye
        self.size = (width, height)
        half = (-(-width // 2), -(-height // 2))
        self.levels = ctx.texture(half, 1, dtype="u1")
        self.atlas_size, self.atlas_offsets = atlas_layout(width, height)
        self.atlas = ctx.texture(self.atlas_size, 4, dtype="f2")
        self.blocks = ctx.texture(self.size, 4, dtype="f2")  # compute output / lit for masks
        self.filtered = ctx.texture(self.size, 4, dtype="f2")  # before the temporal filter
        self.history = [ctx.texture(self.size, 4, dtype="f2") for _ in range(2)]
        self.lit = ctx.texture(self.size, 4, dtype="f2")
        self.lit.build_mipmaps()  # allocates the chain the blur mask reads
        for t in (self.levels, self.atlas, self.blocks, self.filtered, *self.history):
            t.filter = (moderngl.NEAREST, moderngl.NEAREST)
            t.repeat_x = t.repeat_y = False
        self.lit.filter = (moderngl.LINEAR_MIPMAP_LINEAR, moderngl.LINEAR)
        self.lit.repeat_x = self.lit.repeat_y = False
        self.levels_fbo = ctx.framebuffer([self.levels])
        self.atlas_fbo = ctx.framebuffer([self.atlas])
        self.filtered_fbo = ctx.framebuffer([self.filtered])
        self.lit_fbo = ctx.framebuffer([self.lit])
        # The temporal filter writes the eye's colour and the next history together.
        self.temporal_fbos = [ctx.framebuffer([eye.color, h]) for h in self.history]
        self.history_index = 0  # which history texture holds the previous frame
        self.has_history = False
        self.prev_view_projection = np.eye(4)
        self.prev_eye = np.zeros(3)

    def release(self) -> None:
        objects: list[moderngl.Framebuffer | moderngl.Texture] = [
            self.levels_fbo,
            self.atlas_fbo,
            self.filtered_fbo,
            self.lit_fbo,
            *self.temporal_fbos,
            self.levels,
            self.atlas,
            self.blocks,
            self.filtered,
            *self.history,
            self.lit,
        ]
        for obj in objects:
            obj.release()


class CpsState:
    """The CPS targets of both eyes (and whether the level maps hold a frame's levels).

    Made on first use (:attr:`eyes`), not when the eye targets change: a frame without
    coarse shading makes none. At 640x720 they took 75 ms to make, and 6-8 ms at the
    governor's render scales: each new scale's first frame paid it with CPS off."""

    def __init__(self, ctx: moderngl.Context) -> None:
        self.ctx = ctx
        self._eyes: list[CpsEyeTargets] = []
        self.level_maps_valid = False
        self._for: list[EyeTargets] = []  # the eye targets the CPS targets are for
        # Kept for the eye targets' last sizes, as the renderer keeps those (BySize).
        self._by_size: BySize[list[CpsEyeTargets]] = BySize(
            lambda _size: [CpsEyeTargets(self.ctx, t) for t in self._for], release_all
        )

    def ensure(self, targets: list[EyeTargets]) -> None:
        """The CPS targets are to serve these eye targets (those kept for them, or made anew
        when a pass first asks)."""
        if len(self._for) == len(targets) and all(a is b for a, b in zip(self._for, targets)):
            return  # the same eye targets: what is made for them (or not yet) stands
        self._for = targets
        self._eyes = []
        self.level_maps_valid = False

    @property
    def eyes(self) -> list[CpsEyeTargets]:
        """Each eye's CPS targets for the eye targets last ensured (made on first use)."""
        if self._for and not self._serves(self._eyes, self._for):
            eyes = self._by_size.get(self._for[0].size)
            if not self._serves(eyes, self._for):  # the eye targets of that size were made anew
                self._by_size.drop(self._for[0].size)
                eyes = self._by_size.get(self._for[0].size)
            for e in eyes:  # frames of another size came between: their history is not this
                e.has_history = False
            self._eyes = eyes
        return self._eyes

    def made(self) -> list[CpsEyeTargets]:
        """The CPS targets made so far for the eye targets last ensured (none are made)."""
        return self._eyes

    @staticmethod
    def _serves(eyes: list[CpsEyeTargets], targets: list[EyeTargets]) -> bool:
        return len(eyes) == len(targets) and all(c.eye is t for c, t in zip(eyes, targets))

    def read_levels(self) -> list[np.ndarray]:
        """Each eye's level per pixel, (H, W) uint8, row 0 at the top (empty if not made)."""
        if not self.level_maps_valid:
            return []
        out = []
        for e in self._eyes:
            w, h = e.levels.size
            half = np.frombuffer(e.levels.read(alignment=1), np.uint8).reshape(h, w)
            full = np.repeat(np.repeat(half, 2, axis=0), 2, axis=1)[: e.size[1], : e.size[0]]
            out.append(np.ascontiguousarray(np.flipud(full)))
        return out

    def release(self) -> None:
        self._by_size.clear()
        self._eyes = []
        self._for = []


class CpsPass(RenderPass):
    """A CPS pass: its targets are the CPS state's (``res.cps_state``), the frame's detail
    inputs ``frame.cps`` (a CpsFrame)."""

    @property
    def state(self) -> CpsState:
        return self.res.cps_state


class CpsLevelPass(CpsPass):
    """The half-resolution level map of each eye."""

    name = "cps_levels"
    writes = ("levels",)

    def configure(self, settings, scene, frame) -> bool:
        on = deferred(settings) and (cps_mode(settings) == "cps" or settings.cps.visualize)
        self.state.level_maps_valid = self.state.level_maps_valid and on
        return on

    def execute(self, frame: FrameContext, res: Resources) -> None:
        cf = frame.cps
        prog = self.shaders.program("fullscreen.vert.glsl", "cps_levels.frag.glsl")
        self.ctx.disable(moderngl.DEPTH_TEST | moderngl.BLEND)
        for index, (eye, tgt) in enumerate(zip(frame.eyes, res.cps)):
            detail_uniforms(prog, eye, frame.gaze, cf.caps[index], cf.settings)
            weak = cf.settings.temporal and (cf.frame_index + index) % 2 == 1
            uniform(prog, "u_level_offset").value = 1 if weak else 0
            tgt.levels_fbo.use()
            self.fullscreen(prog)
        self.state.level_maps_valid = True


class CpsLightingPass(CpsPass):
    """Lighting once per block: per level into the atlas (fragment) or in compute."""

    name = "cps_lighting"
    reads = ("depth", "normal", "albedo", "levels")
    optional_reads = LIGHTING_EXTRAS
    writes = ("blocks",)

    def __init__(self, ctx: moderngl.Context, shaders: ShaderLibrary, res: Resources) -> None:
        super().__init__(ctx, shaders, res)
        self.stage = "fragment"
        self.dispatch = "multi"

    def configure(self, settings, scene, frame) -> bool:
        self.stage = settings.render.lighting
        self.dispatch = settings.cps.dispatch
        return cps_mode(settings) == "cps"

    def execute(self, frame: FrameContext, res: Resources) -> None:
        cf = frame.cps
        frame.scene.light_buffer.bind_to_uniform_block(0)
        compute = self.stage == "compute"
        defines = lighting_defines(res, frame)
        prog: moderngl.Program | moderngl.ComputeShader
        if compute:
            prog = self.shaders.compute(
                "cps_lighting.comp.glsl", {"MULTI_LEVEL": self.dispatch == "multi", **defines}
            )
        else:
            prog = self.shaders.program("fullscreen.vert.glsl", "cps_lighting.frag.glsl", defines)
        scene_uniforms(prog, frame)
        uniform(prog, "u_background").value = BACKGROUND
        max_level = int(min(max(cf.settings.max_level, 0), MAX_LEVEL))
        self.ctx.disable(moderngl.DEPTH_TEST | moderngl.BLEND)
        for index, (eye, tgt, cps) in enumerate(zip(frame.eyes, res.targets, res.cps)):
            w, h = tgt.size
            deferred_inputs(prog, res, eye, index)
            bind_texture(prog, "levels", cps.levels)
            if isinstance(prog, moderngl.ComputeShader):  # compute
                bind_image(cps.blocks, "out")
                if self.dispatch == "multi":
                    for s in range(max_level + 1):
                        uniform(prog, "u_level").value = s
                        bw, bh = -(-w // (1 << s)), -(-h // (1 << s))
                        prog.run(math.ceil(bw / 8), math.ceil(bh / 8))
                else:
                    prog.run(math.ceil(math.ceil(w / 32) / 8), math.ceil(math.ceil(h / 32) / 8))
            else:
                cps.atlas_fbo.use()
                for s in range(max_level + 1):
                    ox, oy = cps.atlas_offsets[s]
                    cps.atlas_fbo.viewport = (ox, oy, -(-w // (1 << s)), -(-h // (1 << s)))
                    # Level 0 lies in the fovea: the full-size pass only covers that.
                    cps.atlas_fbo.scissor = (
                        fovea_rect(eye, frame.gaze, cf.caps[index], cf.settings) if s == 0 else None
                    )
                    uniform(prog, "u_level").value = s
                    uniform(prog, "u_atlas_offset").value = (ox, oy)
                    self.fullscreen(prog)
                cps.atlas_fbo.scissor = None
        if compute:
            self.ctx.memory_barrier(
                moderngl.TEXTURE_FETCH_BARRIER_BIT | moderngl.SHADER_IMAGE_ACCESS_BARRIER_BIT
            )


class CpsFilterPass(CpsPass):
    """Blocks back to pixels: raw, ordinary bilinear or the paper's hierarchical filter.

    Folded (``folded``, set by the renderer when no pass between this one and the present
    pass needs the pixels): the present pass reconstructs each pixel as it tone-maps it
    (``present.frag.glsl``, CPS_FOLD), which saves writing and reading the eye's colour once a
    frame. This pass then only clears the colour for the passes that add light to it (the
    glow of emissive meshes, ``clears``), and :meth:`resolve` draws the reconstruction into
    the colour when someone reads it (``Renderer.read_hdr``)."""

    name = "cps_filter"
    reads = ("levels", "blocks")
    writes = ("hdr",)  # or "filtered", before the temporal filter

    def __init__(self, ctx: moderngl.Context, shaders: ShaderLibrary, res: Resources) -> None:
        super().__init__(ctx, shaders, res)
        self.from_atlas = True
        self.kind = "hierarchical"
        self.temporal = False
        self.folded = False  # the present pass reconstructs this frame (the renderer decides)
        self.clears = False  # folded: clear the colour for light added on top of it
        self._resolved = True  # the colour holds this frame's reconstruction

    def configure(self, settings, scene, frame) -> bool:
        self.from_atlas = settings.render.lighting == "fragment"
        self.kind = settings.cps.filter
        self.temporal = bool(settings.cps.temporal)
        self.writes = ("filtered",) if self.temporal else ("hdr",)
        self.folded = self.clears = False
        self._resolved = True
        return cps_mode(settings) == "cps"

    def defines(self) -> dict[str, object]:
        """The reconstruction's variant (cps_reconstruct.glsl), for this pass or the present."""
        return {
            "FROM_ATLAS": self.from_atlas,
            "FILTER_HIERARCHICAL": self.kind == "hierarchical",
            "FILTER_BILINEAR": self.kind == "bilinear",
        }

    def bind(self, prog: moderngl.Program, cps, size: tuple[int, int]) -> None:
        """One eye's blocks and level map for the reconstruction in ``prog``."""
        set_uniforms(prog, {}, optional={"u_size": size})  # optimised out unfiltered
        bind_texture(prog, "levels", cps.levels, optional=True)  # raw blocks need none
        if self.from_atlas:
            bind_texture(prog, "atlas", cps.atlas)
            uniform(prog, "u_atlas_offsets").write(np.array(cps.atlas_offsets, np.int32).tobytes())
        else:
            bind_texture(prog, "blocks", cps.blocks)

    def execute(self, frame: FrameContext, res: Resources) -> None:
        self._resolved = not self.folded
        if self.folded:
            if self.clears:
                for tgt in res.targets:
                    tgt.forward.depth_mask = False  # the G-buffer's depth stays
                    tgt.forward.clear(0.0, 0.0, 0.0, 0.0)
                    tgt.forward.depth_mask = True
            return
        self._draw(res, add=False)

    def resolve(self) -> None:
        """Draw a folded frame's reconstruction into the eyes' colour (once), over the light
        the later passes added to it: the colour then holds what the present pass showed."""
        if self._resolved:
            return
        self._resolved = True
        self._draw(self.res, add=self.clears)

    def _draw(self, res: Resources, add: bool) -> None:
        prog = self.shaders.program("fullscreen.vert.glsl", "cps_filter.frag.glsl", self.defines())
        self.ctx.memory_barrier(moderngl.FRAMEBUFFER_BARRIER_BIT)
        self.ctx.disable(moderngl.DEPTH_TEST | moderngl.BLEND)
        if add:
            self.ctx.enable(moderngl.BLEND)
            self.ctx.blend_func = moderngl.ONE, moderngl.ONE
        for tgt, cps in zip(res.targets, res.cps):
            self.bind(prog, cps, tgt.size)
            fbo = cps.filtered_fbo if self.temporal else tgt.forward
            fbo.use()
            self.fullscreen(prog)
        self.ctx.disable(moderngl.BLEND)


class CpsMaskPass(CpsPass):
    """Black or blur mask over the full-rate lighting (the paper's comparisons)."""

    name = "cps_mask"
    reads = ("hdr",)
    writes = ("hdr",)

    def __init__(self, ctx: moderngl.Context, shaders: ShaderLibrary, res: Resources) -> None:
        super().__init__(ctx, shaders, res)
        self.black = True

    def configure(self, settings, scene, frame) -> bool:
        mode = cps_mode(settings)
        self.black = mode == "black-mask"
        return mode in ("black-mask", "blur-mask")

    def execute(self, frame: FrameContext, res: Resources) -> None:
        cf = frame.cps
        black = self.black
        prog = self.shaders.program(
            "fullscreen.vert.glsl", "cps_mask.frag.glsl", {"BLACK_MASK": black}
        )
        self.ctx.memory_barrier(
            moderngl.FRAMEBUFFER_BARRIER_BIT | moderngl.TEXTURE_FETCH_BARRIER_BIT
        )
        self.ctx.disable(moderngl.DEPTH_TEST | moderngl.BLEND)
        for index, (eye, tgt, cps) in enumerate(zip(frame.eyes, res.targets, res.cps)):
            self.ctx.copy_framebuffer(cps.lit_fbo, tgt.forward)
            if not black:
                cps.lit.build_mipmaps()
            detail_uniforms(prog, eye, frame.gaze, cf.caps[index], cf.settings)
            bind_texture(prog, "lit", cps.lit)
            tgt.forward.use()
            self.fullscreen(prog)


class CpsTemporalPass(CpsPass):
    """Alternating temporal filter with optional reprojection of the history."""

    name = "cps_temporal"
    reads = ("filtered", "depth", "levels")  # and its own history of the previous frame
    writes = ("hdr", "history")

    def configure(self, settings, scene, frame) -> bool:
        on = cps_mode(settings) == "cps" and settings.cps.temporal
        if not on:
            self.reset()
        return on

    def execute(self, frame: FrameContext, res: Resources) -> None:
        cf = frame.cps
        s = cf.settings
        prog = self.shaders.program(
            "fullscreen.vert.glsl", "cps_temporal.frag.glsl", {"REPROJECT": s.reproject}
        )
        self.ctx.disable(moderngl.DEPTH_TEST | moderngl.BLEND)
        for index, (eye, tgt, cps) in enumerate(zip(frame.eyes, res.targets, res.cps)):
            weak = (cf.frame_index + index) % 2 == 1  # this frame is the finer one
            previous = cps.history[cps.history_index]
            fbo = cps.temporal_fbos[1 - cps.history_index]
            bind_texture(prog, "current", cps.filtered)
            bind_texture(prog, "history", previous)
            bind_texture(prog, "gb_depth", tgt.depth)
            bind_texture(prog, "levels", cps.levels)
            w = float(s.history_weight)
            set_uniforms(
                prog,
                {
                    "u_inv_view_projection": eye.inverse_view_projection,
                    "u_eye": tuple(eye.position),
                    "u_size": tgt.size,
                    "u_current_weight": w if weak else 1.0 - w,
                    "u_has_history": int(cps.has_history),
                },
                # The REPROJECT variant only.
                optional={
                    "u_prev_view_projection": cps.prev_view_projection,
                    "u_prev_eye": tuple(float(v) for v in cps.prev_eye),
                },
            )
            fbo.use()
            self.fullscreen(prog)
            cps.history_index = 1 - cps.history_index
            cps.has_history = True
            cps.prev_view_projection = eye.view_projection.copy()
            cps.prev_eye = np.asarray(eye.position, np.float64).copy()

    def reset(self) -> None:
        """Forget the history (scene change, mode change, a jump along the path)."""
        for cps in self.state.made():  # those not made yet have none
            cps.has_history = False
