"""The scene on the GPU: the static meshes merged per material (or one vertex/index buffer
pair per mesh), texture pyramids, lights.

Geometry is uploaded once per scene; base colour textures stream their pyramid levels
(TextureStreamer); the per-pixel material maps (normal, metallic-roughness, occlusion: linear
data; emissive: sRGB) are uploaded once with hardware mipmaps. A mesh carries a tangent
attribute only when its material has a normal map. ``release()`` frees everything it made.

The material of one mesh reaches a shader through two calls, for every pass that draws meshes
(G-buffer, forward, blend, ids, and the shadow maps' depth passes):
``render.materials.material_defines(mesh)`` picks the program variant (``alpha_mask_defines``
for depth-only passes, with ``shaders/alpha_mask.glsl``) and
``GpuScene.bind_material(prog, index)`` sets its uniforms and textures (units from
``render.constants.TEXTURE_UNITS``).

Merged meshes (``GpuScene(merge=True)``, the renderer's default): real interiors hold a
thousand meshes or more, and on a software rasteriser each draw call (its program, uniforms,
textures and validation) costs more than its triangles. The meshes are grouped by material
into one vertex/index buffer pair per group (``GpuGroup``), each vertex carrying its mesh's
index (``in_object``). What a per-mesh draw sets as uniforms (the TCR level
and tint) is one row per mesh of the per-object table, an SSBO at
``render.constants.OBJECT_TABLE_BINDING`` that ``geometry.vert.glsl`` reads under the
``OBJECT_TABLE`` variant (``write_object_table``). A group's index buffer holds every member's
chunks (``app.lod``) level by level: all level-0 ranges first, in member order, then level 1,
and so on. Culling and level choice stay per chunk, so per mesh (``render.culling`` on the
groups' chunk table), and the visible ranges that touch are drawn as one call: a group seen
whole at full detail is one call, and a group split into several ranges is one indirect
multi-draw of them. Blended groups keep each member's chunks too (``draw_members``): the blend
pass sorts meshes back to front as before and draws each run of one group's meshes in that
order as one multi-draw. ``merge=False`` keeps the per-mesh path (tests, debugging).

The geometry is held once: merged, a mesh has no buffers of its own (only the standalone ones
do), so its group's are all there is; ``geometry_bytes`` counts them (the bench's
``geometry.gpu_bytes``).
"""

from __future__ import annotations

import logging
import math
import time
import weakref
from collections.abc import Sequence
from dataclasses import dataclass

import moderngl
import numpy as np

from app.ao_bake import BackgroundBake
from app.camera import EyeView
from app.scene import Light, Material, Scene, Texture
from app.tangents import generate_tangents
from render.constants import LEVEL_TINTS, MAX_LIGHTS, OBJECT_TABLE_BINDING
from render.culling import (
    Chunks,
    chunk_mesh,
    frustum_planes,
    indirect_commands,
    lod_levels,
    merge_chunks,
    triangles_by_error,
    visible_ranges,
)
from render.materials import factor_writes
from render.texture_stream import TextureStreamer

log = logging.getLogger(__name__)
VERTEX_FORMAT = "3f 3f 2f 3f"
VERTEX_ATTRS = ("in_position", "in_normal", "in_uv", "in_color")
TANGENT_FORMAT = VERTEX_FORMAT + " 4f"  # meshes with a normal map
TANGENT_ATTRS = (*VERTEX_ATTRS, "in_tangent")
GL_SRGB8_ALPHA8 = 0x8C43

# Material map -> the sampler's name (TEXTURE_UNITS, ``u_<name>``) and whether it is colour.
MAPS = {
    "normal_texture": ("normal_map", False),
    "metallic_roughness_texture": ("mr_map", False),
    "occlusion_texture": ("occlusion_map", False),
    "emissive_texture": ("emissive_map", True),
}


@dataclass
class GpuMesh:
    """One mesh. Its own vertex/index/sky buffers only where it is drawn on its own (every
    mesh with ``merge=False``, the standalone ones with it); a merged mesh's geometry lives
    in its group's buffers alone (None here), so the scene holds it once."""

    name: str
    vbo: moderngl.Buffer | None
    ibo: moderngl.Buffer | None
    material: Material
    texture: int | None  # index into GpuScene.streamer
    vertex_count: int
    sky_vbo: moderngl.Buffer | None  # per vertex: sky visibility front, back (2f; 0 unbaked)
    tangents: bool = False  # the vertex buffer has a tangent (TANGENT_FORMAT)
    centre: tuple[float, float, float] = (0.0, 0.0, 0.0)  # bounding-box centre (blend order)
    maps: dict[str, moderngl.Texture] | None = None  # sampler name -> material map
    # Ranges of the index buffer, each with its world-space bounds (render.culling): one for
    # a small mesh, spatially coherent chunks of a big one.
    chunks: Chunks | None = None

    @property
    def blended(self) -> bool:
        return self.material.alpha_mode == "BLEND"


@dataclass
class GpuGroup:
    """Meshes of one material (none blended) in one vertex/index buffer pair. ``members``:
    their mesh indices; ``chunks``: every member's chunks as ranges of this index buffer
    (level 0 of all members first, then each coarser level); ``index_count``: the level-0
    block's length (the whole group at full detail)."""

    material_index: int
    members: list[int]
    vbo: moderngl.Buffer
    ibo: moderngl.Buffer
    sky_vbo: moderngl.Buffer
    object_vbo: moderngl.Buffer  # per vertex: the mesh index (1i)
    material: Material
    texture: int | None
    vertex_counts: list[int]  # each member's vertices, in order
    index_count: int
    tangents: bool = False
    maps: dict[str, moderngl.Texture] | None = None
    chunks: Chunks | None = None
    member_columns: list[tuple[int, int]] | None = None  # each member's columns of chunks

    @property
    def blended(self) -> bool:
        return self.material.alpha_mode == "BLEND"

    def member_chunks(self, k: int) -> Chunks:
        """Member ``k``'s chunks as ranges of this group's index buffer."""
        assert self.chunks is not None and self.member_columns is not None
        a, b = self.member_columns[k]
        c = self.chunks
        return Chunks(c.first[:, a:b], c.count[:, a:b], c.error[:, a:b], c.lo[a:b], c.hi[a:b])


class GpuScene:
    def __init__(
        self,
        ctx: moderngl.Context,
        scene: Scene,
        anisotropy: float = 1.0,
        stream_in: bool = False,
        merge: bool = True,
    ) -> None:
        started = time.perf_counter()
        self.ctx = ctx
        self.scene = scene
        # Textures no material uses as its base colour are not streamed (a 1x1 stands in,
        # keeping the indices): they are material maps, uploaded below.
        colour = {mat.texture for mat in scene.materials}
        streamed = [
            t if i in colour else Texture(t.name, _PLACEHOLDER, t.repeat)
            for i, t in enumerate(scene.textures)
        ]
        self.streamer = TextureStreamer(ctx, streamed, anisotropy=anisotropy, stream_in=stream_in)
        self.anisotropy = anisotropy
        self._maps: dict[tuple[int, bool], moderngl.Texture] = {}
        # program -> id(material) -> (material, its factors' uniforms and bytes): _bind
        self._factor_writes: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()
        self.meshes: list[GpuMesh] = []
        vertex_data: list[np.ndarray] = []  # each mesh's interleaved vertices (for merging)
        index_data: list[np.ndarray] = []  # and its drawing-order indices (every level)
        for m in scene.meshes:
            colors = m.colors if m.colors is not None else np.ones_like(m.positions)
            mat = scene.materials[m.material]
            maps = self._material_maps(mat)
            columns = [m.positions, m.normals, m.uvs, colors]
            tangents = "normal_map" in maps
            if tangents:
                t = m.tangents
                if t is None or len(t) != len(m.positions):
                    t = generate_tangents(m.positions, m.normals, m.uvs, m.indices)
                columns.append(t)
            data = np.hstack(columns).astype(np.float32)
            lo, hi = m.bounds() if len(m.positions) else (np.zeros(3), np.zeros(3))
            lod = m.lod
            if lod is not None and lod.source_triangles == m.triangle_count:
                indices, chunks = lod.triangles, lod.chunks  # app.lod: built at load
            else:
                indices, chunks = chunk_mesh(m.positions, m.indices)
            centre = (lo + hi) * 0.5
            vertex_data.append(data)
            index_data.append(np.asarray(indices, np.uint32).reshape(-1))
            self.meshes.append(
                GpuMesh(
                    m.name,
                    None,  # uploaded below unless the mesh is merged into a group
                    None,
                    mat,
                    mat.texture,
                    int(m.indices.size),  # the full level's index count
                    None,
                    tangents,
                    (float(centre[0]), float(centre[1]), float(centre[2])),
                    maps,
                    chunks,
                )
            )
        self.cull = True  # render.culling; off: every range drawn (the test's reference)
        self._all, self._owner = merge_chunks([m.chunks for m in self.meshes])
        self.groups: list[GpuGroup] = []
        self.standalone = list(range(len(self.meshes)))  # meshes drawn one by one
        self.group_of: dict[int, int] = {}  # mesh index -> its group
        self._member_all, self._member_owner = merge_chunks([])
        if merge:
            self._merge(vertex_data, index_data)
        for i in self.standalone:  # merged meshes: their group's buffers only
            mesh, data = self.meshes[i], vertex_data[i]
            mesh.vbo = ctx.buffer(data.tobytes())
            mesh.ibo = ctx.buffer(index_data[i].tobytes())
            mesh.sky_vbo = ctx.buffer(np.zeros((max(len(data), 1), 2), np.float32).tobytes())
        self._group_all, self._group_owner = merge_chunks([g.chunks for g in self.groups])
        del vertex_data, index_data
        n_rows = max(len(self.meshes), 1)
        self.object_table = ctx.buffer(reserve=n_rows * 16)
        self._table_key: bytes | None = None
        # Each mesh's base colour texture (-1: none), for the table's resident bases.
        self._texture_of = np.array(
            [-1 if m.texture is None else m.texture for m in self.meshes], np.int64
        )
        self._range_cache: dict[tuple, dict[int, list[tuple[int, int]]]] = {}
        self._glow: dict[str, np.ndarray] = {}  # per group or mesh: its material glows
        self.drawn: dict[int, int] = {}  # triangles drawn per view this frame (eye index)
        self.calls: dict[int, int] = {}  # the geometry pass's draw calls per eye this frame
        self.ranges: dict[int, int] = {}  # and the index ranges those calls drew
        self.draw_calls = 0  # every draw call issued for meshes or groups (a running count)
        # Index ranges drawn (a multi-draw's commands each count: llvmpipe runs each as a draw
        # of its own, with its own fixed cost), a running count like draw_calls.
        self.draw_ranges = 0
        self._group_vaos: dict[tuple[int, int], moderngl.VertexArray] = {}
        # A group whose visible ranges are several (culled members, levels of detail) is one
        # glMultiDrawElementsIndirect of them; False: one call per range (measuring).
        self.multi_draw = True
        self._indirect: dict[tuple, tuple[moderngl.Buffer, dict[int, tuple[int, int]]]] = {}
        self._group_ao_vaos: dict[tuple[int, int], moderngl.VertexArray] = {}
        self._group_ao_buffers: dict[int, moderngl.Buffer] = {}
        self.lod_bias = 0.0  # render.lod_bias: pixels a simplified level may stray (0: full)
        # The sky is drawn this frame (sky.enabled): the panes standing for it are not
        # (Material.sky_standin; ``shown``). Set by the renderer each frame.
        self.daylight = False
        # What unlit materials' glow is multiplied by this frame (app.sky.unlit_gain: the
        # day's outdoor lux with daylight on, else 1). Set by the renderer each frame.
        self.unlit_gain = 1.0
        self._vaos: dict[tuple[int, int], moderngl.VertexArray] = {}
        self._ao_vaos: dict[tuple[int, int], moderngl.VertexArray] = {}
        self._ao_buffers: dict[int, moderngl.Buffer] = {}  # uploaded when AO first draws
        self.ao_bake: BackgroundBake | None = None  # started when AO first draws, if needed
        self.light_list: list[Light] = []
        self.lights = np.zeros((0, 12), np.float32)
        self.light_buffer = ctx.buffer(reserve=3 * MAX_LIGHTS * 16)
        self.light_version = 0  # counts set_lights calls (the shadow maps' cache watches it)
        self.set_lights(scene.lights)
        ctx.finish()
        self.upload_s = time.perf_counter() - started  # geometry, maps, first texture levels

    @property
    def geometry_bytes(self) -> int:
        """GPU bytes of the geometry: every vertex, index, sky-visibility and object-index
        buffer of the meshes and merged groups (not the baked AO, uploaded when first drawn)."""
        buffers = [b for m in self.meshes for b in (m.vbo, m.ibo, m.sky_vbo) if b is not None]
        buffers += [b for g in self.groups for b in (g.vbo, g.ibo, g.sky_vbo, g.object_vbo)]
        return sum(b.size for b in buffers)

    def _merge(self, vertex_data: list[np.ndarray], index_data: list[np.ndarray]) -> None:
        """Group the meshes by material (``GpuGroup``), in the order of each group's first
        mesh; the empty ones stay standalone. A blended group's members keep their own chunk
        table (``_member_all``): the blend pass draws them in its back-to-front order."""
        by_material: dict[int, list[int]] = {}
        for i, (src, mesh) in enumerate(zip(self.scene.meshes, self.meshes)):
            if mesh.chunks is not None:
                by_material.setdefault(src.material, []).append(i)
        grouped = {i for members in by_material.values() for i in members}
        self.standalone = [i for i in range(len(self.meshes)) if i not in grouped]
        member_chunks: list[Chunks | None] = [None] * len(self.meshes)
        for material_index, members in by_material.items():
            group = self._group(material_index, members, vertex_data, index_data)
            for k, i in enumerate(members):
                self.group_of[i] = len(self.groups)
                if group.blended:
                    member_chunks[i] = group.member_chunks(k)
            self.groups.append(group)
        self._member_all, self._member_owner = merge_chunks(member_chunks)

    def _group(
        self,
        material_index: int,
        members: list[int],
        vertex_data: list[np.ndarray],
        index_data: list[np.ndarray],
    ) -> GpuGroup:
        first_mesh = self.meshes[members[0]]
        counts = [len(vertex_data[i]) for i in members]
        bases = np.concatenate([[0], np.cumsum(counts)[:-1]]).astype(np.int64)
        member_chunks: list[Chunks] = [c for c in (self.meshes[i].chunks for i in members) if c]
        levels = max(c.levels for c in member_chunks)
        columns = sum(c.first.shape[1] for c in member_chunks)
        spans = np.cumsum([0] + [c.first.shape[1] for c in member_chunks]).tolist()
        first = np.zeros((levels, columns), np.int64)
        count = np.zeros((levels, columns), np.int64)
        error = np.zeros((levels, columns))
        parts: list[np.ndarray] = []
        offset = 0
        for level in range(levels):
            col = 0
            for base, i, c in zip(bases, members, member_chunks):
                n = c.first.shape[1]
                own = min(level, c.levels - 1)
                error[level, col : col + n] = c.error[own]
                if level < c.levels:
                    indices = index_data[i]
                    for k in range(n):
                        a, b = int(c.first[level, k]), int(c.count[level, k])
                        parts.append(indices[a : a + b] + np.uint32(base))
                        first[level, col + k], count[level, col + k] = offset, b
                        offset += b
                else:  # a mesh with fewer levels repeats its coarsest
                    first[level, col : col + n] = first[own, col : col + n]
                    count[level, col : col + n] = count[own, col : col + n]
                col += n
        chunks = Chunks(
            first,
            count,
            error,
            np.concatenate([c.lo for c in member_chunks]),
            np.concatenate([c.hi for c in member_chunks]),
        )
        ctx = self.ctx
        vertices = np.concatenate([vertex_data[i] for i in members])
        objects = np.repeat(np.asarray(members, np.int32), counts)
        return GpuGroup(
            material_index,
            list(members),
            ctx.buffer(np.ascontiguousarray(vertices, np.float32).tobytes()),
            ctx.buffer(np.concatenate(parts).astype(np.uint32).tobytes()),
            ctx.buffer(np.zeros((max(len(vertices), 1), 2), np.float32).tobytes()),
            ctx.buffer(objects.tobytes()),
            first_mesh.material,
            first_mesh.texture,
            counts,
            int(count[0].sum()),
            first_mesh.tangents,
            first_mesh.maps,
            chunks,
            list(zip(spans[:-1], spans[1:])),
        )

    def write_object_table(self, levels: list[int] | None) -> None:
        """The per-object table (one row per mesh: the TCR tint of its level and that level
        minus its texture's resident base, as the per-mesh path's ``u_tint`` / ``u_level``),
        uploaded when it changes and bound for the merged groups' draws."""
        n = len(self.meshes)
        rows = np.zeros((max(n, 1), 4), np.float32)
        rows[:, :3] = 1.0
        if levels is not None and len(levels) == n and n:
            lv = np.asarray(levels, np.int64)
            tints = np.asarray(LEVEL_TINTS, np.float32)
            rows[:n, :3] = tints[np.clip(lv, 0, len(LEVEL_TINTS) - 1)]
            bases = np.array([0, *(r.base for r in self.streamer.resident)], np.int64)
            rows[:n, 3] = lv - bases[self._texture_of + 1]  # untextured: 0 (unused)
        data = rows.tobytes()
        if data != self._table_key:
            self.object_table.write(data)
            self._table_key = data
        self.object_table.bind_to_storage_buffer(OBJECT_TABLE_BINDING)

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

    def _material_maps(self, mat: Material) -> dict[str, moderngl.Texture]:
        out = {}
        for field, (sampler, srgb) in MAPS.items():
            index = getattr(mat, field)
            if index is not None and 0 <= index < len(self.scene.textures):
                out[sampler] = self._map(index, srgb)
        return out

    def _map(self, index: int, srgb: bool) -> moderngl.Texture:
        """Texture ``index`` as a material map, uploaded once per colour space."""
        key = (index, srgb)
        if key not in self._maps:
            src = self.scene.textures[index]
            h, w = src.rgba.shape[:2]
            rows = np.ascontiguousarray(np.flipud(src.rgba))  # GL rows: bottom first
            tex = self.ctx.texture(
                (w, h), 4, rows.tobytes(), internal_format=GL_SRGB8_ALPHA8 if srgb else None
            )
            tex.build_mipmaps()
            tex.filter = (moderngl.LINEAR_MIPMAP_LINEAR, moderngl.LINEAR)
            tex.repeat_x = tex.repeat_y = src.repeat
            tex.anisotropy = self.anisotropy
            self._maps[key] = tex
        return self._maps[key]

    def bind_material(
        self, prog: moderngl.Program, index: int, names: tuple[str, ...] | None = None
    ) -> None:
        """Mesh ``index``'s material into ``prog``: factors (where the variant has them) and
        textures on their units. ``names``: only these samplers (default: all it has)."""
        self._bind(prog, self.meshes[index], names)

    def bind_group_material(
        self, prog: moderngl.Program, group: int, names: tuple[str, ...] | None = None
    ) -> None:
        """As :meth:`bind_material`, for merged group ``group`` (one material)."""
        self._bind(prog, self.groups[group], names)

    def _bind(
        self, prog: moderngl.Program, mesh: GpuMesh | GpuGroup, names: tuple[str, ...] | None
    ) -> None:
        from render.pass_graph import bind_texture  # it imports this module

        mat = mesh.material
        # The factors as bytes, per program and material, packed once (the G-buffer binds a
        # material for every draw of both eyes: ~250 draws a frame in a 62-material room).
        by_material = self._factor_writes.get(prog)
        if by_material is None:
            by_material = self._factor_writes[prog] = {}
        gain = self.unlit_gain if mat.unlit else 1.0
        writes = by_material.get(id(mat))
        if writes is None or writes[0] is not mat or writes[1] != gain:
            writes = by_material[id(mat)] = (mat, gain, factor_writes(prog, mat, gain))
        for member, data in writes[2]:
            member.write(data)
        if mesh.texture is not None and (names is None or "albedo" in names):
            bind_texture(prog, "albedo", self.streamer.resident[mesh.texture].tex, optional=True)
        for sampler, tex in (mesh.maps or {}).items():
            if names is None or sampler in names:
                bind_texture(prog, sampler, tex, optional=True)

    def shown(self, material: Material) -> bool:
        """Whether meshes of ``material`` are drawn this frame: all but a pane standing for the
        sky while the sky itself is drawn (daylight on)."""
        return not (self.daylight and material.sky_standin)

    def shown_groups(self) -> list[int]:
        """The merged groups drawn this frame (``shown``)."""
        return [g for g, group in enumerate(self.groups) if self.shown(group.material)]

    def shown_standalone(self) -> list[int]:
        """The meshes drawn one by one this frame (``shown``)."""
        return [i for i in self.standalone if self.shown(self.meshes[i].material)]

    def draw(
        self,
        vao: moderngl.VertexArray,
        index: int,
        view_projection: np.ndarray | None = None,
        eye: EyeView | None = None,
    ) -> int:
        """Draw mesh ``index`` through ``vao``: only its chunks inside the frustum of
        ``view_projection`` (None: all of them), each at the level of detail ``lod_bias``
        allows seen from ``eye`` (None: full detail). Returns the triangles drawn."""
        chunks = self.meshes[index].chunks
        if chunks is None:
            return 0
        if view_projection is None or not self.cull:
            vao.render(moderngl.TRIANGLES, vertices=self.meshes[index].vertex_count)
            self.draw_calls += 1
            self.draw_ranges += 1
            return self.meshes[index].vertex_count // 3
        return self._draw_ranges(vao, self._view_ranges(view_projection, eye).get(index, ()))

    def draw_group(
        self,
        vao: moderngl.VertexArray,
        group: int,
        view_projection: np.ndarray | None = None,
        eye: EyeView | None = None,
    ) -> int:
        """As :meth:`draw`, for merged group ``group``: its members' visible chunks at their
        levels, neighbouring ranges as one call. Returns the triangles drawn."""
        g = self.groups[group]
        if view_projection is None or not self.cull:
            vao.render(moderngl.TRIANGLES, vertices=g.index_count)
            self.draw_calls += 1
            self.draw_ranges += 1
            return g.index_count // 3
        key = self._view_key(view_projection, eye, True)
        every = self._view_ranges(view_projection, eye, merged=True)
        ranges = every.get(group, ())
        if len(ranges) < 2 or not self.multi_draw:
            return self._draw_ranges(vao, ranges)
        if key not in self._indirect:
            self._indirect[key] = self._commands(every)
        buffer, offsets = self._indirect[key]
        start, n = offsets[group]
        vao.render_indirect(buffer, moderngl.TRIANGLES, count=n, first=start)
        self.draw_calls += 1
        self.draw_ranges += n
        return sum(count for _, count in ranges) // 3

    def draw_members(
        self,
        vao: moderngl.VertexArray,
        members: list[int],
        view_projection: np.ndarray,
        eye: EyeView | None = None,
    ) -> int:
        """Meshes ``members`` of one blended group through its ``vao``, in this order (the
        blend pass's back to front), each culled and at its level as :meth:`draw` would:
        one indirect multi-draw of their ranges. Returns the triangles drawn."""
        if self.cull:
            every = self._view_ranges(view_projection, eye, merged="members")
        else:
            every = visible_ranges(self._member_all, np.zeros((0, 4)), None, self._member_owner)
        ranges: list[tuple[int, int]] = []
        for m in members:
            for first, count in every.get(m, ()):
                if ranges and ranges[-1][0] + ranges[-1][1] == first:
                    ranges[-1] = (ranges[-1][0], ranges[-1][1] + count)
                else:
                    ranges.append((first, count))
        if len(ranges) < 2 or not self.multi_draw:
            return self._draw_ranges(vao, ranges)
        buffer, _ = self._commands({0: ranges})
        vao.render_indirect(buffer, moderngl.TRIANGLES, count=len(ranges))
        buffer.release()
        self.draw_calls += 1
        self.draw_ranges += len(ranges)
        return sum(count for _, count in ranges) // 3

    def _commands(
        self, every: dict[int, list[tuple[int, int]]]
    ) -> tuple[moderngl.Buffer, dict[int, tuple[int, int]]]:
        """:func:`render.culling.indirect_commands` in one buffer, and where each group's are."""
        data, offsets = indirect_commands(every)
        return self.ctx.buffer(data.tobytes()), offsets

    def _draw_ranges(self, vao: moderngl.VertexArray, ranges) -> int:
        drawn = 0
        for first, count in ranges:
            vao.render(moderngl.TRIANGLES, vertices=count, first=first)
            drawn += count
        self.draw_calls += len(ranges)
        self.draw_ranges += len(ranges)
        return drawn // 3

    def _table(self, merged: bool | str) -> tuple[Chunks, np.ndarray]:
        if merged == "members":  # blended groups' members, in their groups' index buffers
            return self._member_all, self._member_owner
        return (self._group_all, self._group_owner) if merged else (self._all, self._owner)

    def _view_ranges(
        self, view_projection: np.ndarray, eye: EyeView | None, merged: bool | str = False
    ) -> dict[int, list[tuple[int, int]]]:
        """Every mesh's (``merged``: every group's; ``"members"``: every blended group
        member's) ranges to draw for one view, its chunks tested and their levels chosen all
        at once (real rooms hold hundreds of meshes); the last views' answers are kept, so
        the passes of a frame that draw the same eye share them."""
        table, owner = self._table(merged)
        lod = eye is not None and self.lod_bias > 0
        key = self._view_key(view_projection, eye, merged)
        if key in self._range_cache:
            return self._range_cache[key]
        levels = None
        if lod and eye is not None:
            pixels_per_radian = float(eye.projection[1, 1]) * eye.height * 0.5
            keep = self._glowing(merged)[owner] if len(owner) else None
            levels = lod_levels(table, eye.position, pixels_per_radian, self.lod_bias, keep)
        ranges = visible_ranges(table, frustum_planes(view_projection), levels, owner)
        if len(self._range_cache) >= 16:  # two eyes and the shadow maps' faces of a frame
            self._range_cache.clear()
            for buffer, _ in self._indirect.values():
                buffer.release()
            self._indirect.clear()
        self._range_cache[key] = ranges
        return ranges

    def triangles_by_error(self, eye: EyeView, errors: tuple[float, ...]) -> dict[float, int]:
        """:func:`render.culling.triangles_by_error` for every mesh, seen by ``eye``."""
        keep = self._glowing(False)[self._owner] if len(self._owner) else None
        return triangles_by_error(self._all, eye, errors, keep)

    def _glowing(self, merged: bool | str) -> np.ndarray:
        """Per owner of a chunk table (a group where ``merged`` is True, else a mesh): whether
        its material glows (kept however small it is on screen)."""
        key = "groups" if merged is True else "meshes"
        if key not in self._glow:
            if key == "groups":
                mats = [self.scene.materials[g.material_index] for g in self.groups]
            else:
                mats = [m.material for m in self.meshes]
            self._glow[key] = np.array([max(m.emissive) > 0.0 for m in mats] + [False], bool)
        return self._glow[key]

    def _view_key(
        self, view_projection: np.ndarray, eye: EyeView | None, merged: bool | str
    ) -> tuple:
        lod = eye is not None and self.lod_bias > 0
        return (
            merged,
            np.asarray(view_projection, np.float64).tobytes(),
            np.asarray(eye.position, np.float64).tobytes() if lod and eye is not None else b"",
            self.lod_bias if lod else 0.0,
        )

    def _vertex_array(
        self,
        program: moderngl.Program,
        mesh: GpuMesh | GpuGroup,
        extra: Sequence[tuple[moderngl.Buffer | None, str, str]],
    ) -> moderngl.VertexArray:
        """``mesh``'s vertices (the attributes ``program`` has) plus ``extra`` buffers whose
        attribute ``program`` uses."""
        layout = (TANGENT_FORMAT, TANGENT_ATTRS) if mesh.tangents else (VERTEX_FORMAT, VERTEX_ATTRS)
        attrs = [a for a in layout[1] if a in program]
        fmt = " ".join(
            f if a in attrs else f[0] + "x4" for f, a in zip(layout[0].split(), layout[1])
        )
        if mesh.vbo is None:
            raise ValueError(
                f"mesh '{getattr(mesh, 'name', '')}' is merged into a group: draw its group"
            )
        buffers: list = [(mesh.vbo, fmt, *attrs)]
        buffers += [(buf, f, name) for buf, f, name in extra if buf is not None and name in program]
        return self.ctx.vertex_array(program, buffers, index_buffer=mesh.ibo, index_element_size=4)

    def vao(self, program: moderngl.Program, index: int) -> moderngl.VertexArray:
        key = (program.glo, index)
        if key not in self._vaos:
            mesh = self.meshes[index]
            self._vaos[key] = self._vertex_array(program, mesh, [(mesh.sky_vbo, "2f", "in_sky")])
        return self._vaos[key]

    def group_vao(self, program: moderngl.Program, group: int) -> moderngl.VertexArray:
        """Merged group ``group`` through ``program`` (with its mesh indices as in_object)."""
        key = (program.glo, group)
        if key not in self._group_vaos:
            g = self.groups[group]
            extra = [(g.sky_vbo, "2f", "in_sky"), (g.object_vbo, "1i", "in_object")]
            self._group_vaos[key] = self._vertex_array(program, g, extra)
        return self._group_vaos[key]

    def _mesh_ao(self, index: int) -> np.ndarray:
        """Mesh ``index``'s baked occlusion (N, 2), 1 where it has none or a wrong count."""
        src = self.scene.meshes[index]
        n = int(src.positions.shape[0])
        ok = src.ao is not None and src.ao.shape == (n, 2)
        return np.asarray(src.ao if ok else np.ones((n, 2)), np.float32)

    def ao_vao(self, program: moderngl.Program, index: int) -> moderngl.VertexArray:
        """Mesh ``index`` with its baked ambient occlusion as ``in_ao`` (render/ao.py); the
        occlusion is uploaded on first use (1 where the mesh has none or a wrong count). A
        scene without starts its bake in the background and is drawn unoccluded until then."""
        self._poll_ao_bake()
        key = (program.glo, index)
        if key not in self._ao_vaos:
            mesh = self.meshes[index]
            if index not in self._ao_buffers:
                self._ao_buffers[index] = self.ctx.buffer(self._mesh_ao(index).tobytes())
            extra = [(self._ao_buffers[index], "2f", "in_ao")]
            self._ao_vaos[key] = self._vertex_array(program, mesh, extra)
        return self._ao_vaos[key]

    def group_ao_vao(self, program: moderngl.Program, group: int) -> moderngl.VertexArray:
        """As :meth:`ao_vao`, for merged group ``group`` (its members' occlusion in order)."""
        self._poll_ao_bake()
        key = (program.glo, group)
        if key not in self._group_ao_vaos:
            g = self.groups[group]
            if group not in self._group_ao_buffers:
                ao = np.concatenate([self._mesh_ao(i) for i in g.members])
                self._group_ao_buffers[group] = self.ctx.buffer(ao.tobytes())
            extra = [(self._group_ao_buffers[group], "2f", "in_ao")]
            self._group_ao_vaos[key] = self._vertex_array(program, g, extra)
        return self._group_ao_vaos[key]

    def _poll_ao_bake(self) -> None:
        if self.ao_bake is None:
            if all(m.ao is not None for m in self.scene.meshes):
                return
            self.ao_bake = BackgroundBake(self.scene)
        if self.ao_bake.done and self.ao_bake.result is not None:
            self.scene, self.ao_bake.result = self.ao_bake.result, None
            self._release_ao()  # next draws upload the baked values

    def _release_ao(self) -> None:
        for v in (*self._ao_vaos.values(), *self._group_ao_vaos.values()):
            v.release()
        for b in (*self._ao_buffers.values(), *self._group_ao_buffers.values()):
            b.release()
        self._ao_vaos.clear()
        self._ao_buffers.clear()
        self._group_ao_vaos.clear()
        self._group_ao_buffers.clear()

    def release(self) -> None:
        self._release_ao()
        for v in (*self._vaos.values(), *self._group_vaos.values()):
            v.release()
        self._group_vaos.clear()
        for m in self.meshes:
            for buf in (m.vbo, m.ibo, m.sky_vbo):
                if buf is not None:
                    buf.release()
        for g in self.groups:
            for buf in (g.vbo, g.ibo, g.sky_vbo, g.object_vbo):
                buf.release()
        self.groups.clear()
        for buffer, _ in self._indirect.values():
            buffer.release()
        self._indirect.clear()
        self.object_table.release()
        self.streamer.release()
        for tex in self._maps.values():
            tex.release()
        self._maps.clear()
        self.light_buffer.release()
        self._vaos.clear()
        self.meshes.clear()

    def set_sky_visibility(self, values: list[np.ndarray]) -> None:
        """Each mesh's per-vertex sky visibility ((N, 2): front, back), from app.sky_light."""
        for mesh, v in zip(self.meshes, values):
            data = np.ascontiguousarray(v, np.float32)
            if mesh.sky_vbo is not None and data.nbytes == mesh.sky_vbo.size:
                mesh.sky_vbo.write(data.tobytes())
        for g in self.groups:
            if max(g.members) >= len(values):
                continue
            rows = [np.ascontiguousarray(values[i], np.float32).reshape(-1) for i in g.members]
            if all(r.size == 2 * n for r, n in zip(rows, g.vertex_counts)):
                g.sky_vbo.write(np.concatenate(rows).tobytes())

    @property
    def texture_bytes(self) -> int:
        maps = sum(t.width * t.height * 4 * 4 // 3 for t in self._maps.values())
        return self.streamer.resident_bytes() + maps

    def texture_levels(self) -> list[int]:
        """Pyramid depth n of each mesh's texture (0 for untextured meshes)."""
        return [
            self.streamer.n_levels(m.texture) if m.texture is not None else 0 for m in self.meshes
        ]


_PLACEHOLDER = np.full((1, 1, 4), 255, np.uint8)


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
