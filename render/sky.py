"""Daylight on the GPU: the baked sky, the sun's uniforms, the sky visibility and the sky behind.

Two passes. ``DaylightPass`` (first in the frame) re-bakes the sky on the CPU only when a
``sky.*`` setting changes (``app.sky.bake_sky``: about 15 ms), starts the scene's sky visibility
bake once per scene (``app.sky_field.VisibilityBake``, a background thread: the share by place,
then per vertex) and uploads each part when it is ready, and hands the lighting a
:class:`SkyFrame` as the ``sky`` resource: with it the lighting compiles its ``SKY`` variant
(sky.glsl: the sun and the sky's diffuse light). ``SkyPass`` draws the sky where no geometry
covers a pixel, after the opaque lighting, so windows open onto it (glass is drawn after it).
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass

import moderngl
import numpy as np

from app.scene import Light
from app.settings import SkySettings
from app.sky import SkyBake, bake_sky, north_east, scene_sky, sky_key, unlit_gain
from app.sky_field import SkyField, VisibilityBake
from app.sky_model import SUN_HALF_ANGLE_DEG
from render.gpu_scene import GpuScene
from render.pass_graph import FrameContext, RenderPass, Resources, bind_texture, set_uniforms
from render.shaders import ShaderLibrary

log = logging.getLogger(__name__)


class GpuSkyField:
    """The sky's share by place (``app.sky_field``) as one 3D float texture, the + and -
    grids' slabs along z; before the bake is done, one empty cell (every pixel keeps its
    vertex's share)."""

    def __init__(self, ctx: moderngl.Context) -> None:
        self.ctx = ctx
        self.field: SkyField | None = None
        self.texture: moderngl.Texture3D | None = None
        self.set(None)

    def set(self, field: SkyField | None) -> None:
        if self.texture is not None:
            self.texture.release()
        self.field = field
        size, data = ((1, 1, 2), np.full((2, 1, 1, 4), -1.0, np.float32))
        if field is not None:
            x, y, z = field.dims
            size, data = (x, y, 2 * z), field.packed()
        self.texture = self.ctx.texture3d(size, 4, np.ascontiguousarray(data).tobytes(), dtype="f4")
        self.texture.filter = (moderngl.LINEAR, moderngl.LINEAR)
        self.texture.repeat_x = self.texture.repeat_y = self.texture.repeat_z = False

    def uniforms(self) -> dict[str, object]:
        f = self.field
        if f is None:
            return {"u_sf_origin_cell": (0.0, 0.0, 0.0, 1.0), "u_sf_dims": (1, 1, 1)}
        return {
            "u_sf_origin_cell": (*(float(v) for v in f.origin), float(f.cell)),
            "u_sf_dims": tuple(int(v) for v in f.dims),
        }

    def release(self) -> None:
        if self.texture is not None:
            self.texture.release()
            self.texture = None


@dataclass
class SkyFrame:
    """What the shaders need of the daylight this frame (the ``sky`` resource)."""

    texture: moderngl.Texture
    bake: SkyBake
    north: np.ndarray
    east: np.ndarray
    scale: float  # a dimmer on sun and sky (1: Brightness acts in the exposure)
    field: GpuSkyField  # the sky's share by place

    @property
    def sun_to(self) -> tuple[float, float, float]:
        sun = self.bake.sun
        if sun is None:
            return (0.0, -1.0, 0.0)
        d = sun.direction
        return (-d[0], -d[1], -d[2])

    def bind(self, prog: moderngl.Program | moderngl.ComputeShader) -> None:
        """The sky's diffuse light for sky.glsl (in the SKY variants; the sun is a light of the
        light loop)."""
        sh = (self.bake.sh * self.scale).astype(np.float32)
        set_uniforms(prog, {}, optional={"u_sky_sh": sh.tobytes()})
        tex = self.field.texture
        if tex is not None and bind_texture(prog, "sky_field", tex, optional=True):
            set_uniforms(prog, self.field.uniforms())


class DaylightPass(RenderPass):
    """The sky baked for the settings and the scene's sky visibility; writes ``sky``."""

    name = "daylight"
    writes = ("sky",)

    def __init__(self, ctx: moderngl.Context, shaders: ShaderLibrary, res: Resources) -> None:
        super().__init__(ctx, shaders, res)
        self.sky: SkySettings = SkySettings()
        self.bake: SkyBake | None = None
        self._key: tuple | None = None
        self.texture: moderngl.Texture | None = None
        self.visibility: VisibilityBake | None = None
        self._visibility_scene: GpuScene | None = None
        self.visibility_ready = False
        self._field_shown = False
        self.field = GpuSkyField(ctx)

    def configure(self, settings, scene, frame) -> bool:
        self.sky = scene_sky(settings.sky, getattr(scene, "scene", scene))  # its own north
        return bool(settings.sky.enabled)

    # -- the sky -------------------------------------------------------------------------------
    def update_sky(self, sky: SkySettings) -> SkyBake:
        """Bake the sky again when a ``sky.*`` setting changed (the sun moves with it)."""
        key = sky_key(sky)
        if self.bake is None or key != self._key:
            self.bake = bake_sky(sky)
            self._key = key
            self._upload(self.bake.image)
        return self.bake

    def _upload(self, image: np.ndarray) -> None:
        h, w = image.shape[:2]
        if self.texture is None or self.texture.size != (w, h):
            if self.texture is not None:
                self.texture.release()
            self.texture = self.ctx.texture((w, h), 3, dtype="f4")
            self.texture.filter = (moderngl.LINEAR, moderngl.LINEAR)
            self.texture.repeat_x = True
            self.texture.repeat_y = False
        self.texture.write(np.ascontiguousarray(image, np.float32).tobytes())

    @property
    def sun(self) -> Light | None:
        """The sun of the last baked settings (None below the horizon or with daylight off)."""
        return self.bake.sun if self.bake is not None and self.enabled else None

    # -- the sky visibility --------------------------------------------------------------------
    def update_visibility(self, scene: GpuScene) -> None:
        """Start the scene's visibility bake once; upload the share by place as soon as it is
        ready (the per-vertex share, for where no point was near, takes as long again) and
        the vertices' when they are."""
        if scene is not self._visibility_scene:
            if self.visibility is not None:
                self.visibility.cancel()
            self._visibility_scene = scene
            self.visibility_ready = False
            self._field_shown = False
            self.field.set(None)
            self.visibility = VisibilityBake(scene.scene) if scene.meshes else None
        bake = self.visibility
        if bake is None or self.visibility_ready:
            return
        done = bake.done  # read first: ``field`` is set before the bake is done
        if not self._field_shown and bake.field is not None:
            self.field.set(bake.field)
            self._field_shown = True
        if done:
            if bake.result is not None:
                scene.set_sky_visibility(bake.result)
            self.visibility_ready = True

    def wait_for_visibility(self, scene: GpuScene, timeout: float = 120.0) -> bool:
        """Bake (or finish baking) ``scene``'s sky visibility now and upload it (tests, bench)."""
        self.update_visibility(scene)
        if self.visibility is not None:
            self.visibility.wait(timeout)
        self.update_visibility(scene)
        return self.visibility_ready

    def execute(self, frame: FrameContext, res: Resources) -> None:
        bake = self.update_sky(self.sky)
        self.update_visibility(frame.scene)
        assert self.texture is not None
        north, east = north_east(self.sky.north_deg)
        # Brightness is the exposure's compensation (the present pass): no dimmer on the sky.
        res.put("sky", SkyFrame(self.texture, bake, north, east, 1.0, self.field))

    def release(self) -> None:
        super().release()
        if self.visibility is not None:
            self.visibility.cancel()
        self.field.release()
        if self.texture is not None:
            self.texture.release()
            self.texture = None


def frame_unlit_gain(daylight: object, settings, scene: object) -> float:
    """``app.sky.unlit_gain`` for the frame's settings: the daylight pass's bake of the
    scene's sky (the same bake it draws, baked again only when a ``sky.*`` setting changed)."""
    if not settings.sky.enabled or not isinstance(daylight, DaylightPass):
        return 1.0
    try:
        bake = daylight.update_sky(scene_sky(settings.sky, getattr(scene, "scene", scene)))
    except Exception:  # noqa: BLE001 - the daylight pass logs its own failure; glow as at night
        return 1.0
    return unlit_gain(bake)


class SkyPass(RenderPass):
    """The sky where no geometry covers a pixel (depth still at the far plane)."""

    name = "sky"
    reads = ("depth", "hdr", "sky")
    writes = ("hdr",)

    def configure(self, settings, scene, frame) -> bool:
        return bool(settings.sky.enabled)

    def execute(self, frame: FrameContext, res: Resources) -> None:
        sky: SkyFrame | None = res.get("sky")
        if sky is None:  # the daylight pass failed this frame (logged once): keep the background
            return
        prog = self.shaders.program("sky.vert.glsl", "sky.frag.glsl")
        ctx = self.ctx
        ctx.memory_barrier(moderngl.FRAMEBUFFER_BARRIER_BIT)  # after a compute lighting
        ctx.enable(moderngl.DEPTH_TEST)
        ctx.disable(moderngl.BLEND | moderngl.CULL_FACE)
        ctx.depth_func = "<="
        sun = sky.bake.sun
        half = math.radians(SUN_HALF_ANGLE_DEG)
        disc = (0.0, 0.0, 0.0)
        if sun is not None:
            # The disc's radiance: its illuminance over its solid angle (far above the range a
            # half float holds; storable() clamps it).
            k = sun.intensity * sky.scale / (math.pi * half * half)
            disc = (sun.color[0] * k, sun.color[1] * k, sun.color[2] * k)
        bind_texture(prog, "sky", sky.texture)
        set_uniforms(
            prog,
            {"u_sky_north": tuple(sky.north), "u_sky_east": tuple(sky.east)},
            optional={
                "u_sun_to": sky.sun_to,
                "u_sun_disc": disc,
                "u_sun_cos": math.cos(half),
                "u_sky_scale": sky.scale,
            },
        )
        for eye, tgt in zip(frame.eyes, res.targets):
            tgt.forward.use()
            tgt.forward.depth_mask = False
            set_uniforms(
                prog,
                {
                    "u_inv_view_projection": eye.inverse_view_projection,
                    "u_eye": tuple(eye.position),
                },
            )
            self.fullscreen(prog)
            tgt.forward.depth_mask = True
        ctx.depth_func = "<"
        ctx.disable(moderngl.DEPTH_TEST)
