"""The one renderer, driven by the Qt widget and by the headless EGL host alike.

A frame is the pass list ``PASS_TYPES`` (one line per pass, in order). Each pass says whether
it runs from the settings (``configure``) and which named resources it reads and writes
(``render.pass_graph``); the renderer checks the enabled list once per configuration and runs
it. The host supplies the output framebuffer (the widget's default FBO, or an offscreen
texture) and the frame's inputs.
"""

from __future__ import annotations

import dataclasses
import logging
import time
from typing import Generic, TypeVar, cast

import moderngl
import numpy as np

from app.ambient import AmbientEstimate
from app.camera import jittered
from app.frame import FrameInput
from app.governor import (
    LOD_ERRORS,
    Governor,
    apply_overrides,
    program_key,
    still_overrides,
)
from app.paths import FIXED_DT
from app.photon_map import PhotonMap
from app.refine import refine_on
from app.scene import Light, Scene, lights_with_daylight
from app.settings import Settings
from app.sky import scene_sky, sky_key, sun_light
from app.tcr import finest_per_texture
from render.ab_split import ABSplitPass, SplitFrame
from render.ambient_source import AmbientSource
from render.ao import AmbientOcclusionPass
from render.constants import CPS_LEVELS
from render.cps import (
    CpsFilterPass,
    CpsFrame,
    CpsLevelPass,
    CpsLightingPass,
    CpsMaskPass,
    CpsState,
    CpsTemporalPass,
)
from render.exposure import Exposure, ExposurePass
from render.gpu_scene import GpuScene
from render.pass_graph import (
    BySize,
    FrameContext,
    RenderPass,
    Resources,
    check_graph,
    release_all,
)
from render.passes import (
    CULL_MIN_LIGHTS,  # noqa: F401 - re-exported
    BlendPass,
    EmissivePass,
    EyeTargets,
    ForwardPass,
    GBufferPass,
    LightCullPass,
    LightingPass,
    ObjectIdPass,
    deferred,
)
from render.photons import PhotonPass
from render.present import OverlayPass, PresentPass
from render.refine import RefinePass
from render.reflections import ReflectionPass
from render.shaders import ShaderLibrary
from render.shadow_mask import ShadowMaskPass
from render.shadows import ShadowPass
from render.sky import DaylightPass, SkyPass, frame_unlit_gain
from render.upscale import render_size

log = logging.getLogger(__name__)

# The frame, in order. Adding a pass: its class (reads, writes, configure, execute) and a line.
PASS_TYPES: tuple[type[RenderPass], ...] = (
    DaylightPass,
    ShadowPass,
    GBufferPass,
    LightCullPass,
    CpsLevelPass,
    PhotonPass,
    AmbientOcclusionPass,
    ShadowMaskPass,
    LightingPass,
    CpsLightingPass,
    CpsFilterPass,
    CpsTemporalPass,
    CpsMaskPass,
    EmissivePass,
    ForwardPass,
    SkyPass,
    ReflectionPass,
    BlendPass,
    RefinePass,
    ExposurePass,
    PresentPass,
    ABSplitPass,
    OverlayPass,
)


P = TypeVar("P", bound=RenderPass)


class _Pass(Generic[P]):
    """``renderer.<pass name>``: the pass of that name (for the hosts, panels and tests)."""

    def __set_name__(self, owner: type, name: str) -> None:
        self.name = name

    def __get__(self, renderer: Renderer, owner: type | None = None) -> P:
        return cast(P, renderer.pass_named(self.name))


def refined_settings(s: Settings) -> Settings:
    """A refining frame's settings (:meth:`Renderer.frame_settings`): full-rate shading and
    the finest textures."""
    return dataclasses.replace(
        s,
        cps=dataclasses.replace(s.cps, mode="none"),
        tcr=dataclasses.replace(s.tcr, enabled=False, tint=False),
    )


def _frame_key(settings: Settings, refining: bool) -> tuple:
    """The programs a frame of these (the frame's own) settings draws: program_key and
    whether it refines (the running mean's programs, full-rate shading, no texture levels)."""
    if refining and str(settings.render.refine) != "off":
        return (*program_key(refined_settings(settings)), True)
    return (*program_key(settings), False)


#: The warm frames' eyes (Renderer.warm_variants): this fraction of a side of the view's,
#: at least WARM_MIN_PX.
WARM_SHARE = 8
WARM_MIN_PX = 16


class Renderer:
    daylight = _Pass[DaylightPass]()
    shadows = _Pass[ShadowPass]()
    gbuffer = _Pass[GBufferPass]()
    light_cull = _Pass[LightCullPass]()
    cps_levels = _Pass[CpsLevelPass]()
    photons = _Pass[PhotonPass]()
    ao = _Pass[AmbientOcclusionPass]()
    shadow_mask = _Pass[ShadowMaskPass]()
    lighting = _Pass[LightingPass]()
    cps_lighting = _Pass[CpsLightingPass]()
    cps_filter = _Pass[CpsFilterPass]()
    cps_temporal = _Pass[CpsTemporalPass]()
    cps_mask = _Pass[CpsMaskPass]()
    emissive = _Pass[EmissivePass]()
    forward = _Pass[ForwardPass]()
    refine = _Pass[RefinePass]()
    exposure_meter = _Pass[ExposurePass]()
    sky = _Pass[SkyPass]()
    reflections = _Pass[ReflectionPass]()
    present = _Pass[PresentPass]()
    ab_split = _Pass[ABSplitPass]()
    overlay = _Pass[OverlayPass]()

    def __init__(
        self,
        ctx: moderngl.Context,
        settings: Settings,
        pass_types: tuple[type[RenderPass], ...] = PASS_TYPES,
    ) -> None:
        self.ctx = ctx
        self.settings = settings
        self.shaders = ShaderLibrary(ctx)
        self.cps = CpsState(ctx)
        self.resources = Resources(self.cps)
        self.passes: list[RenderPass] = [t(ctx, self.shaders, self.resources) for t in pass_types]
        self._by_name = {p.name: p for p in self.passes}
        self.ids = ObjectIdPass(ctx, self.shaders, self.resources)  # on request only
        self._checked: set[tuple] = set()  # configurations whose pass list was checked
        self.gpu_scene: GpuScene | None = None
        # Static meshes merged per material (render.gpu_scene.GpuGroup); False: one draw per
        # mesh, as before (tests compare the two, debugging). Read by set_scene.
        self.merge_meshes = True
        # The CPS filter folded into the present pass where nothing between them needs the
        # pixels (PresentPass.fold_filter); False: always its own pass (tests compare them).
        self.fold_cps_filter = True
        self._sun: Light | None = None
        self._sun_key: tuple | None = None
        self._synced: tuple[GpuScene, list[Light]] | None = None  # the lights last uploaded
        # The estimated ambient term for a scene and its lights, and the scene's probe.
        self._ambient = AmbientSource(ctx)  # the estimate and its field, kept
        self.targets: list[EyeTargets] = []
        self._eye_targets = BySize(
            lambda size: [EyeTargets(ctx, *size) for _ in range(2)], release_all
        )
        self.frames = 0
        self._errors_logged: set[str] = set()
        self._empty = GpuScene(ctx, Scene("empty", [], []))
        # Exposure: fixed or metered (render.exposure); stepped once a frame by frame_dt
        # seconds (the headless hosts' fixed step; the window may set its own).
        self.exposure = Exposure()
        self.frame_dt = FIXED_DT
        self._exposure_scale = self.exposure.step(settings.render, None, 0.0, False)
        # The frame-time governor (render.target_fps): its overrides apply to a copy of the
        # user's settings for each frame; ``display_hz`` is the window's refresh (None in the
        # headless hosts, where "auto" means fixed settings).
        self.governor = Governor()
        self.display_hz: float | None = None
        # The last frame dropped the refinement's mean (finer textures arrived while refining):
        # the host restarts its session's samples (``Refinement.restart``).
        self.refine_restarted = False
        self._refine_dropped = False
        # The programs drawn for this scene (program_key of the frames' settings) and the scene
        # of the last real frame: what :meth:`warm_variants` has still to draw.
        self._warmed: set[tuple] = set()
        self._drawn: GpuScene | None = None
        self._warm_done: tuple | None = None  # (scene, the user's program_key) warmed

    def pass_named(self, name: str) -> RenderPass:
        return self._by_name[name]

    def meter_afresh(self) -> None:
        """Automatic exposure meters the next frame at once (a waiting metering of an earlier
        picture is dropped), as a camera meters before its first picture."""
        self.exposure.reset()
        if "exposure_meter" in self._by_name:
            self.exposure_meter.forget()

    # -- scene and targets ---------------------------------------------------------------------
    def set_scene(self, scene: Scene | None, stream_in: bool = False) -> None:
        """Upload ``scene`` (``stream_in``: huge texture sets arrive over the next frames, see
        :class:`render.texture_stream.TextureStreamer`)."""
        if self.gpu_scene is not None:
            self.gpu_scene.release()
            self.gpu_scene = None
        self.meter_afresh()  # another room
        self._forget_refinement()
        self.governor.new_scene()  # another room costs otherwise: learn it afresh
        self._warmed.clear()  # its materials are other programs
        self._warm_done = None
        if scene is not None:
            self.gpu_scene = GpuScene(
                self.ctx,
                scene,
                self.settings.render.anisotropy,
                stream_in=stream_in,
                merge=self.merge_meshes,
            )
            self._warm_up()

    def frame_lights(self) -> list[Light]:
        """The lights of a frame: the scene's lamps, then the sun (``kind="directional"``,
        ``direction`` the way its light travels) while daylight is on and it is up, in place
        of the model's own (``app.scene.lights_with_daylight``)."""
        if self.gpu_scene is None:
            return []
        lights = list(self.gpu_scene.scene.lights)
        sky = self.settings.sky
        if not sky.enabled:
            return lights
        sky = scene_sky(sky, self.gpu_scene.scene)
        key = (id(self.gpu_scene), sky_key(sky))
        if self._sun_key != key:  # astral only when the date, time, site or north change
            self._sun, self._sun_key = sun_light(sky), key
        own = lights_with_daylight(lights, True)
        return own + ([self._sun] if self._sun is not None else [])

    def _sync_lights(self) -> None:
        """The GPU's light list follows the frame's (the sun comes and goes with the daylight
        settings): one upload when it changes; the shadow maps see it by ``light_version``."""
        if self.gpu_scene is None:
            return
        lights = self.frame_lights()
        if self._synced is None or self._synced[0] is not self.gpu_scene:
            self._synced = (self.gpu_scene, list(self.gpu_scene.scene.lights))  # as uploaded
        if lights != self._synced[1]:  # lights set on the GpuScene directly stay until then
            self.gpu_scene.set_lights(lights)
            self._synced = (self.gpu_scene, lights)

    def set_photons(self, photons: PhotonMap | None) -> None:
        """The photon map for the current scene (traced by the host), or None: no indirect."""
        if photons is not self.photons.photons:  # hosts hand the same map every frame
            self._forget_refinement()
        self.photons.set_photons(photons)

    def _forget_refinement(self) -> None:
        refine = self._by_name.get("refine")
        if isinstance(refine, RefinePass):
            refine.forget()
        self._refine_dropped = True  # the next refining frame tells the host

    def frame_settings(self, frame: FrameInput) -> Settings:
        """The settings a frame is drawn with: the renderer's, or while the frame is refining
        (``frame.refining``: the session's choice; render.refine not "off") the same with
        full-rate shading (no CPS or masks) and the finest textures (TCR off), as
        ``app.quality.full_quality`` has them (the photon map stays the current one)."""
        s = self.settings
        if not (frame.refining and str(s.render.refine) != "off"):
            return s
        return refined_settings(s)

    def _warm_up(self) -> None:
        """Compile every shader variant now, so the first frames do not stall."""
        tcr = self.settings.tcr
        modes: list[dict[str, object]] = [{}]
        if tcr.enabled:
            mode = "TCR_PAPER" if tcr.mode == "paper" else "TCR_CLAMP"
            modes = [{mode: True, "TCR_TINT": tcr.tint}]
        merged = [True] if self.gpu_scene is not None and self.gpu_scene.groups else []
        for fragment in ("gbuffer.frag.glsl", "forward.frag.glsl"):
            for textured in (False, True):
                for extra in modes:
                    for table in (False, *merged):
                        self.shaders.program(
                            "geometry.vert.glsl",
                            fragment,
                            {"HAS_TEXTURE": textured, "OBJECT_TABLE": table, **extra},
                        )
        self.shaders.program("geometry.vert.glsl", "emissive.frag.glsl")
        self.shaders.compute("lighting.comp.glsl")
        for fragment in ("lighting.frag.glsl", "overlay.frag.glsl", "exposure_meter.frag.glsl"):
            self.shaders.program("fullscreen.vert.glsl", fragment)
        self.shaders.program(
            "fullscreen.vert.glsl", "present.frag.glsl", PresentPass.defines(self.settings)
        )

    def _ensure_targets(self, width: int, height: int) -> None:
        self.targets = self._eye_targets.get((width, height))

    # -- the frame -----------------------------------------------------------------------------
    def frame_context(
        self,
        frame: FrameInput,
        out: moderngl.Framebuffer,
        origin: tuple[int, int] = (0, 0),
        split: SplitFrame | None = None,
        settings: Settings | None = None,
    ) -> FrameContext:
        """The frame's inputs as every pass sees them (``settings``: the frame's, see
        :meth:`frame_settings`; default the renderer's)."""
        settings = settings or self.settings
        r = settings.render
        s = settings.cps
        caps: list[tuple[float, float, float]] = (
            frame.cps_caps if frame.cps_caps and len(frame.cps_caps) == 2 else [(0, 0, 0)] * 2
        )
        ambient, gradient = self.ambient_terms()
        est = self._ambient_estimate()
        scene = self.gpu_scene or self._empty
        scene.daylight = bool(settings.sky.enabled)  # the sky shows through its stand-ins
        scene.unlit_gain = frame_unlit_gain(self._by_name.get("daylight"), settings, scene)
        return FrameContext(
            eyes=frame.eyes,
            scene=scene,
            light_scale=1.0,  # lamps as the model gives them: Brightness is in the exposure
            ambient=ambient,
            ambient_gradient=gradient,
            occluder_return=-1.0 if est is None else est.occluder_return,
            ambient_field=self._ambient.field_for(est, settings),
            exposure=self._exposure_scale * r.exposure,
            out=out,
            out_origin=origin,
            gaze=frame.gaze,
            gaze_fixed=frame.gaze_fixed,
            levels=frame.levels if settings.tcr.enabled else None,
            tcr_mode=settings.tcr.mode,
            tint=settings.tcr.tint,
            cps=CpsFrame(s, caps, self.frames, list(frame.edge_hits or [])),
            edge_hits=frame.edge_hits,
            split=split,
            refining=bool(frame.refining and str(r.refine) != "off"),
            refine_sample=int(frame.sample),
            refine_target=int(frame.refine_target),
            normal_maps=bool(r.normal_maps),
        )

    def ambient_term(self) -> float:
        """The frame's ambient term: estimated from the frame's lights and the sky
        (``app.ambient``, once per scene, set of lights and sky) with
        ``render.ambient_estimate``, else ``render.ambient``; beside a photon map in use, the
        estimate of only what the map leaves out (lamp-lit), or ``render.ambient`` (daylight).
        With the estimate this is its mean; the shaders take it by the way a surface faces
        (:meth:`ambient_terms`)."""
        est = self._ambient_estimate()
        return float(self.settings.render.ambient) if est is None else est.ambient

    def ambient_terms(self) -> tuple[float, tuple[float, float, float]]:
        """``u_ambient`` and ``u_ambient_gradient``: the even light of a surface of normal n
        is ``max(u_ambient + gradient . n, 0)`` (``AmbientEstimate.base_and_gradient``)."""
        est = self._ambient_estimate()
        if est is None:
            return float(self.settings.render.ambient), (0.0, 0.0, 0.0)
        return est.base_and_gradient()

    def _ambient_estimate(self) -> AmbientEstimate | None:
        r = self.settings.render
        scene = self.gpu_scene
        if not r.ambient_estimate or scene is None:
            return None
        photons = self._by_name.get("photons")  # a renderer may run without the pass
        # Beside a photon map, only the light it leaves out (AmbientProbe.estimate); in
        # daylight that is next to nothing, and the fixed even light stays (as before).
        beside = (
            isinstance(photons, PhotonPass)
            and photons.photons is not None
            and deferred(self.settings)
        )
        if beside and self.settings.sky.enabled:
            return None
        sky = scene_sky(self.settings.sky, scene.scene) if self.settings.sky.enabled else None
        daylight = self._by_name.get("daylight")

        def sky_sh():
            return (
                daylight.update_sky(sky).sh
                if sky is not None and isinstance(daylight, DaylightPass)
                else None
            )

        key = sky_key(sky) if sky is not None else None
        return self._ambient.estimate(scene, self.frame_lights(), key, sky_sh, beside)

    def step_exposure(self) -> None:
        """This frame's exposure: the fixed EV, or the last metering adapted by frame_dt."""
        meter = self._by_name.get("exposure_meter")
        metering = isinstance(meter, ExposurePass) and meter.enabled
        grid = meter.take() if isinstance(meter, ExposurePass) else None
        self._exposure_scale = self.exposure.step(
            self.settings.render, grid, self.frame_dt, metering
        )

    def exposure_readout(self) -> str:
        """``"Exposure EV 7.2 (auto)"``: the EV the last frame was shown at."""
        return self.exposure.readout(self.settings.render)

    def displayed_brightness(self) -> float:
        """What TCR's light term reads (``app.exposure.displayed_brightness``)."""
        return self.exposure.displayed_brightness(self.settings.render)

    def exposure_state(self) -> tuple[float, float | None]:
        """The last frame's EV before the Brightness and the room's metered EV (None: not
        metered), for the session's TCR light term (``Session.exposure_state``)."""
        return self.exposure.base_ev, self.exposure.scene_ev

    def configure(self, ctx: FrameContext, settings: Settings | None = None) -> list[RenderPass]:
        """Ask every pass whether it runs (its own rule) and check the enabled list's reads
        (once per configuration); the enabled passes, in order."""
        settings = settings or self.settings
        for p in self.passes:
            p.enabled = bool(p.configure(settings, ctx.scene, ctx))
        enabled = [p for p in self.passes if p.enabled]
        key = tuple((p.name, p.reads, p.writes) for p in enabled)
        if key not in self._checked:
            check_graph(enabled)
            self._checked.add(key)
        if isinstance(self._by_name.get("present"), PresentPass):
            self.present.fold_filter(enabled, ctx.scene, self.fold_cps_filter)
        return enabled

    def render(
        self,
        frame: FrameInput,
        out: moderngl.Framebuffer,
        origin: tuple[int, int] = (0, 0),
        split: SplitFrame | None = None,
    ) -> None:
        """One stereo frame into ``out``; ``split``: the presenter's A/B split over it (see
        ``render.ab_frame``). The governor's knobs (``self.governor``) apply to a copy of the
        settings for this frame only; the eyes are drawn at ``render.scale`` and enlarged by
        the present pass."""
        user = self.settings
        if split is None and self.governor.budget_ms > 0:
            try:
                self.warm_variants(frame)
            except Exception as exc:  # noqa: BLE001 - a failed warm-up: the frame is drawn on
                self._log_once("warm-up", exc)
        start = time.perf_counter()
        self.settings = apply_overrides(user, self.governor.overrides)
        try:
            self._render(frame, out, origin, split, user)
        finally:
            self.settings = user
        wall_ms = (time.perf_counter() - start) * 1000.0
        pass_ms = self.pass_ms()
        try:
            self.governor.observe(
                user,
                pass_ms,
                max(wall_ms, sum(pass_ms.values())),
                self.display_hz,
                refining=bool(getattr(frame, "refining", False)),
                lod_triangles=self._lod_triangles(frame),
            )
        except Exception as exc:  # noqa: BLE001 - a broken step: the user's settings, drawn on
            self._log_once("governor", exc)
            self.governor = Governor()  # the next frame at the user's own settings

    def warm_variants(self, frame: FrameInput, limit: int | None = 1) -> int:
        """Draw up to ``limit`` (None: all) of the programs the governor's knobs could turn
        to that this scene has not drawn yet, each in one small frame no one sees
        (:meth:`app.governor.Governor.program_variants`); how many are left.

        A program's first frame compiles it: on llvmpipe with a cold shader cache, 0.3-1 s
        for hard shadows or coarse lighting, a stall in the walk the governor meant to keep
        smooth. Drawn from the scene's second frame on (the shadow maps and the mask exist
        then, so a warm frame takes a real frame's programs), one a frame in the window;
        with refinement on, a refining frame at full quality too (the first still frame).
        The warm frames leave the exposure, the shadow maps, the frame count and the
        governor as they were; a refinement in progress starts again."""
        user = self.settings
        scene = self.gpu_scene
        if scene is None or self._drawn is not scene or not frame.eyes:
            return 0
        done = (scene, program_key(user))
        if self._warm_done == done:  # every frame: nothing new unless the user's key changed
            return 0
        todo: dict[tuple, tuple[Settings, bool]] = {}
        variants = self.governor.program_variants(user)
        candidates = [(apply_overrides(user, o), False) for o in variants]
        if refine_on(user.render.refine, self.display_hz):  # standing still: full quality
            candidates.append((apply_overrides(user, still_overrides(user)), True))
        for settings, refining in candidates:
            key = _frame_key(settings, refining)
            if key not in self._warmed:
                todo.setdefault(key, (settings, refining))
        if not todo:
            self._warm_done = done
            return 0
        items = list(todo.items())[: len(todo) if limit is None else max(0, limit)]
        eye = frame.eyes[0]
        w, h = max(WARM_MIN_PX, eye.width // WARM_SHARE), max(WARM_MIN_PX, eye.height // WARM_SHARE)
        small = dataclasses.replace(
            frame,
            eyes=[dataclasses.replace(e, width=w, height=h) for e in frame.eyes],
            refining=False,
        )
        refine = self._by_name.get("refine")
        was_refining = isinstance(refine, RefinePass) and refine.valid
        warm_refine = any(r for _, (_, r) in items)
        kept = (self.frames, self._exposure_scale, self.refine_restarted, self._refine_dropped)
        color = self.ctx.texture((2 * w, h), 4)
        out = self.ctx.framebuffer([color])
        try:
            for key, (settings, refining) in items:
                self.settings = settings
                drawn = dataclasses.replace(small, refining=True, sample=0) if refining else small
                try:
                    out.use()
                    self._render(drawn, out, (0, 0), None, user, warming=True)
                finally:
                    self.settings = user
                self._warmed.add(key)
        finally:
            out.release()
            color.release()
            self.frames, self._exposure_scale, self.refine_restarted, self._refine_dropped = kept
            if was_refining or warm_refine:
                self._forget_refinement()  # the warm frames drew over its targets
        return len(todo) - len(items)

    def _lod_triangles(self, frame: FrameInput) -> dict[float, int] | None:
        """Every 8th frame while the governor holds a frame rate: the left eye's triangles
        at each allowed error of ``LOD_ERRORS`` (what its level-of-detail steps would draw;
        about 1 ms on a real room's thousand chunks)."""
        scene = self.gpu_scene
        if scene is None or self.governor.budget_ms <= 0 or self.frames % 8 or not frame.eyes:
            return None
        return scene.triangles_by_error(frame.eyes[0], LOD_ERRORS)

    def _render(
        self,
        frame: FrameInput,
        out: moderngl.Framebuffer,
        origin: tuple[int, int],
        split: SplitFrame | None,
        user: Settings,
        warming: bool = False,
    ) -> None:
        view = (frame.eyes[0].width, frame.eyes[0].height)
        scale = 1.0 if split is not None else self.settings.render.scale
        size = render_size(view, scale)
        if size != view:
            eyes = [dataclasses.replace(e, width=size[0], height=size[1]) for e in frame.eyes]
            frame = dataclasses.replace(frame, eyes=eyes)
        cps = self.settings.cps
        if cps.mode == "cps" and user.cps.mode == "none" and not frame.cps_caps:
            # The governor's CPS: the host cast no edge rays (CPS is off in the user's
            # settings), so every side may reach the governor's coarsest block; the angle
            # from the gaze alone chooses the detail.
            caps = (float(cps.max_level),) * 3
            frame = dataclasses.replace(frame, cps_caps=[caps, caps])
        bias = self.settings.tcr.level_bias - user.tcr.level_bias
        if bias and frame.levels is not None:  # the governor's coarser textures
            frame = dataclasses.replace(frame, levels=[max(0, lv + bias) for lv in frame.levels])
        eye = frame.eyes[0]
        self._ensure_targets(eye.width, eye.height)
        self.cps.ensure(self.targets)
        if not warming:
            self.step_exposure()
        self._sync_lights()
        if split is not None and frame.refining:  # the presenter shows the technique as is
            dx, dy = frame.jitter
            eyes = [
                dataclasses.replace(
                    e, projection=jittered(e.projection, (-dx, -dy), e.width, e.height)
                )
                for e in frame.eyes
            ]
            frame = dataclasses.replace(frame, eyes=eyes, refining=False, jitter=(0.0, 0.0))
        settings = self.frame_settings(frame)
        ctx = self.frame_context(frame, out, origin, split, settings)
        ctx.scene.lod_bias = settings.render.lod_bias  # cheap: the governor moves it
        ctx.view_size = view
        ctx.warming = warming
        refine = self._by_name.get("refine")
        # Refined: the mean is final, so the passes before the accumulation are not drawn.
        holding = isinstance(refine, RefinePass) and refine.holding(ctx)
        enabled = self.configure(ctx, settings)
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
        # Finer textures arrived (the window streams a large scene's textures in), or a new
        # photon map: the mean so far was of another picture, so it starts again (the host
        # tells its session, see ``refine_restarted``).
        if ctx.refining and scene.streamer.uploaded_bytes > 0:
            self._forget_refinement()
        self.refine_restarted = bool(ctx.refining and self._refine_dropped)
        self._refine_dropped = False  # not refining: the session starts from sample 0 anyway
        if self.refine_restarted:
            holding = False
        if holding:
            at = enabled.index(refine) if refine in enabled else 0
            enabled = enabled[at:]
        res = self.resources
        res.begin_frame(self.targets)
        for p in self.passes:
            if not p.enabled or p not in enabled:
                p.last_ms = 0.0
        if holding:  # what the skipped passes made is still in the targets
            res.wrote(tuple(name for p in self.passes if p.enabled for name in p.writes))
        for p in enabled:
            try:
                p.run(ctx)
            except Exception as exc:  # noqa: BLE001 - one bad pass must not kill the app
                self._log_once(p.name, exc)
            res.wrote(p.writes)
        for p in enabled:  # the timers, once every pass is submitted (RenderPass.collect)
            p.collect()
        self.frames += 1
        if not warming:
            self._drawn = self.gpu_scene
            self._warmed.add(_frame_key(settings, ctx.refining))

    def cps_stats(self) -> dict:
        """Share of pixels per detail level and lighting evaluations, from the last frame's
        level maps (read back on request: the panel asks 4 times a second, the benchmark
        after each timed frame)."""
        maps = self.cps.read_levels() if self.cps_levels.enabled else []
        if not maps:
            return {}
        levels = np.concatenate([m.ravel() for m in maps])
        counts = np.bincount(levels, minlength=CPS_LEVELS)[:CPS_LEVELS]
        blocks = float(np.sum(counts / 4.0 ** np.arange(CPS_LEVELS)))
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
        elif p.cache is not None:
            c = p.cache.cache
            x, y, z = c.dims
            out["grid"] = (
                f"irradiance cache: {c.points:,} of {x}x{y}x{z} cells of {100 * c.cell:.3g} cm, "
                f"built in {c.build_ms:.0f} ms"
            )
        if p.enabled:
            out.update(p.reuse_stats())
        return out

    def object_ids(self, frame: FrameInput) -> list[np.ndarray]:
        """Mesh index under each pixel of each eye ((H, W) int32, row 0 at the top; -1: none)."""
        eye = frame.eyes[0]
        if not self.targets:  # the ids have their own targets at the view's size
            self._ensure_targets(eye.width, eye.height)
        ctx = self.frame_context(frame, self.ctx.screen)
        ctx.view_size = (eye.width, eye.height)
        self.resources.begin_frame(self.targets)
        self.ids.run(ctx)
        self.ids.collect()
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
        scene = self.gpu_scene or self._empty  # the scene the frame drew (as frame_context)
        return LightCullPass.evaluations(self.targets, len(scene.lights))

    def triangles_drawn(self) -> list[int]:
        """Triangles the last frame's geometry pass drew per eye (after frustum culling)."""
        drawn = (self.gpu_scene or self._empty).drawn
        return [drawn.get(i, 0) for i in range(2)]

    def draw_calls(self) -> list[int]:
        """Draw calls the last frame's geometry pass (G-buffer or forward) made per eye."""
        calls = (self.gpu_scene or self._empty).calls
        return [calls.get(i, 0) for i in range(2)]

    def draw_ranges(self) -> list[int]:
        """Index ranges those calls drew per eye (each command of a multi-draw counts)."""
        ranges = (self.gpu_scene or self._empty).ranges
        return [ranges.get(i, 0) for i in range(2)]

    def frame_draw_calls(self) -> int:
        """Draw calls for meshes so far, every pass (shadow maps, AO, ids included)."""
        return (self.gpu_scene or self._empty).draw_calls

    def texture_resident_bytes(self) -> int:
        return self.gpu_scene.texture_bytes if self.gpu_scene is not None else 0

    def read_hdr(self, eye: int) -> np.ndarray:
        """One eye's linear HDR colour as (H, W, 4) float32, row 0 at the top."""
        if "cps_filter" in self._by_name:  # folded into the present: draw it into the colour
            self.cps_filter.resolve()
        tex = self.targets[eye].color
        data = np.frombuffer(tex.read(), np.float16).reshape(tex.size[1], tex.size[0], 4)
        return np.flipud(data.astype(np.float32))

    def release(self) -> None:
        for p in (*self.passes, self.ids):
            p.release()
        self.cps.release()
        self._eye_targets.clear()
        self.targets = []
        if self.gpu_scene is not None:
            self.gpu_scene.release()
        self._empty.release()
        self._ambient.release()
        self.shaders.release()
