"""The even light by place on the GPU (``app.ambient_field``): one 3D texture, the six
direction grids packed in two RGBA slabs along z, read by shading.glsl ``even_light`` with
two trilinear fetches a pixel in every path that shades (deferred, CPS, forward, blended)."""

from __future__ import annotations

import moderngl
import numpy as np

from app.ambient_field import AmbientField
from render.constants import TEXTURE_UNITS
from render.pass_graph import has, set_uniforms, uniform


class GpuAmbientField:
    def __init__(self, ctx: moderngl.Context, field: AmbientField) -> None:
        self.field = field
        x, y, z = field.dims
        data = np.ascontiguousarray(field.packed())  # (2 Z, Y, X, 4)
        self.texture = ctx.texture3d((x, y, 2 * z), 4, data.tobytes(), dtype="f2")
        self.texture.filter = (moderngl.LINEAR, moderngl.LINEAR)
        self.texture.repeat_x = self.texture.repeat_y = self.texture.repeat_z = False

    def release(self) -> None:
        self.texture.release()


def bind_field(
    prog: moderngl.Program | moderngl.ComputeShader, field: GpuAmbientField | None
) -> None:
    """Bind ``field`` for ``prog``'s AMBIENT_FIELD variant (other variants have no field)."""
    if field is None or not has(prog, "u_ambient_field"):
        return
    unit = TEXTURE_UNITS["ambient_field"]
    uniform(prog, "u_ambient_field").value = unit
    field.texture.use(unit)
    f = field.field
    set_uniforms(
        prog,
        {
            "u_af_origin_cell": (*(float(v) for v in f.origin), float(f.cell)),
            "u_af_dims": tuple(int(v) for v in f.dims),
        },
    )
