"""The live state both hosts drive: scene, body, stereo camera, gaze and the playing path.

The Qt window feeds it keys and the cursor; the headless host feeds it a recorded path at a
fixed time step. Either way ``frame_input`` gives the renderer the same kind of frame.
"""

from __future__ import annotations

import math

import numpy as np

from app.camera import StereoCamera
from app.cps import side_caps
from app.exposure import EV_DEFAULT, displayed_brightness
from app.frame import FrameInput
from app.gaze import GazeModel
from app.navigation import Walker
from app.paths import FIXED_DT, CameraPath, PathKey
from app.raycast import RayCaster
from app.refine import Refinement, RefineStep, refine_on
from app.scene import Scene
from app.scenes import default_path
from app.settings import Settings
from app.tcr import LevelReason, MotionStateMachine, TcrController, pyramid_sizes


class Session:
    def __init__(self, settings: Settings | None = None) -> None:
        self.settings = settings or Settings()
        self.camera = StereoCamera(self.settings.stereo)
        self.gaze = GazeModel(self.settings.gaze)
        self.walker = Walker(self.settings.navigation)
        self.scene: Scene | None = None
        self.caster: RayCaster | None = None
        self.path: CameraPath | None = None
        self.time = 0.0
        self.viewpoint_speed = 0.0  # m/s plus turning (deg/s scaled), from the last step
        self._last_pose: tuple[float, float, float, float, float] | None = None
        t = self.settings.tcr
        self.motion = MotionStateMachine(t.move_on, t.move_off, t.window_s)
        self.tcr: TcrController | None = None
        self.levels: list[int] | None = None
        self.gazed: int | None = None
        self.eye_size = (640, 720)  # the eye viewport (pixels) the gaze ray is cast for
        self.edge: list = []  # CPS: app.cps.SideCaps per eye, from the last tick
        self._frame = -2  # last path frame applied (-2: none)
        # The host renderer's exposure in its last frame (hosts set it after each frame):
        # (the EV shown at before the Brightness, the EV the meter found for the room or
        # None). None: not known, from the settings alone.
        self.exposure_state: tuple[float, float | None] | None = None
        # Progressive refinement while viewpoint and gaze rest (app.refine); ``_settings_key``
        # is the settings it refines (a change starts it again).
        self.refinement = Refinement()
        self.last_step = RefineStep()
        self._settings_key = ""
        # The display's refresh rate (the window sets it; None headless): render.refine "auto"
        # refines only with one.
        self.display_hz: float | None = None

    def set_scene(self, scene: Scene, path: CameraPath | None = None) -> None:
        """Switch scenes; everything indexed by the old scene's meshes is forgotten first."""
        self.exposure_state = None  # measured in the old room
        self.refinement.reset()
        self.gazed = None
        self.levels = None
        self.edge = []
        self.tcr = None
        self.scene = scene
        owners = scene.triangle_owner()
        cached = scene.ray_caster
        self.caster = (
            cached.with_owners(owners)
            if isinstance(cached, RayCaster)
            else RayCaster(scene.triangles(), owners)
        )
        self.walker.caster = self.caster
        sp = scene.spawn
        self.walker.place(sp.position, sp.yaw_deg, sp.pitch_deg)
        self.path = path or default_path(scene)
        self.time = 0.0
        self._frame = -2
        self._reset_motion()
        n_levels = []
        for mesh in scene.meshes:
            tex = scene.materials[mesh.material].texture
            n_levels.append(
                len(pyramid_sizes(*scene.textures[tex].size)) - 1 if tex is not None else 0
            )
        lo = np.array([m.bounds()[0] for m in scene.meshes]).reshape(-1, 3)
        hi = np.array([m.bounds()[1] for m in scene.meshes]).reshape(-1, 3)
        self.tcr = TcrController(lo, hi, n_levels, [m.name for m in scene.meshes])

    # -- driving -------------------------------------------------------------------------------
    def apply_path_frame(self, n: int, dt: float = FIXED_DT) -> PathKey:
        """Put body and gaze where the path is at frame n (fixed step: reproducible).

        The motion state depends on the frames before, so a jump steps through the frames in
        between (from frame 0 when going back; no rendering, well under a millisecond a frame):
        frame N is the same whether played or sought.
        """
        if self.path is None:
            raise RuntimeError("no path: call set_scene first")
        n = max(0, int(n))
        if n <= self._frame or self._frame < 0:  # backwards (or the first call): from frame 0
            self._reset_motion()
            self._frame = -1
        for k in range(self._frame + 1, n):  # forwards: step through the frames in between
            self.apply_key(self.path.at_frame(k, dt), dt)
        key = self.path.at_frame(n, dt)
        self.apply_key(key, dt)
        self._frame = n
        return key

    def _reset_motion(self) -> None:
        t = self.settings.tcr
        self.motion = MotionStateMachine(t.move_on, t.move_off, t.window_s)
        self._last_pose = None
        self.viewpoint_speed = 0.0
        self.refinement.reset()  # a jump along the path is a move

    def apply_key(self, key: PathKey, dt: float) -> None:
        self.walker.place(key.position, key.yaw_deg, key.pitch_deg)
        self.gaze.set_cursor(*key.gaze)
        self.gaze.button_held = key.gaze_fixed
        self.tick(dt)
        self.time = key.t

    def tick(self, dt: float) -> None:
        """Once per frame in both hosts: gaze, motion state, gazed object, texture levels."""
        self.gaze.update(dt, self.settings.stereo.fov_deg)
        self.observe_motion(dt)
        t = self.settings.tcr
        m = self.motion
        m.move_on, m.move_off, m.window_s = t.move_on, t.move_off, t.window_s
        m.update(dt, self.viewpoint_speed, self.gaze.state.fixed)
        g = self.gaze.state
        w, h = self.eye_size
        wk = self.walker
        x, y, z = (float(v) for v in wk.position)
        fov = self.settings.stereo.fov_deg
        self.refinement.observe(
            dt,
            self.viewpoint_speed,
            t.move_off,
            (g.u, g.v),
            (self.camera.horizontal_fov_deg(w, h), fov),
            (x, y, z, float(wk.yaw_deg), float(wk.pitch_deg)),
            float(fov) / max(1, h),
        )
        self.gazed = self.gazed_index()
        self.edge = self.edge_caps()
        if self.tcr is not None:
            self.levels = [
                int(v)
                for v in self.tcr.update(
                    self.walker.position,
                    self.gazed,
                    m.viewpoint_moving,
                    m.gaze_fixed,
                    self.displayed_brightness(),
                    t,
                )
            ]

    def displayed_brightness(self) -> float:
        """What TCR's light term l reads: how bright the picture shows the room
        (``app.exposure.displayed_brightness``), with the host renderer's last exposure
        (:attr:`exposure_state`) and the settings now (a Brightness just changed counts at
        once). Without a host's exposure: the Brightness at the exposure against the default
        one (automatic: as adapted, so the Brightness alone)."""
        r = self.settings.render
        brightness = r.brightness * r.exposure
        auto = r.exposure_mode == "auto"
        if self.exposure_state is None:
            return displayed_brightness(brightness, EV_DEFAULT if auto else r.exposure_ev)
        shown, scene_ev = self.exposure_state
        return displayed_brightness(brightness, shown if auto else r.exposure_ev, scene_ev)

    def edge_caps(self) -> list:
        """CPS side caps per eye from the edge rays; [] when CPS and its views are off. The
        eye viewport is the one of the last :meth:`frame_input` (640x720 before any)."""
        c = self.settings.cps
        if c.mode == "none" and not c.visualize:
            return []
        w = self.walker
        self.camera.set_pose(w.position, w.yaw_deg, w.pitch_deg)
        return [side_caps(self.caster, eye, c) for eye in self.camera.eyes(*self.eye_size)]

    def observe_motion(self, dt: float) -> None:
        """Viewpoint speed since the last call: metres per second plus turning at 1 m per 30 deg."""
        w = self.walker
        pose = (*(float(v) for v in w.position), w.yaw_deg, w.pitch_deg)
        if self._last_pose is not None and dt > 0:
            a = self._last_pose
            moved = math.dist(a[:3], pose[:3])
            turned = abs((pose[3] - a[3] + 180.0) % 360.0 - 180.0) + abs(pose[4] - a[4])
            self.viewpoint_speed = (moved + turned / 30.0) / dt
        self._last_pose = pose  # type: ignore[assignment]

    @property
    def state(self) -> int:
        """The TCR paper's state: 0 still/moving gaze, 1 moving/moving, 2 still/fixed, 3 both."""
        return self.motion.state

    def reason(self, index: int | None) -> LevelReason | None:
        """Why mesh ``index`` has its texture level (None without TCR data)."""
        if self.tcr is None or index is None:
            return None
        return self.tcr.reason(index) if 0 <= index < len(self.tcr.n_levels) else None

    def current_key(self) -> PathKey:
        """The present pose and gaze as a path key (for recording)."""
        g = self.gaze.state
        return PathKey(
            self.time,
            tuple(float(v) for v in self.walker.position),  # type: ignore
            self.walker.yaw_deg,
            self.walker.pitch_deg,
            (g.u, g.v),
            g.fixed,
        )

    def refine_step(self) -> RefineStep:
        """The next frame's refinement request (counts one rendered frame): the settings
        refined are those of the first frame at rest; any change starts it again."""
        r = self.settings.render
        ref = self.refinement
        ref.enabled = refine_on(r.refine, self.display_hz)
        ref.target = max(1, int(r.refine_samples))
        key = repr(self.settings)
        if key != self._settings_key:
            self._settings_key = key
            ref.frames = 0
        self.last_step = ref.next_frame()
        return self.last_step

    def frame_input(self, eye_width: int, eye_height: int) -> FrameInput:
        """The frame to render now (each call is one rendered frame: it advances the
        refinement while the viewer rests)."""
        self.eye_size = (max(1, int(eye_width)), max(1, int(eye_height)))
        w = self.walker
        self.camera.set_pose(w.position, w.yaw_deg, w.pitch_deg)
        g = self.gaze.state
        caps = [(e.caps["left"], e.caps["right"], e.caps["bottom"]) for e in self.edge]
        step = self.refine_step()
        # Refining asks for full quality: the finest texture levels (TCR's None).
        levels = self.levels if self.settings.tcr.enabled and not step.refining else None
        return FrameInput(
            self.camera.eyes(eye_width, eye_height, step.jitter),
            (g.u, g.v),
            g.fixed,
            levels,
            caps or None,
            [e.hits for e in self.edge] or None,
            refining=step.refining,
            sample=step.sample,
            refine_target=step.target,
            jitter=step.jitter,
        )

    # -- queries -------------------------------------------------------------------------------
    def gazed_index(
        self, eye_width: int | None = None, eye_height: int | None = None
    ) -> int | None:
        """Index of the mesh hit by the (cyclopean) gaze ray, or None; for an eye viewport of
        ``eye_width`` x ``eye_height`` pixels (default: :attr:`eye_size`, which the window sets
        from its letterboxed eyes in device pixels and each :meth:`frame_input` updates)."""
        if self.scene is None or self.caster is None:
            return None
        if eye_width is None or eye_height is None:
            eye_width, eye_height = self.eye_size
        w = self.walker
        self.camera.set_pose(w.position, w.yaw_deg, w.pitch_deg)
        g = self.gaze.state
        dist, owner = self.caster.cast(*self.camera.gaze_ray(g.u, g.v, eye_width, eye_height))
        if not math.isfinite(dist) or owner < 0:
            return None
        return int(owner)

    def gazed_object(self) -> str | None:
        """Name of the mesh under the gaze (as of the last tick), or None."""
        if self.scene is None or self.gazed is None:
            return None
        if not 0 <= self.gazed < len(self.scene.meshes):
            return None
        return self.scene.meshes[self.gazed].name
