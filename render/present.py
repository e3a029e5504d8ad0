"""The passes that put the frame on the screen: both eyes exposed, tone-mapped and enlarged
(EASU, RCAS) side by side (:class:`PresentPass`), then the overlay of text, gaze and the CPS
fovea (:class:`OverlayPass`). The frame's other passes are in ``render.passes``.
"""

from __future__ import annotations

import logging

import moderngl
import numpy as np

from render.constants import TEXTURE_UNITS
from render.cps import CpsFilterPass
from render.pass_graph import (
    BySize,
    FrameContext,
    RenderPass,
    Resources,
    bind_texture,
    set_uniforms,
    uniform,
)
from render.shaders import ShaderLibrary
from render.upscale import rcas_con, sharpen_stops, upscale_defines

log = logging.getLogger(__name__)


class PresentPass(RenderPass):
    """Both eyes side by side into the output, exposed (``frame.exposure``: 1 / L_max times
    the Brightness, see ``render.exposure``), tone-mapped (``render.tone_mapping``) and
    sRGB-encoded; with the CPS level map painted when visualised, and the photons' reuse when
    asked."""

    name = "present"
    reads = ("hdr",)
    optional_reads = ("levels", "indirect", "show_reuse")
    writes = ("out",)

    def __init__(self, ctx: moderngl.Context, shaders: ShaderLibrary, res: Resources) -> None:
        super().__init__(ctx, shaders, res)
        self.visualize = False
        # The CPS filter folded in (Renderer.fold_cps_filter): its pass (render.cps), whose
        # variant and inputs the reconstruction here uses, and whether light was added on top
        # of it in the eyes' colour (emissive glow); None: the colour holds the whole picture.
        self.fold: tuple[CpsFilterPass, bool] | None = None
        self.tone: dict[str, object] = {}
        self.upscaler = "easu"  # render.upscale.UPSCALERS: how eyes drawn smaller are enlarged
        self.sharpen = 0.0  # render.sharpen: RCAS after EASU, 0 off
        # Where RCAS runs: "pass", its own pass at the drawn size before EASU (measured the
        # cheapest: tests/measure_rcas.py), "folded" into EASU's taps (no extra target) or
        # "after" EASU at the view's size as in FSR (an intermediate target per eye).
        self.rcas_placement = "pass"
        self._sharpened = False  # this frame's eyes were sharpened into _display[2:]
        self._after: list[tuple[moderngl.Texture, moderngl.Framebuffer]] = []
        self._display: list[tuple[moderngl.Texture, moderngl.Framebuffer]] = []
        self._displays: BySize[list[tuple[moderngl.Texture, moderngl.Framebuffer]]] = BySize(
            self._make_display, _release_pairs
        )

    @staticmethod
    def defines(settings) -> dict[str, object]:
        """The tone curve's variant (render/shaders/exposure_tonemap.glsl): ACES, AgX or a
        clamp at white."""
        curve = settings.render.tone_mapping
        return {"TONE_ACES": curve == "aces", "TONE_AGX": curve == "agx"}

    def fold_filter(self, enabled: list[RenderPass], scene, allowed: bool) -> None:
        """Fold the CPS filter into this pass (``allowed``: ``Renderer.fold_cps_filter``)
        when no pass between them reads the eyes' colour or writes it other than by adding
        light: each pixel is then reconstructed as it is tone-mapped, one full-screen pass
        fewer (about 2 ms of the corridor's 115 at 2 x 640x720, nothing at the governor's
        walking scale: the reconstruction's own work moves with it, docs/governor_study.md).
        Reflections, the sky, glass, the temporal filter, refinement and automatic exposure
        read or paint over the colour, so with any of them the filter keeps its pass."""
        self.fold = None
        filt = next((p for p in enabled if isinstance(p, CpsFilterPass)), None)
        if not allowed or filt is None or self not in enabled or filt.temporal:
            return
        between = enabled[enabled.index(filt) + 1 : enabled.index(self)]
        touching = [p for p in between if "hdr" in (*p.reads, *p.optional_reads, *p.writes)]
        if not all(p.adds_to_hdr for p in touching):
            return
        adds = any(p.adds_light(scene) for p in touching)  # then cleared first (the glow)
        filt.folded, filt.clears = True, adds
        self.fold = (filt, adds)

    def configure(self, settings, scene, frame) -> bool:
        self.visualize = settings.cps.visualize
        self.tone = self.defines(settings)
        self.upscaler = "bilinear" if settings.render.upscaler == "bilinear" else "easu"
        self.sharpen = float(settings.render.sharpen)
        return True

    def execute(self, frame: FrameContext, res: Resources) -> None:
        levels = res.get("levels") if self.visualize else None
        indirect = res.get("indirect")
        show_reuse = bool(res.get("show_reuse")) and indirect is not None
        src = res.targets[0].size
        w, h = frame.view_size or src
        scaled = upscale_defines(src, (w, h), self.upscaler, self.sharpen)
        fold = self.fold
        folded: dict[str, object] = {}
        if fold is not None:
            folded = {"CPS_FOLD": True, "FOLD_ADD": fold[1], **fold[0].defines()}
        prog = self.shaders.program(
            "fullscreen.vert.glsl",
            "present.frag.glsl",
            {"VISUALIZE": levels is not None, "SHOW_REUSE": show_reuse, **self.tone, **folded},
        )
        x, y = frame.out_origin
        self.ctx.disable(moderngl.DEPTH_TEST | moderngl.BLEND)
        uniform(prog, "u_exposure").value = frame.exposure
        if scaled:  # tone-mapped at the drawn size first, enlarged below
            self._ensure_display(src)
        else:
            frame.out.use()
        for index, tgt in enumerate(res.targets):
            origin = (x + index * w, y)
            if scaled:
                self._display[index][1].use()
                self._display[index][1].viewport = (0, 0, *src)
                origin = (0, 0)
            else:
                frame.out.viewport = (*origin, w, h)
            uniform(prog, "u_origin").value = origin
            if fold is None or fold[1]:
                bind_texture(prog, "eye_color", tgt.color)
            if fold is not None:
                fold[0].bind(prog, res.cps[index], tgt.size)
            if levels is not None:
                bind_texture(prog, "levels", levels[index])
            if show_reuse:
                bind_texture(prog, "indirect", indirect[index])
                uniform(prog, "u_paint_reuse").value = index
            self.fullscreen(prog)
        if scaled:
            if scaled.get("RCAS") and self.rcas_placement == "after":  # as FSR: a view-size pass
                self._upscale(
                    frame, {**scaled, "RCAS": False}, src, (w, h), self._ensure_after((w, h))
                )
                self._sharpen_after(frame, (w, h))
            else:
                if scaled.get("RCAS") and self.rcas_placement == "pass":
                    self._sharpen(src)
                    scaled = {**scaled, "RCAS": False}
                self._upscale(frame, scaled, src, (w, h))
        frame.out.viewport = (x, y, 2 * w, h)

    def _ensure_display(self, size: tuple[int, int]) -> None:
        """Per eye the tone-mapped colour at the drawn size (rgba8), for the upscaler."""
        self._display = self._displays.get(size)

    def _make_display(
        self, size: tuple[int, int]
    ) -> list[tuple[moderngl.Texture, moderngl.Framebuffer]]:
        made = []
        for _ in range(4):  # per eye the tone-mapped colour, then (render.sharpen) sharpened
            tex = self.ctx.texture(size, 4)
            tex.filter = (moderngl.NEAREST, moderngl.NEAREST)
            tex.repeat_x = tex.repeat_y = False
            made.append((tex, self.ctx.framebuffer([tex])))
        return made

    def _sharpen(self, src: tuple[int, int]) -> None:
        """RCAS per eye at the drawn size, into the second pair of targets (render.sharpen)."""
        stops = sharpen_stops(self.sharpen)
        prog = self.shaders.program("fullscreen.vert.glsl", "rcas.frag.glsl")
        uniform(prog, "u_src_size").value = src
        uniform(prog, "u_origin").value = (0, 0)
        uniform(prog, "u_rcas_con").value = rcas_con(stops if stops is not None else 2.0)
        for index in range(2):
            fbo = self._display[2 + index][1]
            fbo.use()
            fbo.viewport = (0, 0, *src)
            bind_texture(prog, "eye_color", self._display[index][0])
            self.fullscreen(prog)
        self._sharpened = True

    def _upscale(
        self,
        frame: FrameContext,
        defines: dict[str, object],
        src: tuple[int, int],
        dst: tuple[int, int],
        into: list[moderngl.Framebuffer] | None = None,
    ) -> None:
        prog = self.shaders.program("fullscreen.vert.glsl", "upscale.frag.glsl", defines)
        frame.out.use()
        x, y = (0, 0) if into else frame.out_origin
        set_uniforms(prog, {"u_src_size": src, "u_dst_size": dst})
        stops = sharpen_stops(self.sharpen)
        if defines.get("RCAS") and stops is not None:
            uniform(prog, "u_rcas_con").value = rcas_con(stops)
        first = 2 if self._sharpened else 0
        self._sharpened = False
        for index, (tex, _fbo) in enumerate(self._display[first : first + 2]):
            origin = (x + index * dst[0], y) if not into else (0, 0)
            target = into[index] if into else frame.out
            target.use()
            target.viewport = (*origin, *dst)
            uniform(prog, "u_origin").value = origin
            bind_texture(prog, "eye_color", tex)
            self.fullscreen(prog)

    def _ensure_after(self, size: tuple[int, int]) -> list[moderngl.Framebuffer]:
        """Per eye EASU's output at the view's size, for RCAS placed after it ("after")."""
        if not self._after or self._after[0][0].size != size:
            self._release_after()
            for _ in range(2):
                tex = self.ctx.texture(size, 4)
                tex.filter = (moderngl.NEAREST, moderngl.NEAREST)
                self._after.append((tex, self.ctx.framebuffer([tex])))
        return [fbo for _tex, fbo in self._after]

    def _sharpen_after(self, frame: FrameContext, dst: tuple[int, int]) -> None:
        stops = sharpen_stops(self.sharpen)
        prog = self.shaders.program("fullscreen.vert.glsl", "rcas.frag.glsl")
        uniform(prog, "u_src_size").value = dst
        uniform(prog, "u_rcas_con").value = rcas_con(stops if stops is not None else 2.0)
        frame.out.use()
        x, y = frame.out_origin
        for index, (tex, _fbo) in enumerate(self._after):
            origin = (x + index * dst[0], y)
            frame.out.viewport = (*origin, *dst)
            uniform(prog, "u_origin").value = origin
            bind_texture(prog, "eye_color", tex)
            self.fullscreen(prog)

    def _release_after(self) -> None:
        for tex, fbo in self._after:
            fbo.release()
            tex.release()
        self._after.clear()

    def _release_display(self) -> None:
        self._displays.clear()
        self._display = []
        self._release_after()

    def release(self) -> None:
        super().release()
        self._release_display()


def _release_pairs(pairs: list[tuple[moderngl.Texture, moderngl.Framebuffer]]) -> None:
    for tex, fbo in pairs:
        fbo.release()
        tex.release()


class OverlayPass(RenderPass):
    """Statistics text (drawn by the host into a small RGBA image) and the gaze marker.

    Only the pixels it covers are touched (scissor rectangles), so it costs next to nothing.
    """

    name = "overlay"
    reads = ("out",)
    optional_reads = ("levels",)  # the edge-ray markers go with the level map's visualisation
    writes = ("out",)
    MARKER = 12

    def __init__(self, ctx: moderngl.Context, shaders: ShaderLibrary, res: Resources) -> None:
        super().__init__(ctx, shaders, res)
        self.text_rgba: np.ndarray | None = None
        self._text_tex: moderngl.Texture | None = None
        self._dirty = False
        self.show_text = True
        self._heat_tex: moderngl.Texture | None = None
        self.show_heat = True  # off while the quality probe renders the frame it measures
        self.show_markers = False

    def configure(self, settings, scene, frame) -> bool:
        self.show_text = settings.render.overlay
        self.show_markers = settings.cps.visualize
        return True

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

    def execute(self, frame: FrameContext, res: Resources) -> None:
        self._upload()
        prog = self.shaders.program("fullscreen.vert.glsl", "overlay.frag.glsl")
        w, h = frame.view_size or res.targets[0].size
        x0, y0 = frame.out_origin
        frame.out.use()
        frame.out.viewport = (x0, y0, 2 * w, h)
        ctx = self.ctx
        ctx.enable(moderngl.BLEND)
        # Colour blends; destination alpha stays 1, or Qt composites the view as translucent.
        # The stub types blend_func as a pair; moderngl also takes (rgb src, dst, alpha src, dst).
        ctx.blend_func = (  # type: ignore[assignment]
            moderngl.SRC_ALPHA,
            moderngl.ONE_MINUS_SRC_ALPHA,
            moderngl.ZERO,
            moderngl.ONE,
        )
        if self._heat_tex is not None and self.show_heat:
            heat = self.shaders.program("fullscreen.vert.glsl", "heatmap.frag.glsl")
            bind_texture(heat, "heat", self._heat_tex)
            set_uniforms(heat, {"u_origin": (x0, y0), "u_view_size": (2 * w, h)})
            self.fullscreen(heat)
        text_tex = self._text_tex if self.show_text else None
        show_text = text_tex is not None
        if text_tex is not None:
            tw, th = text_tex.size
            bind_texture(prog, "text", text_tex)
        else:
            tw, th = 0, 0
            # Nothing drawn: any texture will do.
            uniform(prog, "u_text").value = TEXTURE_UNITS["text"]
        uniform(prog, "u_text_size").value = (tw, th)
        uniform(prog, "u_view_size").value = (2 * w, h)
        uniform(prog, "u_origin").value = (x0, y0)
        gu, gv = frame.gaze
        uniform(prog, "u_gaze").value = (gu, gv)
        uniform(prog, "u_gaze_fixed").value = int(frame.gaze_fixed)
        uniform(prog, "u_show_text").value = int(show_text)
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
        markers = project_hits(frame, (w, h)) if self.show_markers and res.written("levels") else []
        for e, points in enumerate(markers):  # edge-ray hits: small magenta squares
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


def project_hits(
    frame: FrameContext, size: tuple[int, int] | None = None
) -> list[list[tuple[int, int]]]:
    """Edge-ray hit points as pixels of each eye (from the bottom-left) of ``size`` (default:
    the eye's drawn size); behind the eye: none."""
    out: list[list[tuple[int, int]]] = []
    hits_per_eye = frame.edge_hits
    for index, eye in enumerate(frame.eyes):
        points: list[tuple[int, int]] = []
        hits = hits_per_eye[index] if hits_per_eye and index < len(hits_per_eye) else None
        if hits is not None and len(hits):
            h = np.asarray(hits, np.float64).reshape(-1, 3)
            clip = np.c_[h, np.ones(len(h))] @ eye.view_projection.T
            ok = clip[:, 3] > 1e-9
            ndc = clip[ok, :2] / clip[ok, 3:4]
            ew, eh = size or (eye.width, eye.height)
            for x, y in ndc:
                points.append((int((x * 0.5 + 0.5) * ew), int((y * 0.5 + 0.5) * eh)))
        out.append(points)
    return out
