"""The scene on the GPU: one vertex/index buffer pair per mesh, texture pyramids, lights.

Geometry is uploaded once per scene; textures stream their pyramid levels (TextureStreamer).
``release()`` frees everything it made.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import moderngl
import numpy as np

from app.scene import Material, Scene
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
    sky_vbo: moderngl.Buffer  # per vertex: sky visibility front, back (2f; 0 until baked)


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
                    ctx.buffer(np.zeros((max(len(m.positions), 1), 2), np.float32).tobytes()),
                )
            )
        self._vaos: dict[tuple[int, int], moderngl.VertexArray] = {}
        self.lights = light_buffer_data(scene)
        if len(self.lights) > MAX_LIGHTS:
            log.warning(
                "%s has %d lights; only the first %d are drawn",
                scene.name,
                len(self.lights),
                MAX_LIGHTS,
            )
            self.lights = self.lights[:MAX_LIGHTS]
        block = np.zeros((2, MAX_LIGHTS, 4), np.float32)  # std140: positions, then colours
        block[0, : len(self.lights)] = self.lights[:, :4]
        block[1, : len(self.lights)] = self.lights[:, 4:]
        self.light_buffer = ctx.buffer(block.tobytes())

    def vao(self, program: moderngl.Program, index: int) -> moderngl.VertexArray:
        key = (program.glo, index)
        if key not in self._vaos:
            mesh = self.meshes[index]
            attrs = [a for a in VERTEX_ATTRS if a in program]
            fmt = " ".join(
                f if a in attrs else f[0] + "x4"
                for f, a in zip(VERTEX_FORMAT.split(), VERTEX_ATTRS)
            )
            buffers = [(mesh.vbo, fmt, *attrs)]
            if "in_sky" in program:
                buffers.append((mesh.sky_vbo, "2f", "in_sky"))
            self._vaos[key] = self.ctx.vertex_array(
                program, buffers, index_buffer=mesh.ibo, index_element_size=4
            )
        return self._vaos[key]

    def release(self) -> None:
        for v in self._vaos.values():
            v.release()
        for m in self.meshes:
            m.vbo.release()
            m.ibo.release()
            m.sky_vbo.release()
        self.streamer.release()
        self.light_buffer.release()
        self._vaos.clear()
        self.meshes.clear()

    def set_sky_visibility(self, values: list[np.ndarray]) -> None:
        """Each mesh's per-vertex sky visibility ((N, 2): front, back), from app.sky_light."""
        for mesh, v in zip(self.meshes, values):
            data = np.ascontiguousarray(v, np.float32)
            if data.nbytes == mesh.sky_vbo.size:
                mesh.sky_vbo.write(data.tobytes())

    @property
    def texture_bytes(self) -> int:
        return self.streamer.resident_bytes()

    def texture_levels(self) -> list[int]:
        """Pyramid depth n of each mesh's texture (0 for untextured meshes)."""
        return [
            self.streamer.n_levels(m.texture) if m.texture is not None else 0 for m in self.meshes
        ]


def light_buffer_data(scene: Scene) -> np.ndarray:
    rows = [
        (*light.position, light.range_m, *light.color, light.intensity) for light in scene.lights
    ]
    return np.asarray(rows, np.float32).reshape(-1, 8)
