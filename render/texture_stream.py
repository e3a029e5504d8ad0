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

from app.scene import Texture
from app.tcr import build_pyramid, level_bytes

log = logging.getLogger(__name__)
GL_SRGB8_ALPHA8 = 0x8C43


@dataclass
class Resident:
    tex: moderngl.Texture
    base: int  # pyramid level held at the GL texture's level 0
    unused_frames: int = 0  # frames since the finest resident level was last needed


class TextureStreamer:
    def __init__(
        self,
        ctx: moderngl.Context,
        textures: list[Texture],
        budget_bytes: int = 8 << 20,
        keep_frames: int = 30,
        anisotropy: float = 1.0,
    ) -> None:
        self.ctx = ctx
        self.budget_bytes = budget_bytes
        self.keep_frames = keep_frames
        self.anisotropy = anisotropy
        self.sources = textures
        self.pyramids = [
            [np.ascontiguousarray(np.flipud(level)) for level in build_pyramid(t.rgba)]
            for t in textures
        ]  # GL rows: bottom first
        self.level_sizes = [[(p.shape[1], p.shape[0]) for p in pyr] for pyr in self.pyramids]
        self.level_bytes = [level_bytes(*t.size) for t in textures]
        self.resident: list[Resident] = [self._make(i, 0) for i in range(len(textures))]
        self.uploaded_bytes = 0  # in the last update, for statistics

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
