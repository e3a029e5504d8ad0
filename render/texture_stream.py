"""Texture pyramids on the GPU, with only the levels in use resident (TCR, SPEC B).

Each scene texture is one GL texture whose level 0 is pyramid level ``base``: levels finer than
the finest one any object needs are not on the GPU. When a finer level is needed it comes back
within a per-frame upload budget (until then the finest resident level stands in, so a level
change never stalls a frame); when finer levels have gone unused for ``keep_frames`` frames the
texture is re-made from the coarser levels alone, which is a small upload.

Without TCR every texture simply keeps its whole pyramid resident (base 0).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import moderngl
import numpy as np

from app.progress import Progress
from app.scene import Texture
from app.tcr import build_pyramid, level_bytes

log = logging.getLogger(__name__)
GL_SRGB8_ALPHA8 = 0x8C43
# The window streams textures in (coarse first, finer levels within the frame budget) once a
# scene's textures exceed this, starting each at a level no larger than STREAM_IN_START_PX.
STREAM_IN_ABOVE_BYTES = 256 << 20
STREAM_IN_START_PX = 128


@dataclass
class Resident:
    tex: moderngl.Texture
    base: int  # pyramid level held at the GL texture's level 0
    unused_frames: int = 0  # frames since the finest resident level was last needed


def gl_pyramid(texture: Texture) -> list[np.ndarray]:
    """The texture's pyramid in GL row order (bottom row first), built once per texture.

    Building a pyramid is CPU work (seconds for a gigabyte of textures): the window's load
    worker calls :func:`prepare_textures`, so the UI thread only uploads.
    """
    cached = getattr(texture, "_gl_pyramid", None)
    if cached is None or cached[0] is not texture.rgba:
        levels = [np.ascontiguousarray(np.flipud(level)) for level in build_pyramid(texture.rgba)]
        cached = (texture.rgba, levels)
        setattr(texture, "_gl_pyramid", cached)  # noqa: B010 - a cache, not a model field
    return cached[1]


def prepare_textures(textures: list[Texture], progress: Progress | None = None) -> None:
    """Build every texture's pyramid now (on a worker thread), reporting as it goes."""
    for i, texture in enumerate(textures):
        if progress is not None:
            progress.report(i / max(len(textures), 1), f"Preparing textures ({i}/{len(textures)})")
        gl_pyramid(texture)


class TextureStreamer:
    def __init__(
        self,
        ctx: moderngl.Context,
        textures: list[Texture],
        budget_bytes: int = 8 << 20,
        keep_frames: int = 30,
        anisotropy: float = 1.0,
        stream_in: bool = False,
    ) -> None:
        """``stream_in``: when the textures' full chains exceed :data:`STREAM_IN_ABOVE_BYTES`,
        start every texture at a small level and let :meth:`update` bring the finer ones within
        the per-frame budget (the window: a gigabyte of textures never freezes it); headless
        hosts upload everything at once so their first frame is at full quality."""
        self.ctx = ctx
        self.budget_bytes = budget_bytes
        self.keep_frames = keep_frames
        self.anisotropy = anisotropy
        self.sources = textures
        self.pyramids = [gl_pyramid(t) for t in textures]  # GL rows: bottom first
        self.level_sizes = [[(p.shape[1], p.shape[0]) for p in pyr] for pyr in self.pyramids]
        self.level_bytes = [level_bytes(*t.size) for t in textures]
        total = sum(self.chain_bytes(i, 0) for i in range(len(textures)))
        start = [
            self._small_level(i) if stream_in and total > STREAM_IN_ABOVE_BYTES else 0
            for i in range(len(textures))
        ]
        self.resident: list[Resident] = [self._make(i, start[i]) for i in range(len(textures))]
        self.uploaded_bytes = 0  # in the last update, for statistics

    def _small_level(self, index: int) -> int:
        """The finest level no larger than :data:`STREAM_IN_START_PX` on its longest side."""
        for k, (w, h) in enumerate(self.level_sizes[index]):
            if max(w, h) <= STREAM_IN_START_PX:
                return k
        return self.n_levels(index)

    def n_levels(self, index: int) -> int:
        """Index of the coarsest (1x1) level of texture ``index``."""
        return len(self.pyramids[index]) - 1

    def _make(self, index: int, base: int) -> Resident:
        pyr = self.pyramids[index]
        src = self.sources[index]
        tex = self.ctx.texture(
            self.level_sizes[index][base], 4, pyr[base].tobytes(), internal_format=GL_SRGB8_ALPHA8
        )
        if base < len(pyr) - 1:
            tex.build_mipmaps(0, len(pyr) - 1 - base)  # allocates the chain ...
            for k in range(base + 1, len(pyr)):  # ... which we fill with our linear-light levels
                tex.write(pyr[k].tobytes(), level=k - base)
        tex.filter = (moderngl.LINEAR_MIPMAP_LINEAR, moderngl.LINEAR)
        tex.repeat_x = tex.repeat_y = src.repeat
        tex.anisotropy = self.anisotropy
        return Resident(tex, base)

    def chain_bytes(self, index: int, base: int) -> int:
        return sum(self.level_bytes[index][base:])

    def resident_bytes(self) -> int:
        return sum(self.chain_bytes(i, r.base) for i, r in enumerate(self.resident))

    def update(self, finest_needed: list[int]) -> None:
        """Bring residency towards what the objects need; -1 means no object uses the texture."""
        budget = self.budget_bytes
        self.uploaded_bytes = 0
        # Finest first: the most visible improvement gets the budget.
        order = sorted(
            range(len(self.resident)),
            key=lambda i: finest_needed[i] if finest_needed[i] >= 0 else 99,
        )
        for i in order:
            res = self.resident[i]
            need = finest_needed[i]
            if need < 0:
                need = self.n_levels(i)  # unused: may shrink to the 1x1 level after a while
            need = min(max(need, 0), self.n_levels(i))
            if need < res.base:
                cost = self.chain_bytes(i, need)
                if cost > budget and self.uploaded_bytes > 0:
                    continue  # next frame; the finest resident level stands in meanwhile
                self._replace(i, need)
                budget -= cost
                self.uploaded_bytes += cost
            elif need > res.base:
                res.unused_frames += 1
                if res.unused_frames >= self.keep_frames:
                    cost = self.chain_bytes(i, need)
                    self._replace(i, need)
                    self.uploaded_bytes += cost
            else:
                res.unused_frames = 0

    def _replace(self, index: int, base: int) -> None:
        old = self.resident[index]
        self.resident[index] = self._make(index, base)
        old.tex.release()

    def release(self) -> None:
        for r in self.resident:
            r.tex.release()
        self.resident.clear()
