"""The scene on the GPU: one vertex/index buffer pair per mesh, texture pyramids, lights.

Geometry is uploaded once per scene; textures stream their pyramid levels (TextureStreamer).
``release()`` frees everything it made.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import moderngl
import numpy as np

from app.ao_bake import BackgroundBake
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
        self._ao_vaos: dict[tuple[int, int], moderngl.VertexArray] = {}
        self._ao_buffers: dict[int, moderngl.Buffer] = {}  # uploaded when AO first draws
        self.ao_bake: BackgroundBake | None = None  # started when AO first draws, if needed
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
            self._vaos[key] = self.ctx.vertex_array(
                program, [(mesh.vbo, fmt, *attrs)], index_buffer=mesh.ibo, index_element_size=4
            )
        return self._vaos[key]

    def ao_vao(self, program: moderngl.Program, index: int) -> moderngl.VertexArray:
        """Mesh ``index`` with its baked ambient occlusion as ``in_ao`` (render/ao.py); the
        occlusion is uploaded on first use (1 where the mesh has none or a wrong count). A
        scene without starts its bake in the background and is drawn unoccluded until then."""
        self._poll_ao_bake()
        key = (program.glo, index)
        if key not in self._ao_vaos:
            mesh = self.meshes[index]
            if index not in self._ao_buffers:
                src = self.scene.meshes[index]
                n = int(src.positions.shape[0])
                ok = src.ao is not None and src.ao.shape == (n, 2)
                ao = src.ao if ok else np.ones((n, 2))
                self._ao_buffers[index] = self.ctx.buffer(np.asarray(ao, np.float32).tobytes())
            fmt = " ".join(
                f if a in program else f[0] + "x4"
                for f, a in zip(VERTEX_FORMAT.split(), VERTEX_ATTRS)
            )
            attrs = [a for a in VERTEX_ATTRS if a in program]
            content: list = [(mesh.vbo, fmt, *attrs)]
            if "in_ao" in program:
                content.append((self._ao_buffers[index], "2f", "in_ao"))
            self._ao_vaos[key] = self.ctx.vertex_array(
                program, content, index_buffer=mesh.ibo, index_element_size=4
            )
        return self._ao_vaos[key]

    def _poll_ao_bake(self) -> None:
        if self.ao_bake is None:
            if all(m.ao is not None for m in self.scene.meshes):
                return
            self.ao_bake = BackgroundBake(self.scene)
        if self.ao_bake.done and self.ao_bake.result is not None:
            self.scene, self.ao_bake.result = self.ao_bake.result, None
            for v in self._ao_vaos.values():  # next draws upload the baked values
                v.release()
            for b in self._ao_buffers.values():
                b.release()
            self._ao_vaos.clear()
            self._ao_buffers.clear()

    def release(self) -> None:
        for v in (*self._vaos.values(), *self._ao_vaos.values()):
            v.release()
        for b in self._ao_buffers.values():
            b.release()
        self._ao_vaos.clear()
        self._ao_buffers.clear()
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


def light_buffer_data(scene: Scene) -> np.ndarray:
    rows = [
        (*light.position, light.range_m, *light.color, light.intensity) for light in scene.lights
    ]
    return np.asarray(rows, np.float32).reshape(-1, 8)
