"""The live state both hosts drive: scene, body, stereo camera, gaze and the playing path.

The Qt window feeds it keys and the cursor; the headless host feeds it a recorded path at a
fixed time step. Either way ``frame_input`` gives the renderer the same kind of frame.
"""

from __future__ import annotations

import math

from app.camera import StereoCamera
from app.frame import FrameInput
from app.gaze import GazeModel
from app.navigation import Walker
from app.paths import FIXED_DT, CameraPath, PathKey
from app.raycast import RayCaster
from app.scene import Scene
from app.scenes import default_path
from app.settings import Settings


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

    def set_scene(self, scene: Scene, path: CameraPath | None = None) -> None:
        self.scene = scene
        self.caster = RayCaster(scene.triangles(), scene.triangle_owner())
        self.walker.caster = self.caster
        sp = scene.spawn
        self.walker.place(sp.position, sp.yaw_deg, sp.pitch_deg)
        self.path = path or default_path(scene)
        self.time = 0.0

    # -- driving -------------------------------------------------------------------------------
    def apply_path_frame(self, n: int, dt: float = FIXED_DT) -> PathKey:
        """Put body and gaze where the path is at frame n (fixed step: reproducible)."""
        if self.path is None:
            raise RuntimeError("no path: call set_scene first")
        key = self.path.at_frame(n, dt)
        self.apply_key(key, dt)
        return key

    def apply_key(self, key: PathKey, dt: float) -> None:
        self.walker.place(key.position, key.yaw_deg, key.pitch_deg)
        self.gaze.set_cursor(*key.gaze)
        self.gaze.button_held = key.gaze_fixed
        self.gaze.update(dt, self.settings.stereo.fov_deg)
        self.observe_motion(dt)
        self.time = key.t

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
    def viewpoint_moving(self) -> bool:
        return self.viewpoint_speed > 0.05

    @property
    def state(self) -> int:
        """The TCR paper's state: 0 still/moving gaze, 1 moving/moving, 2 still/fixed, 3 both."""
        return int(self.viewpoint_moving) + 2 * int(self.gaze.state.fixed)

    def current_key(self) -> PathKey:
        """The present pose and gaze as a path key (for recording)."""
        g = self.gaze.state
        return PathKey(self.time, tuple(float(v) for v in self.walker.position),  # type: ignore
                       self.walker.yaw_deg, self.walker.pitch_deg, (g.u, g.v), g.fixed)

    def frame_input(self, eye_width: int, eye_height: int) -> FrameInput:
        w = self.walker
        self.camera.set_pose(w.position, w.yaw_deg, w.pitch_deg)
        g = self.gaze.state
        return FrameInput(self.camera.eyes(eye_width, eye_height), (g.u, g.v), g.fixed)

    # -- queries -------------------------------------------------------------------------------
    def gazed_object(self, eye_width: int = 640, eye_height: int = 720) -> str | None:
        """Name of the mesh under the gaze ray of the left eye, or None."""
        if self.scene is None or self.caster is None:
            return None
        w = self.walker
        self.camera.set_pose(w.position, w.yaw_deg, w.pitch_deg)
        eye = self.camera.eyes(eye_width, eye_height)[0]
        g = self.gaze.state
        dist, owner = self.caster.cast(eye.position, eye.ray(g.u, g.v))
        if not math.isfinite(dist) or owner < 0:
            return None
        return self.scene.meshes[owner].name
