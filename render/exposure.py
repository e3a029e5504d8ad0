"""Exposure for the present pass: fixed in EV100, or metered from the lit frame.

``ExposurePass`` (for automatic exposure and TCR's light term) reduces each eye's HDR colour
to a 64 x 36 grid of mean log2 luminance of its surfaces (the void around a model, where
nothing is drawn, is left out; the sky, where it is drawn, is metered) in a fragment shader
(on llvmpipe cheaper than a compute reduction) and starts an asynchronous copy of it into a
pixel buffer; the next frame reads that buffer (the copy finished long before) and meters it
(``app.exposure.metered_ev``), so the readback never waits for the frame being drawn.
``Exposure`` holds the eye's adaptation and gives each frame its exposure factor, its EV and
the readout. The units and formulas are in ``app.exposure``.
"""

from __future__ import annotations

import math

import moderngl
import numpy as np

from app.exposure import (
    EyeAdaptation,
    displayed_brightness,
    effective_ev,
    exposure_scale,
    metered_ev,
    readout,
)
from app.settings import RenderSettings
from app.tcr import terms_from_settings
from render.pass_graph import FrameContext, RenderPass, Resources, bind_texture, set_uniforms
from render.shaders import ShaderLibrary

METER_CELLS = (64, 36)  # per eye: 16:9 cells, about 10 x 20 pixels each at 640 x 720


class ExposurePass(RenderPass):
    """Automatic exposure's meter: both eyes' log-luminance grids, read back a frame later."""

    name = "exposure_meter"
    reads = ("hdr", "depth")
    optional_reads = ("sky",)  # the sky drawn where no surface is: metered too

    def __init__(self, ctx: moderngl.Context, shaders: ShaderLibrary, res: Resources) -> None:
        super().__init__(ctx, shaders, res)
        w, h = METER_CELLS
        self.grid = ctx.texture((2 * w, h), 1, dtype="f4")
        self.grid.filter = (moderngl.NEAREST, moderngl.NEAREST)
        self.fbo = ctx.framebuffer([self.grid])
        self.pbo = ctx.buffer(reserve=2 * w * h * 4)
        self._pending = False  # the buffer holds a grid not read yet

    def configure(self, settings, scene, frame) -> bool:
        # Automatic exposure needs it, and so does TCR's light term (how bright the picture
        # shows the room); otherwise nothing reads it.
        tcr = settings.tcr
        light_term = tcr.enabled and terms_from_settings(tcr).l
        return settings.render.exposure_mode == "auto" or light_term

    def take(self) -> np.ndarray | None:
        """The grid the last metering frame copied, (36, 128) log2 cd/m2; None when none is
        waiting (the first frame, or automatic exposure was off)."""
        if not self._pending:
            return None
        self._pending = False
        w, h = METER_CELLS
        return np.frombuffer(self.pbo.read(), np.float32).reshape(h, 2 * w)

    def forget(self) -> None:
        """Drop a waiting grid (the scene changed: it metered another room)."""
        self._pending = False

    def execute(self, frame: FrameContext, res: Resources) -> None:
        if frame.warming:  # a frame no one sees: the last real frame's metering stays
            return
        prog = self.shaders.program("fullscreen.vert.glsl", "exposure_meter.frag.glsl")
        w, h = METER_CELLS
        # The sky pass drew the sky where no surface is (it failed: the background stays).
        sky = res.get("sky") is not None
        self.ctx.disable(moderngl.DEPTH_TEST | moderngl.BLEND)
        self.fbo.use()
        for index, tgt in enumerate(res.targets[:2]):
            origin = (index * w, 0)
            self.fbo.viewport = (*origin, w, h)
            bind_texture(prog, "eye_color", tgt.color)
            bind_texture(prog, "gb_depth", tgt.depth)
            set_uniforms(
                prog,
                {"u_origin": origin, "u_cells": (w, h), "u_meter_sky": sky},
            )
            self.fullscreen(prog)
        self.fbo.viewport = (0, 0, 2 * w, h)
        # Into the pixel buffer without waiting; take() reads it during the next frame.
        self.grid.read_into(self.pbo)
        self._pending = True

    def release(self) -> None:
        super().release()
        for obj in (self.fbo, self.grid, self.pbo):
            obj.release()


class Exposure:
    """The frame's exposure: the fixed EV or the adapted automatic one, with the Brightness;
    and the eye's adapted metering of the room, which TCR's light term reads."""

    def __init__(self) -> None:
        self.adaptation = EyeAdaptation()  # the eye, adapted to the metered room
        self.base_ev = 0.0  # the EV the last frame was shown at, before the Brightness
        self.mode = "manual"

    @property
    def scene_ev(self) -> float | None:
        """The EV the last metering found for the room (None: not metered); the eye is
        still adapting towards it when it differs from the automatic ``base_ev``."""
        return self.adaptation.target

    def reset(self) -> None:
        """A new scene: the next metering is taken at once."""
        self.adaptation.reset()

    def step(
        self, r: RenderSettings, grid: np.ndarray | None, dt: float, metering: bool = True
    ) -> float:
        """Advance by one frame of ``dt`` seconds with the last metering ``grid`` (None:
        none arrived); ``metering``: whether the meter runs (else the eye forgets the
        room). The factor on the linear picture."""
        self.mode = r.exposure_mode
        if not metering:
            self.adaptation.reset()
        measured = metered_ev(grid) if grid is not None else None
        ev = self.adaptation.update(measured, dt, r.adaptation_s)
        if r.exposure_mode == "auto" and ev is not None:
            self.base_ev = ev
        else:  # fixed, or not metered yet (the first frame starts from the fixed EV)
            self.base_ev = r.exposure_ev
        return self.scale(r)

    def scale(self, r: RenderSettings) -> float:
        """1 / L_max times the Brightness (exposure compensation); without the hidden
        ``render.exposure`` factor, which the renderer adds."""
        b = float(r.brightness)
        if not math.isfinite(b) or b <= 0.0:
            return 0.0
        return exposure_scale(self.base_ev) * b

    def ev(self, r: RenderSettings) -> float:
        """The EV the picture is shown at (what the readout says)."""
        return effective_ev(self.base_ev, r.brightness * r.exposure)

    def displayed_brightness(self, r: RenderSettings) -> float:
        """TCR's light term input (``app.exposure.displayed_brightness``)."""
        return displayed_brightness(r.brightness * r.exposure, self.base_ev, self.scene_ev)

    def readout(self, r: RenderSettings) -> str:
        return readout(self.ev(r), self.mode)
