"""The photon-map gather on the GPU (paper 3.1-3.2): irradiance from the photons near a point.

``GpuPhotonMap`` is one photon map uploaded for one radius and search structure (hash grid with
cells of r or r/2, or a kd-tree); ``PhotonGather`` runs the estimate at a list of points
(``photon_points.comp.glsl``, for tests and benchmarks) or over an eye's G-buffer
(``photon_gather.comp.glsl``). The estimate itself lives in ``photon_gather.glsl`` so the
lighting shaders can include it; it matches ``app.lab.photon_ref`` (see that module and the shader).

Variants (``VARIANTS``), as in the paper's tables:
  radius       hash grid, cell r, 3x3x3 cells as 9 runs of 3 (the paper's method, no heap)
  radius-half  hash grid, cell r/2, 5x5x5 cells as 25 runs of 5
  heap         hash grid + k-nearest max-heap (the kNN baseline, Tables 1-2)
  kdtree       kd-tree, stack traversal, radius query (the kd-tree baseline)
  kdtree-heap  kd-tree + k-nearest max-heap
  shared       hash grid, Algorithm 1: a group whose 64 queries share one cell streams that
               cell's photons through shared memory (Table 4)

On the GPU a map is the 32-byte records (``PhotonMap.records``, sorted by cell or in tree order)
and the grid's start array, each twice: as SSBOs (bindings 0 and 1, the data contract) and as
unsigned integer textures 4096 texels wide (samplers u_pm_records, u_pm_starts). The gather
reads the textures by default because Mesa's llvmpipe runs an SSBO load in a divergent loop as
a per-lane scalar loop (about 9x slower here); ``PhotonGather(source="ssbo")`` reads the SSBOs
instead, bit for bit the same result. On llvmpipe ``shared`` is slower than ``radius`` (its
barriers cost more than the shared fetches save); it is there for the paper's comparison and for
real GPUs.
"""

from __future__ import annotations

import math
import time
from typing import Any

import moderngl
import numpy as np

from app.camera import gl_bytes
from app.hashgrid import HashGrid, KdTree, check_radius
from app.photon_map import PhotonMap
from render.constants import PM_GROUP, PM_MAX_K, PM_NO_WINNER, PM_TEX_SHIFT
from render.pass_graph import bind_image, bind_texture, set_uniforms
from render.shaders import ShaderLibrary

VARIANTS = ("radius", "radius-half", "heap", "kdtree", "kdtree-heap", "shared")
STRUCTURES = ("grid", "grid-half", "kdtree")
# The structure each variant reads; "heap" and "shared" also run on a "grid-half" map.
STRUCTURE_OF = {
    "radius": "grid",
    "radius-half": "grid-half",
    "heap": "grid",
    "kdtree": "kdtree",
    "kdtree-heap": "kdtree",
    "shared": "grid",
}
MAX_K = PM_MAX_K  # the heap lives in registers / private memory; the shader refuses more
GROUP = PM_GROUP  # invocations per work group in both entries (8x8 and 64x1); SHARED relies on it
NO_WINNER = PM_NO_WINNER  # u_reuse_winner's "no left pixel lands here"
COUNTER_NAMES = ("gathered", "reused", "visited", "within")
# Texture and image units: render.constants.TEXTURE_UNITS / IMAGE_UNITS (by sampler name).
TEX_SHIFT = PM_TEX_SHIFT  # injected into the shaders as PM_TEX_SHIFT
TEX_WIDTH = 1 << TEX_SHIFT
# SSBO bindings (photon_gather.glsl and photon_points.comp.glsl).
BIND_PHOTONS, BIND_START, BIND_COUNTERS, BIND_POINTS, BIND_NORMALS, BIND_OUT = 0, 1, 2, 3, 4, 5
SOURCES = ("texture", "ssbo")  # where the gather reads the records and the start array


def _texture_rows(
    ctx: moderngl.Context, words: np.ndarray, components: int, what: str
) -> moderngl.Texture:
    """``words`` (uint32, ``components`` per texel) as a TEX_WIDTH-wide unsigned texture."""
    texels = max(1, -(-words.size // components))
    rows = -(-texels // TEX_WIDTH)
    limit = int(ctx.info.get("GL_MAX_TEXTURE_SIZE", 16384))
    if rows > limit:
        raise ValueError(
            f"photon map too large for one texture: {what} needs {rows} rows of "
            f"{TEX_WIDTH} texels, the driver allows {limit}"
        )
    data = np.zeros(rows * TEX_WIDTH * components, np.uint32)
    data[: words.size] = words.ravel()
    tex = ctx.texture((TEX_WIDTH, rows), components, data.tobytes(), dtype="u4")
    tex.filter = (moderngl.NEAREST, moderngl.NEAREST)
    return tex


class GpuPhotonMap:
    """One photon map on the GPU for one radius and one search structure.

    ``structure``: "grid" (cells of edge r), "grid-half" (cells of r/2) or "kdtree". The records
    go up sorted by cell (grid) or in tree order with the split axis in ``extra`` (kd-tree).
    Raises ``app.hashgrid.GridTooLarge`` when a grid would not fit; the caller picks a larger
    radius or the kd-tree. Zero photons work (every estimate is 0).
    """

    def __init__(
        self, ctx: moderngl.Context, photons: PhotonMap, radius: float, structure: str = "grid"
    ) -> None:
        if structure not in STRUCTURES:
            raise ValueError(f"unknown photon map structure {structure!r}; one of {STRUCTURES}")
        radius = check_radius(radius)
        self.ctx = ctx
        self.structure = structure
        self.radius = radius
        self.photon_count = len(photons)
        self.grid: HashGrid | None = None
        self.tree: KdTree | None = None
        t0 = time.perf_counter()
        if structure == "kdtree":
            self.tree = KdTree.build(photons.positions)
            records = photons.records(self.tree.order, self.tree.axis.astype(np.uint32))
            start = np.zeros(1, np.uint32)
        else:
            self.grid = HashGrid.build(
                photons.positions, radius, cells_per_radius=2 if structure == "grid-half" else 1
            )
            records = photons.records(self.grid.order)
            start = np.ascontiguousarray(self.grid.start, np.uint32)
        self.build_ms = (time.perf_counter() - t0) * 1e3
        # GL refuses zero-sized buffers: pad to one record / one word (u_pm_count says 0).
        self.photons = ctx.buffer(records if records else bytes(32))
        self.start = ctx.buffer(start.tobytes() if start.size else bytes(4))
        # The same bytes as textures, which is what the gather reads by default.
        self.records_texture = _texture_rows(
            ctx, np.frombuffer(records, np.uint32), 4, "the photon records"
        )
        self.starts_texture = _texture_rows(ctx, start, 1, "the grid's start array")

    @property
    def reach(self) -> int:
        """Cells searched on each side of the query cell (grid), 0 for the kd-tree."""
        return int(self.grid.reach) if self.grid is not None else 0

    @property
    def nbytes(self) -> int:
        """GPU memory held: the SSBOs and their texture copies."""
        return 2 * (self.photons.size + self.start.size)

    def bind(self, prog: moderngl.ComputeShader | moderngl.Program) -> None:
        """Bind the photon (0) and start (1) SSBOs, the same data as textures (pm_records,
        pm_starts; the PM_SSBO variant has none) and set the u_pm_* uniforms ``prog`` uses
        (the kd-tree variants have no grid; a zero-photon estimate may drop the rest)."""
        self.photons.bind_to_storage_buffer(BIND_PHOTONS)
        self.start.bind_to_storage_buffer(BIND_START)
        bind_texture(prog, "pm_records", self.records_texture, optional=True)
        bind_texture(prog, "pm_starts", self.starts_texture, optional=True)
        r2 = self.radius * self.radius
        values: dict[str, Any] = {
            "u_pm_count": self.photon_count,
            "u_pm_radius2": r2,
            "u_pm_norm": 1.0 / (math.pi * r2),
        }
        if self.grid is not None:
            values.update(
                u_pm_origin=tuple(float(v) for v in self.grid.origin),
                u_pm_cell=float(self.grid.cell),
                u_pm_dims=tuple(int(v) for v in self.grid.dims),
            )
        set_uniforms(prog, {}, optional=values)

    def release(self) -> None:
        for obj in (self.photons, self.start, self.records_texture, self.starts_texture):
            obj.release()


class PhotonGather:
    """Runs the gather variants; programs come from the (caching) ShaderLibrary."""

    def __init__(
        self, ctx: moderngl.Context, shaders: ShaderLibrary, source: str = "texture"
    ) -> None:
        if source not in SOURCES:
            raise ValueError(f"unknown photon record source {source!r}; one of {SOURCES}")
        self.ctx = ctx
        self.shaders = shaders
        self.source = source  # "ssbo" only to compare: it is ~9x slower on llvmpipe
        self.counting = False  # default for the ``count`` argument of the gathers
        # Pairs of 32-bit words per counter (low, high): see pm_count in photon_gather.glsl.
        self._counters = ctx.buffer(bytes(4 * 2 * len(COUNTER_NAMES)))

    def defines(self, gmap: GpuPhotonMap, variant: str, k: int = 32) -> dict[str, object]:
        """The core defines for ``variant`` on ``gmap`` (checks that they fit together)."""
        if variant not in VARIANTS:
            raise ValueError(f"unknown gather variant {variant!r}; one of {VARIANTS}")
        want = STRUCTURE_OF[variant]
        kd = want == "kdtree"
        if kd != (gmap.structure == "kdtree") or (
            variant in ("radius", "radius-half") and gmap.structure != want
        ):
            raise ValueError(
                f"variant {variant!r} needs a {want!r} photon map, not {gmap.structure!r}"
            )
        d: dict[str, object] = {"KDTREE": True} if kd else {"GRID": True, "GRID_REACH": gmap.reach}
        if variant in ("heap", "kdtree-heap"):
            k = int(k)
            if not 1 <= k <= MAX_K:
                raise ValueError(f"heap size k must be 1..{MAX_K}, not {k}")
            d.update(HEAP=True, HEAP_K=k)
        if variant == "shared":
            d["SHARED"] = True
        if self.source == "ssbo":
            d["PM_SSBO"] = True
        return d

    def gather_points(
        self,
        gmap: GpuPhotonMap,
        points: np.ndarray,
        normals: np.ndarray,
        variant: str = "radius",
        k: int = 32,
        count: bool | None = None,
    ) -> np.ndarray:
        """E at each point (M, 3) float32; ``normals`` are unit (M, 3). ``count`` adds the
        counters (visited / within photons, points as "gathered")."""
        pts = np.asarray(points, np.float32).reshape(-1, 3)
        nrm = np.asarray(normals, np.float32).reshape(-1, 3)
        if len(pts) != len(nrm):
            raise ValueError("points and normals differ in length")
        m = len(pts)
        if m == 0:
            return np.zeros((0, 3), np.float32)
        defines = self.defines(gmap, variant, k)
        defines["COUNT"] = self.counting if count is None else bool(count)
        prog = self.shaders.compute("photon_points.comp.glsl", defines)

        def vec4s(a: np.ndarray) -> bytes:
            v = np.zeros((m, 4), np.float32)
            v[:, :3] = a
            return v.tobytes()

        bufs = [
            self.ctx.buffer(vec4s(pts)),
            self.ctx.buffer(vec4s(nrm)),
            self.ctx.buffer(reserve=16 * m),
        ]
        try:
            for binding, buf in zip((BIND_POINTS, BIND_NORMALS, BIND_OUT), bufs):
                buf.bind_to_storage_buffer(binding)
            self._counters.bind_to_storage_buffer(BIND_COUNTERS)
            gmap.bind(prog)
            prog["u_points"].value = m
            prog.run(-(-m // GROUP))
            self.ctx.memory_barrier(moderngl.SHADER_STORAGE_BARRIER_BIT)
            out = np.frombuffer(bufs[2].read(), np.float32).reshape(m, 4)[:, :3].copy()
        finally:
            for buf in bufs:
                buf.release()
        return out

    def gather_image(
        self,
        gmap: GpuPhotonMap,
        variant: str,
        *,
        depth: moderngl.Texture,
        normal: moderngl.Texture,
        inv_view_projection: np.ndarray,
        size: tuple[int, int],
        out: moderngl.Texture,
        k: int = 32,
        block_rate: bool = False,
        levels: moderngl.Texture | None = None,
        reuse: tuple[moderngl.Texture, moderngl.Texture] | None = None,
        count: bool | None = None,
    ) -> None:
        """E per G-buffer pixel into ``out`` (rgba32f, image unit 0): rgb = E, a = 1 gathered,
        2 copied from the left eye, 0 background; pixels it does not own are left alone.

        ``block_rate`` with ``levels`` (the CPS level map, R8UI at half resolution): only each
        block's light-sample pixel gathers. ``reuse`` = (winner, left_result): ``winner`` an
        r32ui texture of this eye's size (NO_WINNER or the left pixel index y*W+x),
        ``left_result`` the left eye's ``out``; pixels with a winner copy it. ``count`` turns
        on the counters (a separate program, so timing runs do not pay for the atomics)."""
        defines = self.defines(gmap, variant, k)
        if block_rate and levels is None:
            raise ValueError("block_rate needs the CPS level map (levels=)")
        defines.update(
            BLOCK_RATE=bool(block_rate),
            REUSE=reuse is not None,
            COUNT=self.counting if count is None else bool(count),
        )
        prog = self.shaders.compute("photon_gather.comp.glsl", defines)
        w, h = int(size[0]), int(size[1])
        gmap.bind(prog)
        self._counters.bind_to_storage_buffer(BIND_COUNTERS)
        bind_texture(prog, "gb_normal", normal)
        bind_texture(prog, "gb_depth", depth)
        set_uniforms(
            prog,
            {
                "u_inv_view_projection": gl_bytes(np.asarray(inv_view_projection)),
                "u_size": (w, h),
            },
        )
        if block_rate:
            assert levels is not None
            bind_texture(prog, "levels", levels)
        if reuse is not None:
            winner, left = reuse
            bind_image(winner, "reuse_winner", read=True, write=False)
            bind_texture(prog, "left_result", left)
        bind_image(out, "out")
        prog.run(-(-w // 8), -(-h // 8))
        self.ctx.memory_barrier(
            moderngl.TEXTURE_FETCH_BARRIER_BIT | moderngl.SHADER_IMAGE_ACCESS_BARRIER_BIT
        )

    def counters(self) -> dict[str, int]:
        """Counts since reset_counters() (only runs with ``count=True`` add to them)."""
        self.ctx.memory_barrier(
            moderngl.BUFFER_UPDATE_BARRIER_BIT | moderngl.SHADER_STORAGE_BARRIER_BIT
        )
        words = np.frombuffer(self._counters.read(), np.uint32).astype(np.uint64)
        return {
            name: int(words[2 * i] + (words[2 * i + 1] << np.uint64(32)))
            for i, name in enumerate(COUNTER_NAMES)
        }

    def reset_counters(self) -> None:
        self._counters.write(bytes(self._counters.size))

    def release(self) -> None:
        self._counters.release()
