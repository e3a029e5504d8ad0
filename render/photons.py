"""Photon-mapped indirect light in the frame: the gather per eye, with stereo reuse.

The photon map is traced on the CPU (``app.photons``) by the host and handed over with
``PhotonPass.set_photons``; this pass keeps it on the GPU for the current radius and gather
variant (``render.photon_gather``) and writes each eye's irradiance E into an rgba32f target
that the deferred lighting adds (``deferred.glsl``, INDIRECT). Alpha marks how a pixel got its
value: 1 gathered, 2 reused from the left eye, 0 nothing (background, or not a block sample).

Stereo reuse (paper 3.3): the left eye gathers first; ``photon_reuse.comp.glsl`` lets each
left hit point that the right eye sees claim its right-eye pixel; the right eye then gathers
only where no left point landed.
"""

from __future__ import annotations

import logging
import time

import moderngl
import numpy as np

from app.irradiance_cache import cache_for
from app.photon_map import PhotonMap
from app.settings import PhotonSettings
from render.irradiance_cache import GpuIrradianceCache
from render.pass_graph import (
    FrameContext,
    RenderPass,
    Resources,
    bind_image,
    bind_texture,
    set_uniforms,
)
from render.passes import deferred
from render.photon_gather import NO_WINNER, STRUCTURE_OF, GpuPhotonMap, PhotonGather
from render.shaders import ShaderLibrary

log = logging.getLogger(__name__)


class PhotonPass(RenderPass):
    """Per eye the photons' irradiance ("indirect"), or, fused, the photon map that the
    lighting gathers itself ("photon_map"). At block rate (CPS) it reads the level map."""

    name = "photons"
    reads: tuple[str, ...] = ("depth", "normal")
    writes = ("indirect", "photon_map", "show_reuse")

    def __init__(self, ctx: moderngl.Context, shaders: ShaderLibrary, res: Resources) -> None:
        super().__init__(ctx, shaders, res)
        self.gather = PhotonGather(ctx, shaders)
        self.settings = PhotonSettings()
        self.photons: PhotonMap | None = None
        self.gmap: GpuPhotonMap | None = None
        self._gmap_key: tuple | None = None
        self.cache: GpuIrradianceCache | None = None  # photons.indirect = cache
        self._cache_key: tuple | None = None
        self.cache_builds = 0  # caches uploaded (a new photon map or radius builds one)
        self.outputs: list[moderngl.Texture] = []
        self.winner: moderngl.Texture | None = None
        self._clear_winner = b""
        self.block_rate = False
        self.measure = False  # bench: wall-clock per eye (waits for the GPU between eyes)
        self.eye_ms = [0.0, 0.0]
        self.error: str | None = None  # why there is no indirect light (a grid too large...)

    # -- inputs --------------------------------------------------------------------------------
    def set_photons(self, photons: PhotonMap | None) -> None:
        if photons is not self.photons:
            self.photons = photons
            self._drop_map()
            self._drop_cache()

    def _drop_map(self) -> None:
        if self.gmap is not None:
            self.gmap.release()
        self.gmap, self._gmap_key = None, None

    def _drop_cache(self) -> None:
        if self.cache is not None:
            self.cache.release()
        self.cache, self._cache_key = None, None

    def _ensure_cache(self, photons: PhotonMap) -> GpuIrradianceCache | None:
        """The irradiance cache of ``photons`` on the GPU (built on the photon service's worker
        thread after the trace; built here if the radius changed since)."""
        key = (id(photons), self.settings.radius_m)
        if key != self._cache_key:
            self._drop_cache()
            self._cache_key = key
            self.error = None
            try:
                self.cache = GpuIrradianceCache(self.ctx, cache_for(photons, key[1]))
                self.cache_builds += 1
            except (ValueError, moderngl.Error) as exc:
                self.error = str(exc)
                log.warning("no indirect light: %s", exc)
        return self.cache

    def _ensure_map(self, photons: PhotonMap) -> GpuPhotonMap | None:
        s = self.settings
        structure = STRUCTURE_OF[s.gather]
        key = (id(photons), s.radius_m, structure)
        if key != self._gmap_key:
            self._drop_map()
            self._gmap_key = key
            self.error = None
            try:
                self.gmap = GpuPhotonMap(self.ctx, photons, s.radius_m, structure)
            except ValueError as exc:  # GridTooLarge: a clear message, no indirect light
                self.error = str(exc)
                log.warning("no indirect light: %s", exc)
        return self.gmap

    @property
    def active(self) -> bool:
        return self.enabled and self.photons is not None

    def _ensure_targets(self, size: tuple[int, int]) -> None:
        if self.outputs and self.outputs[0].size == size:
            return
        self._release_targets()
        for _ in range(2):
            tex = self.ctx.texture(size, 4, dtype="f4")
            tex.filter = (moderngl.NEAREST, moderngl.NEAREST)
            self.outputs.append(tex)
        self.winner = self.ctx.texture(size, 1, dtype="u4")
        self.winner.filter = (moderngl.NEAREST, moderngl.NEAREST)
        self._clear_winner = np.full(size[0] * size[1], NO_WINNER, np.uint32).tobytes()
        self._clear_output = np.zeros(size[0] * size[1] * 4, np.float32).tobytes()

    # -- the frame -----------------------------------------------------------------------------
    def configure(self, settings, scene, frame) -> bool:
        self.settings = settings.photons
        # Gather only at the block samples when CPS lights the blocks.
        cached = settings.photons.indirect == "cache"
        self.block_rate = deferred(settings) and settings.cps.mode == "cps" and not cached
        self.reads = ("depth", "normal", "levels") if self.block_rate else ("depth", "normal")
        return deferred(settings) and self.photons is not None

    def execute(self, frame: FrameContext, res: Resources) -> None:
        if self.photons is None:
            return
        if self.settings.indirect == "cache":
            self._lookup(frame, res)
            return
        gmap = self._ensure_map(self.photons)
        if gmap is None:
            return
        s = self.settings
        if s.fused:  # the lighting shader gathers itself (Algorithm 1 needs a compute group)
            variant = "radius" if s.gather == "shared" else s.gather
            res.put("photon_map", (gmap, self.gather.defines(gmap, variant, s.k)))
            self.eye_ms = [0.0, 0.0]
            return
        size = res.targets[0].size
        self._ensure_targets(size)
        levels = res.get("levels") if self.block_rate else None
        reuse = s.stereo_reuse
        for index, (eye, tgt) in enumerate(zip(frame.eyes, res.targets)):
            start = self._mark()
            out = self.outputs[index]
            if self.block_rate:  # only block samples are written: no stale values elsewhere
                out.write(self._clear_output)
            reuse_input = None
            if index == 1 and reuse:
                reuse_input = self._scatter(frame, res, levels)
            self.gather.gather_image(
                gmap,
                s.gather,
                depth=tgt.depth,
                normal=tgt.normal,
                inv_view_projection=eye.inverse_view_projection,
                size=size,
                out=out,
                k=s.k,
                block_rate=self.block_rate,
                levels=levels[index] if levels else None,
                reuse=reuse_input,
            )
            self.ctx.memory_barrier(
                moderngl.TEXTURE_FETCH_BARRIER_BIT | moderngl.SHADER_IMAGE_ACCESS_BARRIER_BIT
            )
            self.eye_ms[index] = self._mark() - start if self.measure else 0.0
        res.put("indirect", list(self.outputs))
        res.put("show_reuse", s.show_reuse and reuse)

    def _lookup(self, frame: FrameContext, res: Resources) -> None:
        """Each eye's irradiance looked up in the cache (no gather, no stereo reuse)."""
        assert self.photons is not None
        cache = self._ensure_cache(self.photons)
        if cache is None:
            return
        size = res.targets[0].size
        self._ensure_targets(size)
        for index, (eye, tgt) in enumerate(zip(frame.eyes, res.targets)):
            start = self._mark()
            cache.lookup_image(
                self.shaders,
                depth=tgt.depth,
                normal=tgt.normal,
                inv_view_projection=eye.inverse_view_projection,
                size=size,
                out=self.outputs[index],
            )
            self.eye_ms[index] = self._mark() - start if self.measure else 0.0
        self.ctx.memory_barrier(
            moderngl.TEXTURE_FETCH_BARRIER_BIT | moderngl.SHADER_IMAGE_ACCESS_BARRIER_BIT
        )
        res.put("indirect", list(self.outputs))
        res.put("show_reuse", False)

    def _mark(self) -> float:
        if not self.measure:
            return 0.0
        self.ctx.finish()
        return time.perf_counter() * 1e3

    def _scatter(self, frame: FrameContext, res: Resources, levels: list[moderngl.Texture] | None):
        """Left hit points claim the right-eye pixels that see them (photon_reuse.comp.glsl)."""
        assert self.winner is not None
        left, right = frame.eyes
        tl, tr = res.targets
        self.winner.write(self._clear_winner)
        prog = self.shaders.compute("photon_reuse.comp.glsl", {"BLOCK_RATE": levels is not None})
        bind_texture(prog, "left_depth", tl.depth)
        bind_texture(prog, "right_depth", tr.depth)
        if levels is not None:
            bind_texture(prog, "levels", levels[0])
        set_uniforms(
            prog,
            {
                "u_left_inv_view_projection": left.inverse_view_projection,
                "u_right_view_projection": right.view_projection,
                "u_right_inv_view_projection": right.inverse_view_projection,
                "u_size": tl.size,
                "u_tolerance": self.settings.reuse_tolerance,
            },
        )
        bind_image(self.winner, "winner", read=True, write=True)
        w, h = tl.size
        prog.run(-(-w // 8), -(-h // 8))
        self.ctx.memory_barrier(
            moderngl.SHADER_IMAGE_ACCESS_BARRIER_BIT | moderngl.TEXTURE_FETCH_BARRIER_BIT
        )
        return (self.winner, self.outputs[0])

    # -- statistics ----------------------------------------------------------------------------
    def reuse_stats(self) -> dict:
        """Right-eye pixels reused from the left eye and gathered, from the last frame (read
        back on request)."""
        if (
            len(self.outputs) < 2
            or self.photons is None
            or self.gmap is None
            or self.settings.fused
            or self.settings.indirect == "cache"
        ):
            return {}
        tex = self.outputs[1]
        alpha = np.frombuffer(tex.read(), np.float32).reshape(-1, 4)[:, 3]
        reused = int(np.count_nonzero(alpha == 2.0))
        gathered = int(np.count_nonzero(alpha == 1.0))
        return {
            "reused": reused,
            "gathered": gathered,
            "reuse_share": reused / max(1, reused + gathered),
        }

    def read_indirect(self, eye: int) -> np.ndarray:
        """One eye's irradiance target as (H, W, 4) float32, row 0 at the top."""
        tex = self.outputs[eye]
        data = np.frombuffer(tex.read(), np.float32).reshape(tex.size[1], tex.size[0], 4)
        return np.flipud(data).copy()

    def _release_targets(self) -> None:
        for tex in self.outputs:
            tex.release()
        self.outputs = []
        if self.winner is not None:
            self.winner.release()
            self.winner = None

    def release(self) -> None:
        super().release()
        self._drop_map()
        self._drop_cache()
        self._release_targets()
        self.gather.release()
