"""The one renderer, driven by the Qt widget and by the headless EGL host alike.

A frame is the list of passes below; which run is decided by the settings tree
(``render.path``, ``render.lighting``, ``render.overlay``). The host supplies the output
framebuffer (the widget's default FBO, or an offscreen texture) and the frame's inputs.
"""

from __future__ import annotations

import logging

import moderngl
import numpy as np

from app.frame import FrameInput
from app.photon_map import PhotonMap
from app.scene import Scene
from app.settings import Settings
from app.tcr import finest_per_texture
from render.cps import (
    CpsFilterPass,
    CpsFrame,
    CpsLevelPass,
    CpsLightingPass,
    CpsMaskPass,
    CpsState,
    CpsTemporalPass,
)
from render.gpu_scene import GpuScene
from render.passes import (
    EmissivePass,
    EyeTargets,
    ForwardPass,
    FrameContext,
    GBufferPass,
    LightCullPass,
    LightingPass,
    ObjectIdPass,
    OverlayPass,
    PresentPass,
    RenderPass,
)
from render.photons import PhotonPass
from render.shaders import ShaderLibrary

log = logging.getLogger(__name__)
CULL_MIN_LIGHTS = 8  # light culling runs for scenes with more lights than this


class Renderer:
    def __init__(self, ctx: moderngl.Context, settings: Settings) -> None:
        self.ctx = ctx
        self.settings = settings
        self.shaders = ShaderLibrary(ctx)
        self.gbuffer = GBufferPass(ctx, self.shaders)
        self.lighting = LightingPass(ctx, self.shaders)
        self.emissive = EmissivePass(ctx, self.shaders)
        self.forward = ForwardPass(ctx, self.shaders)
        self.present = PresentPass(ctx, self.shaders)
        self.overlay = OverlayPass(ctx, self.shaders)
        self.ids = ObjectIdPass(ctx, self.shaders)  # on request, not part of the frame
        self.cps = CpsState(ctx)
        self.cps_levels = CpsLevelPass(ctx, self.shaders, self.cps)
        self.cps_lighting = CpsLightingPass(ctx, self.shaders, self.cps)
        self.cps_filter = CpsFilterPass(ctx, self.shaders, self.cps)
        self.cps_temporal = CpsTemporalPass(ctx, self.shaders, self.cps)
        self.cps_mask = CpsMaskPass(ctx, self.shaders, self.cps)
        self.light_cull = LightCullPass(ctx, self.shaders)
        self.photons = PhotonPass(ctx, self.shaders)
        self.passes: list[RenderPass] = [
            self.gbuffer,
            self.light_cull,
            self.cps_levels,
            self.photons,
            self.lighting,
            self.cps_lighting,
            self.cps_filter,
            self.cps_temporal,
            self.cps_mask,
            self.emissive,
            self.forward,
            self.present,
            self.overlay,
        ]
        self.gpu_scene: GpuScene | None = None
        self.targets: list[EyeTargets] = []
        self.frames = 0
        self._errors_logged: set[str] = set()
        self._empty = GpuScene(ctx, Scene("empty", [], []))

    # -- scene and targets ---------------------------------------------------------------------
    def set_scene(self, scene: Scene | None) -> None:
        if self.gpu_scene is not None:
            self.gpu_scene.release()
            self.gpu_scene = None
        if scene is not None:
            self.gpu_scene = GpuScene(self.ctx, scene, self.settings.render.anisotropy)
            self._warm_up()

    def set_photons(self, photons: PhotonMap | None) -> None:
        """The photon map for the current scene (traced by the host), or None: no indirect."""
        self.photons.set_photons(photons)

    def _warm_up(self) -> None:
        """Compile every shader variant now, so the first frames do not stall."""
        tcr = self.settings.tcr
        modes = [{}]
        if tcr.enabled:
            mode = "TCR_PAPER" if tcr.mode == "paper" else "TCR_CLAMP"
            modes = [{mode: True, "TCR_TINT": tcr.tint}]
        for fragment in ("gbuffer.frag.glsl", "forward.frag.glsl"):
            for textured in (False, True):
                for extra in modes:
                    self.shaders.program(
                        "geometry.vert.glsl", fragment, {"HAS_TEXTURE": textured, **extra}
                    )
        self.shaders.program("geometry.vert.glsl", "emissive.frag.glsl")
        self.shaders.compute("lighting.comp.glsl")
        for fragment in ("lighting.frag.glsl", "present.frag.glsl", "overlay.frag.glsl"):
            self.shaders.program("fullscreen.vert.glsl", fragment)

    def _ensure_targets(self, width: int, height: int) -> None:
        if self.targets and self.targets[0].size == (width, height):
            return
        for t in self.targets:
            t.release()
        self.targets = [EyeTargets(self.ctx, width, height) for _ in range(2)]

    # -- the frame -----------------------------------------------------------------------------
    def render(
        self, frame: FrameInput, out: moderngl.Framebuffer, origin: tuple[int, int] = (0, 0)
    ) -> None:
        r = self.settings.render
        eye = frame.eyes[0]
        self._ensure_targets(eye.width, eye.height)
        deferred = r.path == "deferred"
        self.gbuffer.enabled = self.lighting.enabled = self.emissive.enabled = deferred
        self.forward.enabled = not deferred
        self.lighting.stage = r.lighting
        cps = self._configure_cps(frame, deferred)
        scene_lights = len((self.gpu_scene or self._empty).lights)
        # With a handful of lights the culling pass costs more than it saves.
        self.light_cull.enabled = deferred and r.light_culling and scene_lights > CULL_MIN_LIGHTS
        self.photons.settings = self.settings.photons
        self.photons.enabled = deferred and self.photons.photons is not None
        self.photons.block_rate = self.cps_lighting.enabled
        self.photons.level_maps = [e.levels for e in self.cps.eyes]
        self.overlay.enabled = True
        self.overlay.show_text = r.overlay
        ctx = FrameContext(
            eyes=frame.eyes,
            targets=self.targets,
            scene=self.gpu_scene or self._empty,
            light_scale=r.brightness,
            ambient=r.ambient * r.brightness,
            exposure=r.exposure,
            out=out,
            out_origin=origin,
            gaze=frame.gaze,
            gaze_fixed=frame.gaze_fixed,
            levels=frame.levels if self.settings.tcr.enabled else None,
            tcr_mode=self.settings.tcr.mode,
            tint=self.settings.tcr.tint,
            culled=self.light_cull.enabled,
        )
        if cps.visualize and self.cps_levels.enabled:
            ctx.level_maps = [e.levels for e in self.cps.eyes]
            ctx.markers = _project_hits(frame)
        scene = ctx.scene
        if ctx.levels is not None and len(ctx.levels) == len(scene.meshes):
            scene.streamer.update(
                finest_per_texture(
                    ctx.levels, [m.texture for m in scene.meshes], len(scene.streamer.resident)
                )
            )
        else:
            ctx.levels = None
            scene.streamer.update([0] * len(scene.streamer.resident))
        for p in self.passes:
            try:
                p.run(ctx)
            except Exception as exc:  # noqa: BLE001 - one bad pass must not kill the app
                self._log_once(p.name, exc)
        self.frames += 1

    def _configure_cps(self, frame: FrameInput, deferred: bool):
        """Which CPS passes run this frame (CPS and the masks need the deferred path)."""
        s = self.settings.cps
        mode = s.mode if deferred else "none"
        self.cps.ensure(self.targets)
        caps = frame.cps_caps if frame.cps_caps and len(frame.cps_caps) == 2 else [(0, 0, 0)] * 2
        self.cps.frame = CpsFrame(s, caps, self.frames, list(frame.edge_hits or []))
        self.cps.mode = mode
        coarse = mode == "cps"
        self.cps_levels.enabled = deferred and (coarse or s.visualize)
        self.cps.level_maps_valid = self.cps.level_maps_valid and self.cps_levels.enabled
        self.lighting.enabled = deferred and not coarse
        self.cps_lighting.enabled = self.cps_filter.enabled = coarse
        self.cps_lighting.stage = self.settings.render.lighting
        self.cps_lighting.dispatch = s.dispatch
        self.cps_filter.from_atlas = self.settings.render.lighting == "fragment"
        self.cps_temporal.enabled = coarse and s.temporal
        if not self.cps_temporal.enabled:
            self.cps_temporal.reset()
        self.cps_mask.enabled = mode in ("black-mask", "blur-mask")
        return s

    def cps_stats(self) -> dict:
        """Share of pixels per detail level and lighting evaluations, from the last frame's
        level maps (read back on request: the panel asks 4 times a second, the benchmark
        after each timed frame)."""
        maps = self.cps.read_levels() if self.cps_levels.enabled else []
        if not maps:
            return {}
        levels = np.concatenate([m.ravel() for m in maps])
        counts = np.bincount(levels, minlength=6)[:6]
        blocks = float(np.sum(counts / 4.0 ** np.arange(6)))
        return {
            "level_share": (counts / max(1, levels.size)).tolist(),
            "shaded_samples": int(round(blocks)) if self.cps_lighting.enabled else int(levels.size),
            "full_samples": int(levels.size),
        }

    def photon_stats(self) -> dict:
        """Photons on the GPU, the grid, gather time and the right eye's reuse share of the
        last frame (reads the right eye's target back: on request only)."""
        p = self.photons
        if p.photons is None:
            return {}
        out: dict = {"photons": len(p.photons), "gather_ms": p.last_ms, "error": p.error}
        if p.measure:
            out["eye_ms"] = list(p.eye_ms)
        g = p.gmap
        if g is not None and g.grid is not None:
            x, y, z = g.grid.dims
            out["grid"] = (
                f"{x}x{y}x{z} cells of {100 * g.grid.cell:.3g} cm, built in {g.build_ms:.0f} ms"
            )
        elif g is not None:
            out["grid"] = f"kd-tree of {g.photon_count:,} photons, built in {g.build_ms:.0f} ms"
        if p.enabled:
            out.update(p.reuse_stats())
        return out

    def object_ids(self, frame: FrameInput) -> list[np.ndarray]:
        """Mesh index under each pixel of each eye ((H, W) int32, row 0 at the top; -1: none)."""
        eye = frame.eyes[0]
        self._ensure_targets(eye.width, eye.height)
        ctx = FrameContext(
            eyes=frame.eyes,
            targets=self.targets,
            scene=self.gpu_scene or self._empty,
            light_scale=0.0,
            ambient=0.0,
            exposure=1.0,
            out=self.ctx.screen,
            out_origin=(0, 0),
            gaze=frame.gaze,
            gaze_fixed=frame.gaze_fixed,
        )
        self.ids.run(ctx)
        return self.ids.result

    def _log_once(self, name: str, exc: Exception) -> None:
        key = f"{name}: {type(exc).__name__}: {exc}"
        if key not in self._errors_logged:
            self._errors_logged.add(key)
            log.error("render pass %s failed: %s", name, exc, exc_info=exc)

    @property
    def errors(self) -> list[str]:
        return sorted(self._errors_logged)

    # -- statistics ----------------------------------------------------------------------------
    def pass_ms(self) -> dict[str, float]:
        return {p.name: p.last_ms for p in self.passes if p.enabled}

    def shaded_samples(self) -> int:
        """Lighting evaluations last frame: deferred pixels lit, CPS blocks lit, or forward
        fragments shaded."""
        if self.cps_lighting.enabled:
            return int(self.cps_stats().get("shaded_samples", 0))
        stage = self.lighting if self.lighting.enabled else self.forward
        return int(stage.samples)

    def light_evaluations(self) -> dict[str, int]:
        """Full-rate light evaluations last frame with the tile lists and without (deferred
        path; {} when culling is off or the path is forward)."""
        if not self.light_cull.enabled or not self.targets:
            return {}
        return LightCullPass.evaluations(self.targets, len(self.gpu_scene.lights))

    def texture_resident_bytes(self) -> int:
        return self.gpu_scene.texture_bytes if self.gpu_scene is not None else 0

    def read_hdr(self, eye: int) -> np.ndarray:
        """One eye's linear HDR colour as (H, W, 4) float32, row 0 at the top."""
        tex = self.targets[eye].color
        data = np.frombuffer(tex.read(), np.float16).reshape(tex.size[1], tex.size[0], 4)
        return np.flipud(data.astype(np.float32))

    def release(self) -> None:
        for p in (*self.passes, self.ids):
            p.release()
        self.cps.release()
        for t in self.targets:
            t.release()
        if self.gpu_scene is not None:
            self.gpu_scene.release()
        self._empty.release()
        self.shaders.release()


def _project_hits(frame: FrameInput) -> list[list[tuple[int, int]]]:
    """Edge-ray hit points as pixels of each eye (from the bottom-left); behind the eye: none."""
    out: list[list[tuple[int, int]]] = []
    for index, eye in enumerate(frame.eyes):
        points: list[tuple[int, int]] = []
        hits = frame.edge_hits[index] if frame.edge_hits and index < len(frame.edge_hits) else None
        if hits is not None and len(hits):
            h = np.asarray(hits, np.float64).reshape(-1, 3)
            clip = np.c_[h, np.ones(len(h))] @ eye.view_projection.T
            ok = clip[:, 3] > 1e-9
            ndc = clip[ok, :2] / clip[ok, 3:4]
            for x, y in ndc:
                points.append((int((x * 0.5 + 0.5) * eye.width), int((y * 0.5 + 0.5) * eye.height)))
        out.append(points)
    return out
