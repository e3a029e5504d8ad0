"""The screen-space shadow mask: the lights' shadow factors once per frame, at reduced resolution.

Without it, the deferred lighting looks up every shadowed light's map at every pixel (four
bilinear comparisons each for soft shadows); on llvmpipe both sides of a branch run, so a light
out of a pixel's reach still pays for its lookups, and eight shadowed lamps cost 2.3x the
unshadowed frame. This pass works out, before the lighting, the shadow factor of up to
``SHADOW_MASK_SLOTS`` (8) shadowed lights at every 2nd (``render.shadow_detail=half``) or 4th
(``quarter``; ``auto``, the default: the 4th from ``AUTO_QUARTER_FROM`` lights on) pixel across
and down, each only for the lights whose range, cone and side reach the pixel's surface
(shadow_mask.frag.glsl). The factors (8 bits each) and the sample's view distance go into one
RGBA32UI texel; the lighting reads a pixel's factors once, upsampled from the four samples
around it with bilinear weights times closeness in depth and orientation (shadow_mask.glsl),
and its light loop does no map lookups for those lights. A light's slot
travels in the Shadows block (``shadow_light[i].z``, render/shadows.py, most prominent lights
first); with more than eight shadowed lights the others keep their per-pixel lookups (the
SHADOW_MASK 2 variant).

Deferred path only, full rate and coarse pixel shading alike (both light through
deferred.glsl's ``light_texel``); the forward path and blended glass light per pixel.
"""

from __future__ import annotations

from dataclasses import dataclass

import moderngl
import numpy as np

from app.camera import EyeView
from render.constants import SHADOW_MASK_SLOTS
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

STEPS = {"half": 2, "quarter": 4}  # render.shadow_detail -> the sample spacing in pixels
# render.shadow_detail=auto: every 2nd pixel, every 4th from this many lights in the mask on.
# The mask's cost grows with its lights while each one's shadow is a smaller part of the
# light: showroom-8 (8 shadowed lamps, soft, 2x640x720, fixed settings, llvmpipe) 148 ms a
# frame at every 2nd pixel (mask 26 ms), 130 ms at every 4th (9 ms), unshadowed 108 ms, with
# 0.2 % of the pixels changed by more than 8 levels of 255.
AUTO_QUARTER_FROM = 4


def mask_step(detail: str, lights: int) -> int:
    """The sample spacing in pixels for ``render.shadow_detail`` with ``lights`` in the mask
    (0: every pixel looks up its maps, no mask)."""
    if detail == "auto":
        return STEPS["quarter" if lights >= AUTO_QUARTER_FROM else "half"]
    return STEPS.get(detail, 0)


# Shadowed lights from which the mask is used (render.shadows -> count). Measured on llvmpipe,
# 2x640x720, on a quiet machine: it pays from the first light, hard or soft (the shared living
# room, one lamp: hard 1.31x unshadowed per pixel, 1.23x with the mask; soft 1.33x and 1.27x).
MIN_LIGHTS = {"hard": 1, "soft": 1}


@dataclass
class MaskFrame:
    """What the lighting needs of this frame's mask (``res.get("shadow_mask")``)."""

    textures: list[moderngl.Texture]  # per eye
    step: int  # samples every ``step`` pixels across and down
    slots: int  # slots the scene's shadowed lights could fill, 4 or 8 (scene_slots)
    # the scene has more shadowed lights than slots: those without one look up their maps
    # per pixel (the SHADOW_MASK 2 variant, for every frame of such a scene)
    overflow: bool

    def defines(self) -> dict[str, object]:
        """The lighting's variant: not the step (a uniform) nor the slots lit this frame,
        which change as lamps come into view, but the slots the scene could fill and whether
        its shadowed lights could overflow them: a new variant mid-walk is compiled in that
        frame (110-200 ms in the corridor walk)."""
        return {"SHADOW_MASK": 2 if self.overflow else 1, "SHADOW_MASK_SLOTS_USED": self.slots}

    def bind(
        self, prog: moderngl.Program | moderngl.ComputeShader, eye: EyeView, index: int
    ) -> None:
        bind_texture(prog, "shadow_mask", self.textures[index])
        set_uniforms(prog, {"u_mask_depth": depth_terms(eye), "u_mask_step": self.step})


def scene_slots(casters: int) -> int:
    """The mask's slots for a scene of ``casters`` shadow-casting lights: 4 where it has at
    most 4, else ``SHADOW_MASK_SLOTS``. Fixed for the scene, not chosen by the lights in view
    each frame: the lighting's variant must not change as one walks (8 slots cost the
    showroom's lighting 4 % more than 4, at 2x640x720, so a scene of few lamps keeps 4)."""
    return 4 if casters <= 4 else SHADOW_MASK_SLOTS


def depth_terms(eye: EyeView) -> tuple[float, float]:
    """(a, b) with view distance = b / (ndc_z + a) for the eye's perspective projection."""
    return float(eye.projection[2, 2]), float(eye.projection[2, 3])


def mask_size(size: tuple[int, int], step: int) -> tuple[int, int]:
    """The mask's size for an eye of ``size``: one sample per ``step`` pixels, rounded up."""
    return max(1, -(-size[0] // step)), max(1, -(-size[1] // step))


class MaskTargets:
    """One eye's mask (RGBA32UI: two words of 8-bit factors, the view distance, the normal)
    and its framebuffer."""

    def __init__(self, ctx: moderngl.Context, size: tuple[int, int]) -> None:
        self.size = size
        self.texture = ctx.texture(size, 4, dtype="u4")
        self.texture.filter = (moderngl.NEAREST, moderngl.NEAREST)
        self.texture.repeat_x = self.texture.repeat_y = False
        self.fbo = ctx.framebuffer([self.texture])

    def release(self) -> None:
        self.fbo.release()
        self.texture.release()


class ShadowMaskPass(RenderPass):
    """Per eye, before the lighting: the shadow factors of up to 8 shadowed lights."""

    name = "shadow_mask"
    reads = ("shadow_maps", "depth", "normal")
    writes = ("shadow_mask",)

    def __init__(self, ctx: moderngl.Context, shaders: ShaderLibrary, res: Resources) -> None:
        super().__init__(ctx, shaders, res)
        self.step = STEPS["half"]
        self.detail = "half"  # render.shadow_detail: the step follows it and the lights
        self.targets: list[MaskTargets] = []
        self._by_size: BySize[list[MaskTargets]] = BySize(
            lambda size: [MaskTargets(self.ctx, size) for _ in range(2)], release_all
        )
        self.lights = 0  # lights in the mask last frame
        self.min_lights = 1
        self.slots = 4  # the slots the scene's shadowed lights could fill (scene_slots)
        self.overflow = False  # the scene has more shadowed lights than SHADOW_MASK_SLOTS
        # The sun looked up over each sample's footprint (shadow_mask.frag.glsl sun_factor):
        # a blind's slatted sun averages into an even patch instead of aliasing into blobs.
        # False: its own soft edge (tests compare the two).
        self.sun_footprint = True

    def configure(self, settings, scene, frame) -> bool:
        r = settings.render
        self.detail = r.shadow_detail
        self.min_lights = MIN_LIGHTS.get(r.shadows, 1)
        casters = sum(1 for light in scene.light_list if light.casts_shadows)
        self.slots = scene_slots(casters)
        self.overflow = casters > SHADOW_MASK_SLOTS
        return (
            r.path == "deferred"
            and r.shadows != "off"
            and mask_step(self.detail, SHADOW_MASK_SLOTS) > 0
            and casters > 0
        )

    def _ensure(self, eye_size: tuple[int, int]) -> None:
        self.targets = self._by_size.get(mask_size(eye_size, self.step))

    def execute(self, frame: FrameContext, res: Resources) -> None:
        slots, _shadowed = res.get("shadow_maps", ([], 0))
        self.samples = 0
        self.lights = len(slots) if len(slots) >= self.min_lights else 0
        if not self.lights:
            return  # too few lights have a map this frame: the lighting looks them up itself
        self.step = mask_step(self.detail, len(slots))
        self._ensure(res.targets[0].size)
        lights = np.full(SHADOW_MASK_SLOTS, -1, np.int32)
        lights[: len(slots)] = slots
        # The sun among them: its lookup over each sample's footprint (a compile-time variant:
        # on llvmpipe the lamps' samples would pay for its code too).
        known = frame.scene.light_list
        sun = self.sun_footprint and any(
            0 <= i < len(known) and known[i].kind == "directional" for i in slots
        )
        prog = self.shaders.program(
            "fullscreen.vert.glsl",
            "shadow_mask.frag.glsl",
            {"SHADOW_MASK_SLOTS_USED": self.slots, "SUN_FOOTPRINT": sun},
        )
        frame.scene.light_buffer.bind_to_uniform_block(0)
        self.ctx.disable(moderngl.BLEND | moderngl.DEPTH_TEST | moderngl.CULL_FACE)
        for eye, tgt, own in zip(frame.eyes, res.targets, self.targets):
            # half a sample's spacing: step / 2 pixels of 2 / (P11 H) radians, per metre
            spread = self.step / (float(eye.projection[1, 1]) * tgt.size[1])
            own.fbo.use()
            bind_texture(prog, "gb_depth", tgt.depth)
            bind_texture(prog, "gb_normal", tgt.normal)
            set_uniforms(
                prog,
                {
                    "u_inv_view_projection": eye.inverse_view_projection,
                    "u_size": tgt.size,
                    "u_mask_lights": lights.tobytes(),
                    "u_mask_depth": depth_terms(eye),
                    "u_mask_step": self.step,
                },
                # the sun's footprint (shadow_mask.frag.glsl sun_footprint), where a sun is
                optional={"u_view_projection": eye.view_projection, "u_mask_spread": spread},
            )
            self.fullscreen(prog)
            self.samples += own.size[0] * own.size[1]
        res.put(
            "shadow_mask",
            MaskFrame(
                [own.texture for own in self.targets],
                self.step,
                self.slots,
                overflow=self.overflow,
            ),
        )

    def release(self) -> None:
        super().release()
        self._by_size.clear()
        self.targets = []
