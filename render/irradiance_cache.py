"""The irradiance cache on the GPU: one 3D texture, one lookup per pixel.

``GpuIrradianceCache`` uploads an ``app.irradiance_cache.IrradianceCache`` (its six direction
grids stacked along its axis with the fewest cells, an empty slice between them, linearly
filtered) and ``lookup_image`` writes an eye's irradiance E into the same rgba32f target the
photon gather fills (``irradiance_cache.comp.glsl``), so the deferred lighting uses it
unchanged.
"""

from __future__ import annotations

from typing import cast

import moderngl
import numpy as np

from app.camera import gl_bytes
from app.irradiance_cache import BUCKETS, IrradianceCache
from render.pass_graph import bind_image, bind_texture, set_uniforms
from render.shaders import ShaderLibrary


class GpuIrradianceCache:
    def __init__(self, ctx: moderngl.Context, cache: IrradianceCache) -> None:
        self.ctx = ctx
        self.cache = cache
        axis = cache.stack_axis
        along = 3 - axis  # that axis in values (6, Z, Y, X, 4)
        pad = [(0, 0)] * 5
        pad[along] = (0, 1)  # one empty slice after each grid: weight 0 between directions
        slabs = np.pad(cache.values, pad)
        stacked = np.ascontiguousarray(np.concatenate(list(slabs), axis=along - 1))
        size = [int(v) for v in cache.dims]
        size[axis] = BUCKETS * (size[axis] + 1)
        shape = (size[0], size[1], size[2])
        self.texture = ctx.texture3d(shape, 4, stacked.tobytes(), dtype="f4")
        self._nbytes = int(stacked.nbytes)
        self.texture.filter = (moderngl.LINEAR, moderngl.LINEAR)
        self.texture.repeat_x = self.texture.repeat_y = self.texture.repeat_z = False

    @property
    def nbytes(self) -> int:
        return self._nbytes

    def lookup_image(
        self,
        shaders: ShaderLibrary,
        *,
        depth: moderngl.Texture,
        normal: moderngl.Texture,
        inv_view_projection: np.ndarray,
        size: tuple[int, int],
        out: moderngl.Texture,
    ) -> None:
        """E per G-buffer pixel into ``out`` (rgba32f): rgb = E, a = 1, background 0."""
        prog = shaders.compute("irradiance_cache.comp.glsl")
        c = self.cache
        bind_texture(prog, "gb_normal", normal)
        bind_texture(prog, "gb_depth", depth)
        bind_texture(
            prog, "irradiance_cache", cast(moderngl.Texture, self.texture)
        )  # 3D: same use()
        w, h = int(size[0]), int(size[1])
        set_uniforms(
            prog,
            {
                "u_inv_view_projection": gl_bytes(np.asarray(inv_view_projection)),
                "u_size": (w, h),
                "u_ic_origin": tuple(float(v) for v in c.origin),
                "u_ic_cell": float(c.cell),
                "u_ic_dims": tuple(int(v) for v in c.dims),
                "u_ic_stack": c.stack_axis,
            },
        )
        bind_image(out, "out")
        prog.run(-(-w // 8), -(-h // 8))

    def release(self) -> None:
        self.texture.release()
