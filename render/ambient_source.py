"""The frame's even light (``render.ambient``, ``render.ambient_estimate``,
``render.ambient_by_place``): the estimate from the frame's lights and the sky
(``app.ambient``), made once per scene, set of lights, sky and photon map, and its field by
place uploaded once per estimate. The renderer asks it for each frame
(``Renderer.ambient_terms``, ``Renderer.frame_context``).
"""

from __future__ import annotations

from collections.abc import Sequence

import moderngl
import numpy as np

from app.ambient import AmbientEstimate, AmbientProbe, probe_for
from app.raycast import RayCaster
from app.scene import Light
from app.settings import Settings
from render.ambient_field import GpuAmbientField
from render.gpu_scene import GpuScene


class AmbientSource:
    """The estimate and its field for the scene drawn, kept until what they depend on changes."""

    def __init__(self, ctx: moderngl.Context) -> None:
        self.ctx = ctx
        self._estimate: tuple[GpuScene, tuple, AmbientEstimate] | None = None
        self._probe: tuple[GpuScene, AmbientProbe] | None = None
        self._field: GpuAmbientField | None = None  # the estimate's field, uploaded

    def estimate(
        self,
        scene: GpuScene,
        lights: Sequence[Light],
        sky: tuple | None,
        sky_sh,
        beside_photons: bool,
    ) -> AmbientEstimate:
        """The estimate for ``lights`` and the sky (``sky``: its key, ``sky_sh()`` its light,
        asked only when the estimate is made again); ``beside_photons``: only what a photon
        map leaves out (``AmbientProbe.estimate``)."""
        key = (list(lights), sky, beside_photons)
        cached = self._estimate
        if cached is None or cached[0] is not scene or cached[1] != key:
            if self._probe is None or self._probe[0] is not scene:
                own = scene.scene.ray_caster
                caster = own if isinstance(own, RayCaster) else None
                self._probe = (scene, probe_for(scene.scene, caster))
            sh: np.ndarray | None = sky_sh() if sky is not None else None
            value = self._probe[1].estimate(lights, sh, beside_photons=beside_photons)
            self._estimate = cached = (scene, key, value)
        return cached[2]

    def field_for(self, est: AmbientEstimate | None, settings: Settings) -> GpuAmbientField | None:
        """The estimate's even light by place on the GPU (``render.ambient_by_place``),
        uploaded once per estimate."""
        field = est.by_place if est is not None and settings.render.ambient_by_place else None
        if field is None:
            return None
        if self._field is None or self._field.field is not field:
            if self._field is not None:
                self._field.release()
            self._field = GpuAmbientField(self.ctx, field)
        return self._field

    def release(self) -> None:
        if self._field is not None:
            self._field.release()
            self._field = None
