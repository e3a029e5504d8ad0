"""The scene on the GPU: one vertex/index buffer pair per mesh, mipmapped sRGB textures.

Uploaded once per scene; never per frame. ``release()`` frees everything it made.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import moderngl
import numpy as np

from app.scene import Material, Scene

log = logging.getLogger(__name__)
GL_SRGB8_ALPHA8 = 0x8C43
MAX_LIGHTS = 1024  # must match shading.glsl; 32 KiB of the 64 KiB uniform block limit
VERTEX_FORMAT = "3f 3f 2f 3f"
VERTEX_ATTRS = ("in_position", "in_normal", "in_uv", "in_color")


@dataclass
class GpuMesh:
    name: str
    vbo: moderngl.Buffer
    ibo: moderngl.Buffer
    material: Material
    texture: moderngl.Texture | None
    vertex_count: int


class GpuScene:
    def __init__(self, ctx: moderngl.Context, scene: Scene, anisotropy: float = 1.0) -> None:
        self.ctx = ctx
        self.scene = scene
        self.textures: list[moderngl.Texture] = []
        self.texture_bytes = 0
        for tex in scene.textures:
            rgba = np.ascontiguousarray(np.flipud(tex.rgba))  # GL's row 0 is the bottom (v = 0)
            t = ctx.texture(tex.size, 4, rgba.tobytes(), internal_format=GL_SRGB8_ALPHA8)
            t.build_mipmaps()
            t.filter = (moderngl.LINEAR_MIPMAP_LINEAR, moderngl.LINEAR)
            t.repeat_x = t.repeat_y = tex.repeat
            t.anisotropy = anisotropy
            self.textures.append(t)
            self.texture_bytes += mip_chain_bytes(*tex.size, 4)
        self.meshes: list[GpuMesh] = []
        for m in scene.meshes:
            colors = m.colors if m.colors is not None else np.ones_like(m.positions)
            data = np.hstack([m.positions, m.normals, m.uvs, colors]).astype(np.float32)
            mat = scene.materials[m.material]
            tex = self.textures[mat.texture] if mat.texture is not None else None
            self.meshes.append(GpuMesh(m.name, ctx.buffer(data.tobytes()),
                                       ctx.buffer(m.indices.astype(np.uint32).tobytes()), mat,
                                       tex, int(m.indices.size)))
        self._vaos: dict[tuple[int, int], moderngl.VertexArray] = {}
        self.lights = light_buffer_data(scene)
        if len(self.lights) > MAX_LIGHTS:
            log.warning("%s has %d lights; only the first %d are drawn", scene.name,
                        len(self.lights), MAX_LIGHTS)
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
            fmt = " ".join(f if a in attrs else f[0] + "x4" for f, a in
                           zip(VERTEX_FORMAT.split(), VERTEX_ATTRS))
            self._vaos[key] = self.ctx.vertex_array(
                program, [(mesh.vbo, fmt, *attrs)], index_buffer=mesh.ibo, index_element_size=4)
        return self._vaos[key]

    def release(self) -> None:
        for v in self._vaos.values():
            v.release()
        for m in self.meshes:
            m.vbo.release()
            m.ibo.release()
        for t in self.textures:
            t.release()
        self.light_buffer.release()
        self._vaos.clear()
        self.meshes.clear()
        self.textures.clear()


def light_buffer_data(scene: Scene) -> np.ndarray:
    rows = [(*light.position, light.range_m, *light.color, light.intensity)
            for light in scene.lights]
    return np.asarray(rows, np.float32).reshape(-1, 8)


def mip_chain_bytes(width: int, height: int, bytes_per_texel: int) -> int:
    total = 0
    w, h = width, height
    while True:
        total += w * h * bytes_per_texel
        if w == 1 and h == 1:
            return total
        w, h = max(1, w // 2), max(1, h // 2)
