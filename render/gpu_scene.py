"""The scene on the GPU: one vertex/index buffer pair per mesh, texture pyramids, lights.

Geometry is uploaded once per scene; textures stream their pyramid levels (TextureStreamer).
``release()`` frees everything it made.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass

import moderngl
import numpy as np

from app.scene import Light, Material, Scene
from render.constants import MAX_LIGHTS
from render.texture_stream import TextureStreamer

log = logging.getLogger(__name__)
VERTEX_FORMAT = "3f 3f 2f 3f"
VERTEX_ATTRS = ("in_position", "in_normal", "in_uv", "in_color")


@dataclass
class GpuMesh:
    name: str
    vbo: moderngl.Buffer
    ibo: moderngl.Buffer
    material: Material
    texture: int | None  # index into GpuScene.streamer
    vertex_count: int


class GpuScene:
    def __init__(
        self,
        ctx: moderngl.Context,
        scene: Scene,
        anisotropy: float = 1.0,
        stream_in: bool = False,
    ) -> None:
        self.ctx = ctx
        self.scene = scene
        self.streamer = TextureStreamer(
            ctx, scene.textures, anisotropy=anisotropy, stream_in=stream_in
        )
        self.meshes: list[GpuMesh] = []
        for m in scene.meshes:
            colors = m.colors if m.colors is not None else np.ones_like(m.positions)
            data = np.hstack([m.positions, m.normals, m.uvs, colors]).astype(np.float32)
            mat = scene.materials[m.material]
            self.meshes.append(
                GpuMesh(
                    m.name,
                    ctx.buffer(data.tobytes()),
                    ctx.buffer(m.indices.astype(np.uint32).tobytes()),
                    mat,
                    mat.texture,
                    int(m.indices.size),
                )
            )
        self._vaos: dict[tuple[int, int], moderngl.VertexArray] = {}
        self.light_list: list[Light] = []
        self.lights = np.zeros((0, 12), np.float32)
        self.light_buffer = ctx.buffer(reserve=3 * MAX_LIGHTS * 16)
        self.light_version = 0  # counts set_lights calls (the shadow maps' cache watches it)
        self.set_lights(scene.lights)

    def set_lights(self, lights: list[Light]) -> None:
        """The lights the frame draws (the scene's, or those plus the sun): the uniform block
        and ``light_list`` (index i of both is the same light), without re-uploading geometry."""
        if len(lights) > MAX_LIGHTS:
            log.warning(
                "%s has %d lights; only the first %d are drawn",
                self.scene.name,
                len(lights),
                MAX_LIGHTS,
            )
        self.light_list = list(lights[:MAX_LIGHTS])
        self.lights = light_rows(self.light_list)
        block = np.zeros((3, MAX_LIGHTS, 4), np.float32)  # std140: the block's three arrays
        for k in range(3):
            block[k, : len(self.lights)] = self.lights[:, 4 * k : 4 * k + 4]
        self.light_buffer.write(block.tobytes())
        self.light_version += 1

    def vao(self, program: moderngl.Program, index: int) -> moderngl.VertexArray:
        key = (program.glo, index)
        if key not in self._vaos:
            mesh = self.meshes[index]
            attrs = [a for a in VERTEX_ATTRS if a in program]
            fmt = " ".join(
                f if a in attrs else f[0] + "x4"
                for f, a in zip(VERTEX_FORMAT.split(), VERTEX_ATTRS)
            )
            self._vaos[key] = self.ctx.vertex_array(
                program, [(mesh.vbo, fmt, *attrs)], index_buffer=mesh.ibo, index_element_size=4
            )
        return self._vaos[key]

    def release(self) -> None:
        for v in self._vaos.values():
            v.release()
        for m in self.meshes:
            m.vbo.release()
            m.ibo.release()
        self.streamer.release()
        self.light_buffer.release()
        self._vaos.clear()
        self.meshes.clear()

    @property
    def texture_bytes(self) -> int:
        return self.streamer.resident_bytes()

    def texture_levels(self) -> list[int]:
        """Pyramid depth n of each mesh's texture (0 for untextured meshes)."""
        return [
            self.streamer.n_levels(m.texture) if m.texture is not None else 0 for m in self.meshes
        ]


def light_rows(lights: list[Light]) -> np.ndarray:
    """One row of 12 floats per light, the uniform block's three vec4 (shading.glsl):
    position and range (range -1: directional), colour and intensity, and the cone: the
    direction scaled by 1 / (cos inner - cos outer) and the offset -cos outer times that scale
    (glTF's smooth spot falloff; a point light (0, 0, 0, 1) is lit all round, a directional
    light's is its unit direction)."""
    rows = []
    for light in lights:
        d = np.asarray(light.direction, np.float64)
        n = float(np.linalg.norm(d))
        d = d / n if n > 1e-12 and np.isfinite(n) else np.array([0.0, -1.0, 0.0])
        if light.kind == "directional":
            cone = (*d, 1.0)
            rng = -1.0
        elif light.kind == "spot":
            cos_o, cos_i = spot_cosines(light)
            scale = 1.0 / max(1e-3, cos_i - cos_o)
            cone = (*(d * scale), -cos_o * scale)
            rng = light.range_m
        else:
            cone = (0.0, 0.0, 0.0, 1.0)
            rng = light.range_m
        rows.append((*light.position, rng, *light.color, light.intensity, *cone))
    return np.asarray(rows, np.float32).reshape(-1, 12)


def spot_cosines(light: Light) -> tuple[float, float]:
    """cos(outer), cos(inner) of a spot's half angles (outer within 0..90 degrees, inner at
    most outer)."""
    outer = min(max(float(light.outer_cone_deg), 0.01), 90.0)
    inner = min(max(float(light.inner_cone_deg), 0.0), outer)
    return math.cos(math.radians(outer)), math.cos(math.radians(inner))


def light_buffer_data(scene: Scene) -> np.ndarray:
    """The scene's light rows (see :func:`light_rows`)."""
    return light_rows(list(scene.lights))
