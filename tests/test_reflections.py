"""Reflections on glossy surfaces (render/reflections.py, ``render.reflections``): a glossy
floor mirrors a glowing panel on the wall ahead where a mirror would show it, a rough floor
does not, the picture away from glossy surfaces is untouched, and the forward path (no
G-buffer) draws as before."""

from __future__ import annotations

import numpy as np
import pytest

from app.camera import StereoCamera
from app.frame import FrameInput
from app.scene import Material, PointLight, Scene, Viewpoint
from app.settings import Settings
from render.offscreen import OffscreenHost
from tests.test_photons import HALF, _box_walls, _quad

LUMA = np.array([0.2126, 0.7152, 0.0722])
W, H = 160, 120
PITCH = -25.0  # looking down at the floor ahead, the panel in view above it


def _room(floor_roughness: float) -> Scene:
    """A dim box whose floor has ``floor_roughness``, a glowing panel on the far wall (+Z)
    between 0.2 and 1.0 m above the floor, a lamp near the ceiling."""
    walls = _box_walls()
    mats = [
        Material("wall", (0.3, 0.3, 0.3, 1.0), roughness=0.9),
        Material("floor", (0.2, 0.15, 0.1, 1.0), roughness=floor_roughness),
        Material("panel", (0.0, 0.0, 0.0, 1.0), emissive=(40.0, 40.0, 40.0)),
    ]
    for m in walls:
        m.material = 1 if m.name == "wall1-1" else 0
    y0, y1 = -HALF[1] + 0.2, -HALF[1] + 1.0
    z = HALF[2] - 0.01
    corners = np.array([[-1.0, y0, z], [1.0, y0, z], [1.0, y1, z], [-1.0, y1, z]])
    panel = _quad("panel", corners, np.array([0.0, 0.0, -1.0]), 2)
    lamp = PointLight((0.0, HALF[1] - 0.3, 0.0), (1.0, 1.0, 1.0), 2.0, 1e4)
    scene = Scene("glossy room", [*walls, panel], mats, lights=[lamp])
    scene.spawn = Viewpoint((0.0, 0.0, -1.0))
    return scene


def _frame(scene: Scene, reflections: str, path: str = "deferred") -> np.ndarray:
    """The left eye's HDR luminance (row 0 at the top) looking at the panel past the floor."""
    s = Settings()
    s.set("render.reflections", reflections)
    s.set("render.path", path)
    s.set("render.exposure_mode", "manual")
    # The fixed even light: the glowing panel lights the room through the estimate too,
    # and the mirror image is what is measured here.
    s.set("render.ambient_estimate", False)
    with OffscreenHost(2 * W, H, s) as host:
        host.set_scene(scene)
        cam = StereoCamera(s.stereo)
        cam.set_pose(scene.spawn.position, 180.0, PITCH)  # looking down +Z
        frame = FrameInput(cam.eyes(*host.eye_size), gaze=(0.5, 0.5))
        host.draw(frame)
        host.draw(frame)
        enabled = host.renderer.reflections.enabled
        hdr = host.read_hdr(0)[:, :, :3]
    assert enabled == (reflections == "screen" and path == "deferred")
    return hdr @ LUMA


def _rows(lum: np.ndarray) -> tuple[slice, slice]:
    """The panel's rows (bright) and the floor's rows below the panel's mirror image."""
    bright = np.flatnonzero(lum[:, W // 2] > 0.5 * lum[:, W // 2].max())
    assert bright.size, "the panel is in view"
    return slice(int(bright.min()), int(bright.max()) + 1), slice(int(bright.max()) + 2, H)


def test_a_glossy_floor_mirrors_the_glowing_panel():
    """Below the panel the glossy floor shows its mirror image: its brightest floor pixels
    several times brighter with reflections than without (the even light alone), centred
    under the panel; the panel itself and the walls above it are unchanged."""
    scene = _room(0.1)
    on, off = _frame(scene, "screen"), _frame(scene, "off")
    panel, floor = _rows(off)
    column = slice(W // 2 - 10, W // 2 + 10)
    assert on[floor, column].max() > 4.0 * off[floor, column].max()
    sides = np.concatenate([on[floor, :15], on[floor, -15:]], axis=1)
    assert on[floor, column].mean() > 2.0 * sides.mean()  # under the panel, not everywhere
    assert on[panel, column] == pytest.approx(off[panel, column], rel=1e-3)
    above = slice(0, panel.start - 2)
    assert on[above] == pytest.approx(off[above], rel=1e-3, abs=1e-6)


def test_a_rough_floor_keeps_the_even_light():
    """Roughness 0.9: nothing to mirror, the frame as without the pass."""
    scene = _room(0.9)
    on, off = _frame(scene, "screen"), _frame(scene, "off")
    assert on == pytest.approx(off, rel=1e-4, abs=1e-6)


def test_the_forward_path_draws_without_reflections():
    """The forward path has no G-buffer to march: the pass stays off and the picture is the
    same whatever the setting says."""
    scene = _room(0.1)
    on, off = _frame(scene, "screen", "forward"), _frame(scene, "off", "forward")
    assert np.isfinite(on).all()
    assert on == pytest.approx(off, rel=1e-5, abs=1e-6)


def test_a_change_of_render_scale_keeps_the_reflection():
    """The governor's render scale resizes the eyes' targets: the pass follows (its targets
    kept for the last sizes) and the mirror image is there at each size, without error."""
    scene = _room(0.1)
    s = Settings()
    s.set("render.exposure_mode", "manual")
    # The fixed even light: the glowing panel lights the room through the estimate too,
    # and the mirror image is what is measured here.
    s.set("render.ambient_estimate", False)
    with OffscreenHost(2 * W, H, s) as host:
        host.set_scene(scene)
        cam = StereoCamera(s.stereo)
        cam.set_pose(scene.spawn.position, 180.0, PITCH)
        frame = FrameInput(cam.eyes(*host.eye_size), gaze=(0.5, 0.5))
        peaks = []
        steps = ((1.0, "screen"), (0.75, "screen"), (0.75, "off"), (1.0, "screen"))
        for scale, reflections in steps:
            s.set("render.scale", scale)
            s.set("render.reflections", reflections)
            host.draw(frame)
            lum = host.read_hdr(0)[:, :, :3] @ LUMA
            h = lum.shape[0]
            peaks.append(float(lum[h // 2 :, lum.shape[1] // 2 - 5 : lum.shape[1] // 2 + 5].max()))
        assert not host.renderer.errors
        sizes = sorted(host.renderer.reflections._by_size.sizes())
    assert sizes == [(W * 3 // 4, H * 3 // 4), (W, H)]  # the two sizes drawn, kept
    assert peaks[1] > 3.0 * peaks[2]  # smaller: the floor mirrors the panel, off it does not
    assert peaks[0] == pytest.approx(peaks[3], rel=1e-3)  # back at full size: the same picture


def _open_room(sky: bool) -> np.ndarray:
    """The glossy room without its far wall (+Z), at 10:00 on the default date with the sky on
    or off: the left eye's HDR luminance looking level at the opening from 0.4 m above the
    floor (reflections on, then off)."""
    scene = _room(0.1)
    scene.meshes = [m for m in scene.meshes if m.name not in ("wall21", "panel")]
    s = Settings()
    s.set("sky.enabled", sky)
    s.set("render.exposure_mode", "manual")
    out = []
    for reflections in ("screen", "off"):
        s.set("render.reflections", reflections)
        with OffscreenHost(2 * W, H, s) as host:
            host.set_scene(scene)
            if sky and host.renderer.gpu_scene is not None:
                with host.ctx:
                    host.renderer.daylight.wait_for_visibility(host.renderer.gpu_scene)
            cam = StereoCamera(s.stereo)
            # Low and level: the floor ahead is seen at shallow angles, so the directions it
            # mirrors are the sky's seen through the opening.
            cam.set_pose((0.0, -HALF[1] + 0.4, -1.0), 180.0, 0.0)
            frame = FrameInput(cam.eyes(*host.eye_size), gaze=(0.5, 0.5))
            host.draw(frame)
            host.draw(frame)
            assert not host.renderer.errors
            out.append(host.read_hdr(0)[:, :, :3] @ LUMA)
    return np.stack(out)


def test_a_glossy_floor_mirrors_the_sky_through_an_opening():
    """Rays that leave through the opening meet nothing: with daylight they take the sky seen
    in their direction (the floor near the opening several times brighter than its even
    light), without it the background, which lights nothing, is not mirrored."""
    on, off = _open_room(True)
    column = slice(W // 2 - 20, W // 2 + 20)
    centre = off[: H // 2, W // 2]  # level: the upper half is above the horizon
    sky = np.flatnonzero(centre > 0.2 * centre.max())
    assert sky.size > H // 8, "the sky is in view through the opening"
    floor = slice(H // 2 + 12, H // 2 + 32)  # the floor a little below the opening's sill
    assert on[floor, column].mean() > 2.0 * off[floor, column].mean()
    assert on[sky] == pytest.approx(off[sky], rel=1e-3)  # the sky itself unchanged
    dark_on, dark_off = _open_room(False)
    assert dark_on[floor, column] == pytest.approx(dark_off[floor, column], rel=1e-3, abs=1e-6)
    assert np.isfinite(on).all() and np.isfinite(dark_on).all()
