"""The presenter's A/B split: each eye shows the technique left of a divider and the same view
at full quality right of it, with a divider line and a caption on each side.

The full-quality half is drawn by a second renderer (``render.ab_frame.ABFrame``, the quality
probe's reference settings) into its own target; :class:`ABSplitPass` runs after the present
pass of the live frame and copies that target's pixels right of the divider into each eye,
draws the divider and the captions, and leaves the overlay (gaze marker, statistics) to the
overlay pass after it. Without a split in the frame (``FrameContext.split is None``) the pass
does not run and the frame is exactly the normal one.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import moderngl
import numpy as np
from PIL import Image, ImageDraw, ImageFont

from app.settings import Settings
from render.cps import cps_mode
from render.pass_graph import FrameContext, RenderPass, Resources, bind_texture, set_uniforms
from render.shaders import ShaderLibrary

# The divider: a 2 px light line with a 1 px dark edge on each side (readable on any picture).
LINE_COLOUR = (1.0, 1.0, 1.0)
EDGE_COLOUR = (0.0, 0.0, 0.0)
CAPTION_GAP = 10  # px between the divider and a caption
EYE_MARGIN = 6  # px between a caption and the eye's edge
WITHOUT = "Without (full quality)"

# What each mitigation mode does, in plain words (cps.mode choices).
MITIGATION_WORDS = {
    "none": "",
    "black-mask": "the periphery darkened (black mask)",
    "blur-mask": "the periphery blurred (blur mask)",
    "cps": "coarse shading in the periphery",
}


@dataclass
class SplitView:
    """What the split shows: the divider as a share of each eye's width (0 = all full
    quality, 1 = all technique) and the caption of each side."""

    divider: float = 0.5
    left: str = ""
    right: str = WITHOUT

    def divider_px(self, eye_width: int) -> int:
        """The divider's x in an eye of ``eye_width`` pixels (the first full-quality column)."""
        share = min(max(float(self.divider), 0.0), 1.0) if np.isfinite(self.divider) else 0.5
        return int(round(share * eye_width))


@dataclass
class SplitFrame:
    """A frame's split: the full-quality frame (both eyes side by side, display colour, as
    big as the live view) and what to show."""

    reference: moderngl.Texture
    view: SplitView


def technique_caption(settings: Settings, has_photons: bool = False) -> str:
    """The left caption: what differs from full quality, in words a designer reads."""
    parts = []
    mode = settings.cps.mode
    if mode != "none":
        words = MITIGATION_WORDS.get(mode, mode)
        if cps_mode(settings) == "none":  # the masks and CPS run on the deferred path only
            words += " (needs the deferred rendering path)"
        parts.append(words)
    if settings.tcr.enabled:
        parts.append("texture detail chosen per object (TCR)")
    p = settings.photons
    if has_photons and (p.stereo_reuse or p.fused or p.gather != "radius"):
        parts.append("faster indirect light")
    if not parts:
        return "No technique on: both sides at full quality"
    return "With " + " and ".join(parts)


@functools.lru_cache(maxsize=4)
def _font(size: int) -> ImageFont.ImageFont | ImageFont.FreeTypeFont:
    try:
        return ImageFont.load_default(size=size)
    except TypeError:  # Pillow < 10.1 has no sized default font
        return ImageFont.load_default()


def wrap(text: str, font: ImageFont.ImageFont | ImageFont.FreeTypeFont, width: int) -> list[str]:
    """``text`` in lines no wider than ``width`` px (greedy, at spaces); [] when a single word
    does not fit."""
    probe = ImageDraw.Draw(Image.new("RGBA", (1, 1)))
    lines: list[str] = []
    for word in text.split():
        trial = f"{lines[-1]} {word}" if lines else word
        if lines and probe.textlength(trial, font=font) <= width:
            lines[-1] = trial
        elif probe.textlength(word, font=font) <= width:
            lines.append(word)
        else:
            return []
    return lines


def caption_image(text: str, size: int, max_width: int = 1 << 16) -> np.ndarray | None:
    """``text`` white on translucent black at ``size`` px, wrapped to fit ``max_width`` px;
    (h, w, 4) uint8, row 0 at the top; None when it cannot fit (a word wider than that)."""
    font = _font(size)
    pad = max(4, size // 3)
    lines = wrap(text, font, max_width - 2 * pad)
    if not lines:
        return None
    probe = ImageDraw.Draw(Image.new("RGBA", (1, 1)))
    boxes = [probe.textbbox((0, 0), line, font=font) for line in lines]
    line_h = int(max(b[3] for b in boxes)) + max(2, size // 6)
    width = int(max(b[2] for b in boxes)) + 2 * pad
    height = line_h * len(lines) + 2 * pad
    img = Image.new("RGBA", (width, height), (0, 0, 0, 170))
    draw = ImageDraw.Draw(img)
    for i, line in enumerate(lines):
        draw.text((pad, pad + i * line_h), line, font=font, fill=(255, 255, 255, 255))
    return np.asarray(img, np.uint8)


def caption_size(eye: tuple[int, int]) -> int:
    """Caption text height for an eye of (width, height) pixels: readable at a glance, never
    tiny, and small enough that a caption takes a line or two of its half."""
    w, h = eye
    return max(14, min(28, w // 24, h // 24))


def caption_rects(
    view: SplitView, eye: tuple[int, int], sizes: tuple[tuple[int, int], tuple[int, int]]
) -> list[tuple[int, int, int, int] | None]:
    """Where the (left, right) captions go in one eye: (x, y, w, h) from the eye's lower left,
    by the divider, near the bottom; None for a side too narrow to hold its caption (or
    without one: a width of 0)."""
    w, h = eye
    d = view.divider_px(w)
    margin = max(6, h // 40)
    out: list[tuple[int, int, int, int] | None] = []
    for side, (cw, ch) in enumerate(sizes):
        room = d if side == 0 else w - d
        if cw == 0 or room < cw + CAPTION_GAP:
            out.append(None)
            continue
        x = d - CAPTION_GAP - cw if side == 0 else d + CAPTION_GAP
        out.append((x, margin, cw, ch))
    return out


class ABSplitPass(RenderPass):
    """The split over the presented frame: full quality right of the divider in each eye, the
    divider line and the captions (only when the frame has a split)."""

    name = "ab_split"
    reads = ("out",)
    writes = ("out",)

    def __init__(self, ctx: moderngl.Context, shaders: ShaderLibrary, res: Resources) -> None:
        super().__init__(ctx, shaders, res)
        self._captions: dict[int, tuple[tuple[str, int, int], moderngl.Texture]] = {}
        # The caption rectangles of the last frame, (x, y, w, h) from an eye's lower left (the
        # same in both eyes), left side's first; None for a side without one.
        self.caption_rects: list[tuple[int, int, int, int] | None] = []

    def configure(self, settings, scene, frame) -> bool:
        return frame.split is not None

    def _caption(self, side: int, text: str, size: int, room: int) -> moderngl.Texture | None:
        """The texture of one side's caption, wrapped to ``room`` px (in steps of 32 px, so a
        dragged divider remakes it now and then, not every frame); made again only when its
        text, size or room changes."""
        room = room // 32 * 32
        key = (text, size, room)
        kept = self._captions.get(side)
        if kept is not None and kept[0] == key:
            return kept[1]
        if kept is not None:
            kept[1].release()
            del self._captions[side]
        img = caption_image(text, size, room) if text else None
        if img is None:
            return None
        h, w = img.shape[:2]
        tex = self.ctx.texture((w, h), 4, np.ascontiguousarray(np.flipud(img)).tobytes())
        tex.filter = (moderngl.NEAREST, moderngl.NEAREST)
        self._captions[side] = (key, tex)
        return tex

    def execute(self, frame: FrameContext, res: Resources) -> None:
        split: SplitFrame = frame.split
        view = split.view
        w, h = res.targets[0].size
        x0, y0 = frame.out_origin
        ctx = self.ctx
        frame.out.use()
        ctx.disable(moderngl.DEPTH_TEST | moderngl.BLEND)
        d = view.divider_px(w)
        prog = self.shaders.program("fullscreen.vert.glsl", "ab_split.frag.glsl")
        bind_texture(prog, "ab_reference", split.reference)
        set_uniforms(
            prog,
            {"u_divider": d, "u_line_colour": LINE_COLOUR, "u_edge_colour": EDGE_COLOUR},
        )
        left = max(0, d - 2)  # the line's dark left edge; nothing left of it is touched
        for eye in range(len(frame.eyes)):
            origin = (x0 + eye * w, y0)
            frame.out.viewport = (*origin, w, h)
            set_uniforms(prog, {"u_origin": origin, "u_reference_origin": (eye * w, 0)})
            ctx.scissor = (origin[0] + left, y0, w - left, h)
            self.fullscreen(prog)
        ctx.scissor = None
        self._draw_captions(frame, view, (w, h))
        frame.out.viewport = (x0, y0, 2 * w, h)

    def _draw_captions(self, frame: FrameContext, view: SplitView, eye: tuple[int, int]) -> None:
        w, h = eye
        size = caption_size(eye)
        d = view.divider_px(w)
        rooms = (d - CAPTION_GAP - EYE_MARGIN, w - d - CAPTION_GAP - EYE_MARGIN)
        texs = [
            self._caption(0, view.left, size, rooms[0]),
            self._caption(1, view.right, size, rooms[1]),
        ]
        sizes = tuple(t.size if t is not None else (0, 0) for t in texs)
        rects = self.caption_rects = caption_rects(view, eye, sizes)  # type: ignore[arg-type]
        prog = self.shaders.program("fullscreen.vert.glsl", "ab_split.frag.glsl", {"CAPTION": 1})
        ctx = self.ctx
        ctx.enable(moderngl.BLEND)
        # Colour blends; destination alpha stays 1 (as the overlay pass: Qt would see through).
        ctx.blend_func = (  # type: ignore[assignment]
            moderngl.SRC_ALPHA,
            moderngl.ONE_MINUS_SRC_ALPHA,
            moderngl.ZERO,
            moderngl.ONE,
        )
        x0, y0 = frame.out_origin
        for e in range(len(frame.eyes)):  # each eye its own captions, at the same place
            frame.out.viewport = (x0 + e * w, y0, w, h)
            for tex, rect in zip(texs, rects):
                if tex is None or rect is None:
                    continue
                x, y, cw, ch = rect
                cx, cy = x0 + e * w + x, y0 + y
                bind_texture(prog, "text", tex)
                set_uniforms(prog, {"u_caption_origin": (cx, cy)})
                # Kept inside this eye: a caption never spills into the other.
                sx0, sx1 = max(cx, x0 + e * w), min(cx + cw, x0 + (e + 1) * w)
                if sx1 <= sx0:
                    continue
                ctx.scissor = (sx0, cy, sx1 - sx0, min(ch, h - y))
                self.fullscreen(prog)
        ctx.scissor = None
        ctx.disable(moderngl.BLEND)

    def release(self) -> None:
        super().release()
        for _key, tex in self._captions.values():
            tex.release()
        self._captions.clear()
