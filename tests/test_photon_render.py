"""Photon-mapped indirect light in the frame: only where asked for, equal to the CPU reference,
stereo reuse that lands where the geometry says, block-rate gathering under CPS."""

from __future__ import annotations

import numpy as np
import pytest

from app import indirect
from app.camera import StereoCamera, disparity_px
from app.frame import FrameInput
from app.lab.photon_ref import estimate_radius
from app.scene import Material, Mesh, PointLight, Scene, Viewpoint
from app.scenes import resolve
from app.session import Session
from app.settings import Settings
from render.offscreen import OffscreenHost

W, H = 320, 180


def box_room(depth: float = 3.0) -> Scene:
    """A 6 x 3 x 8 m grey room; the camera at (0, 1.5, 0) looks at the far wall ``depth`` m
    away; one light near the ceiling."""
    lo = np.array([-3.0, 0.0, -depth])
    hi = np.array([3.0, 3.0, 5.0])
    meshes = []
    for axis in range(3):
        for side, value in ((0, lo[axis]), (1, hi[axis])):
            u, v = [a for a in range(3) if a != axis]
            corners = []
            for cu, cv in ((0, 0), (1, 0), (1, 1), (0, 1)):
                p = np.zeros(3)
                p[axis] = value
                p[u] = (lo[u], hi[u])[cu]
                p[v] = (lo[v], hi[v])[cv]
                corners.append(p)
            n = np.zeros(3)
            n[axis] = 1.0 if side == 0 else -1.0  # facing into the room
            idx = np.array([[0, 1, 2], [0, 2, 3]], np.uint32)
            if np.dot(np.cross(corners[1] - corners[0], corners[2] - corners[0]), n) < 0:
                idx = idx[:, ::-1].copy()
            meshes.append(
                Mesh(
                    f"wall{axis}{side}",
                    np.array(corners, np.float32),
                    np.tile(n, (4, 1)).astype(np.float32),
                    np.zeros((4, 2), np.float32),
                    idx,
                    0,
                )
            )
    return Scene(
        "box",
        meshes,
        [Material("grey", (0.6, 0.6, 0.6, 1.0), roughness=1.0)],
        lights=[PointLight((0.0, 2.6, -1.0), (1, 1, 1), 20.0, 12.0)],
        spawn=Viewpoint((0.0, 1.5, 0.0)),
    ).sanitized()


def photon_settings(**values) -> Settings:
    s = Settings()
    s.render.overlay = False
    s.photons.enabled = "on"
    s.photons.photons = 1 << 14
    s.photons.radius_m = 0.4
    s.photons.indirect = "gather"  # these tests check the paper's gather itself
    for key, value in values.items():
        s.set(key.replace("__", "."), value)
    return s


def eye_frame(host: OffscreenHost, pos=(0.0, 1.5, 0.0)) -> FrameInput:
    cam = StereoCamera(host.settings.stereo)
    cam.set_pose(pos, 0.0, 0.0)
    return FrameInput(cam.eyes(*host.eye_size), gaze=(0.5, 0.5))


def gbuffer_points(host: OffscreenHost, eye: int, fi: FrameInput):
    """World points and normals of one eye's G-buffer (GL row order), and the lit mask."""
    tgt = host.renderer.targets[eye]
    w, h = tgt.size
    with host.ctx:
        depth = np.frombuffer(tgt.depth.read(), np.float32).reshape(h, w)
        normal = np.frombuffer(tgt.normal.read(), np.float16).reshape(h, w, 4)
    ys, xs = np.mgrid[0:h, 0:w]
    ndc = np.stack(
        [(xs + 0.5) / w * 2 - 1, (ys + 0.5) / h * 2 - 1, depth * 2.0 - 1, np.ones_like(depth)],
        axis=-1,
    ).astype(np.float64)
    world = ndc @ fi.eyes[eye].inverse_view_projection.T
    points = world[..., :3] / world[..., 3:]
    n = normal[..., :3].astype(np.float64)
    n /= np.maximum(np.linalg.norm(n, axis=-1, keepdims=True), 1e-12)
    return points, n, depth < 1.0


def test_no_photon_map_unless_the_scene_or_the_user_asks():
    s = photon_settings(photons__enabled="scene")
    scene = box_room()
    assert not scene.indirect
    with OffscreenHost(W, H, s) as host:
        host.set_scene(scene)
        host.draw(eye_frame(host))
        assert host.photon_cache.map is None
        assert not host.renderer.photons.active
        assert "photons" not in host.renderer.pass_ms()
        scene.indirect = True  # the scene asks: now it is traced
        host.draw(eye_frame(host))
        assert host.photon_cache.map is not None and len(host.photon_cache.map) > 0
        assert host.renderer.pass_ms().get("photons") is not None
        s.photons.enabled = "off"
        host.draw(eye_frame(host))
        assert not host.renderer.photons.active


def test_map_is_traced_again_only_when_what_it_depends_on_changes(monkeypatch):
    calls = []
    real = indirect.trace

    def counting(settings, scene, progress=None, cancel=None):
        calls.append(settings.photons)
        return real(settings, scene, progress, cancel)

    monkeypatch.setattr(indirect, "trace", counting)
    s = photon_settings()
    with OffscreenHost(W, H, s) as host:
        host.set_scene(box_room())
        for key, value in (
            ("photons.radius_m", 0.3),
            ("photons.gather", "radius-half"),
            ("photons.stereo_reuse", False),
            ("render.brightness", 0.5),
        ):
            s.set(key, value)
            host.draw(eye_frame(host))
        assert calls == [1 << 14]  # radius, variant, reuse and the dimmer: no new tracing
        s.photons.photons = 1 << 13
        host.draw(eye_frame(host))
        s.photons.seed = 3
        host.draw(eye_frame(host))
        assert calls == [1 << 14, 1 << 13, 1 << 13]
        assert not host.renderer.errors


@pytest.mark.parametrize("gather", ["radius", "shared"])
def test_indirect_target_equals_the_cpu_reference(gather):
    s = photon_settings(photons__gather=gather, photons__stereo_reuse=False)
    with OffscreenHost(W, H, s) as host:
        host.set_scene(box_room())
        fi = eye_frame(host)
        host.draw(fi)
        with host.ctx:
            gpu = np.flipud(host.renderer.photons.read_indirect(0))  # GL row order
        points, normals, lit = gbuffer_points(host, 0, fi)
        sel = np.flatnonzero(lit.ravel())[::37]
        ref = estimate_radius(
            host.photon_cache.map,
            points.reshape(-1, 3)[sel],
            normals.reshape(-1, 3)[sel],
            s.photons.radius_m,
        )
        got = gpu.reshape(-1, 4)[sel, :3]
        assert ref.max() > 0
        # The G-buffer depth is 24-bit: the CPU reconstructs the same points to ~1e-6 m, so
        # only photons within that of the radius can be counted differently.
        close = np.isclose(got, ref, rtol=1e-3, atol=1e-3 * ref.mean())
        assert close.mean() > 0.995, f"{(~close).sum()} of {close.size} values differ"
        assert np.all(np.isfinite(gpu)) and np.all(gpu[..., :3] >= 0)


def test_indirect_light_brightens_the_room_and_stays_finite():
    s = photon_settings()
    s.render.ambient_estimate = False  # against the fixed ambient, not its estimate
    with OffscreenHost(W, H, s) as host:
        host.set_scene(box_room())
        fi = eye_frame(host)
        lit = host.draw(fi).astype(float)
        with_hdr = host.read_hdr(0)
        s.photons.enabled = "off"
        dark = host.draw(fi).astype(float)
        assert lit.mean() > dark.mean() + 2.0  # bounced light adds to every wall
        assert np.all(np.isfinite(with_hdr))
        assert (lit >= dark - 1).all()  # indirect light only ever adds


def test_reuse_maps_a_point_to_the_right_eye_pixel_the_disparity_predicts():
    s = photon_settings(stereo__convergence_m=2.0)
    with OffscreenHost(W, H, s) as host:
        host.set_scene(box_room(depth=3.0))
        fi = eye_frame(host)
        host.draw(fi)
        w, h = host.eye_size
        with host.ctx:
            winner = np.frombuffer(host.renderer.photons.winner.read(), np.uint32).reshape(h, w)
        row = h // 2  # the centre line looks straight at the far wall, 3 m away
        expected = disparity_px(3.0, w, h, s.stereo)  # left x minus right x
        for q in range(w // 4, 3 * w // 4, 7):
            index = int(winner[row, q])
            assert index != 0xFFFFFFFF
            px, py = index % w, index // w
            assert py == row
            assert abs((px - q) - expected) <= 1.0
        assert winner[winner != 0xFFFFFFFF].max() < w * h  # indices of left pixels only


def test_reuse_covers_most_of_the_right_eye_and_matches_gathering():
    s = photon_settings()
    scene = resolve("showroom")
    session = Session(s)
    session.set_scene(scene)
    session.apply_path_frame(60)
    with OffscreenHost(W, H, s) as host:
        host.set_scene(scene)
        fi = session.frame_input(*host.eye_size)
        host.draw(fi)
        with host.ctx:
            stats = host.renderer.photon_stats()
            reused = host.renderer.photons.read_indirect(1)
        assert stats["reuse_share"] >= 0.7
        assert set(np.unique(reused[..., 3])) <= {0.0, 1.0, 2.0}
        s.photons.stereo_reuse = False
        host.draw(fi)
        with host.ctx:
            gathered = host.renderer.photons.read_indirect(1)
        both = (reused[..., 3] > 0) & (gathered[..., 3] > 0)
        rel = (
            np.abs(reused[..., :3] - gathered[..., :3])[both].mean()
            / gathered[..., :3][both].mean()
        )
        assert rel < 0.1  # a neighbour's value at most a pixel away: close, not equal


def test_extreme_stereo_keeps_reuse_inside_the_image():
    s = photon_settings(stereo__ipd_mm=100.0, stereo__convergence_m=0.1)
    with OffscreenHost(W, H, s) as host:
        host.set_scene(box_room(depth=0.3))  # the wall right in front of the eyes
        fi = eye_frame(host)
        host.draw(fi)
        w, h = host.eye_size
        with host.ctx:
            winner = np.frombuffer(host.renderer.photons.winner.read(), np.uint32)
            right = host.renderer.photons.read_indirect(1)
        set_ = winner[winner != 0xFFFFFFFF]
        assert set_.size == 0 or set_.max() < w * h
        assert np.all(np.isfinite(right))
        assert not host.renderer.errors


def test_under_coarse_shading_only_block_samples_gather():
    s = photon_settings(cps__mode="cps", cps__max_level=3, photons__stereo_reuse=False)
    with OffscreenHost(W, H, s) as host:
        host.set_scene(box_room())
        fi = eye_frame(host)
        fi.cps_caps = [(3, 3, 3), (3, 3, 3)]  # walls near on every side: blocks up to 8x8
        img = host.draw(fi)
        with host.ctx:
            levels = host.renderer.cps.read_levels()[0]
            left = host.renderer.photons.read_indirect(0)
        gathered = int((left[..., 3] == 1.0).sum())
        # One gathered sample per 2^s block of the left eye's level map.
        counts = np.bincount(levels.ravel(), minlength=4)
        blocks = float(np.sum(counts / 4.0 ** np.arange(len(counts))))
        assert counts[1:].sum() > 0.5 * levels.size  # most of the view is coarse
        assert gathered == pytest.approx(blocks, rel=0.02)
        assert np.isfinite(img).all()


def test_grid_too_large_is_reported_not_drawn_wrong():
    s = photon_settings(photons__radius_m=0.001)
    with OffscreenHost(W, H, s) as host:
        host.set_scene(box_room())
        host.draw(eye_frame(host))
        with host.ctx:
            stats = host.renderer.photon_stats()
        assert "cells" in (stats.get("error") or "")
        assert host.renderer.photons.gmap is None
        assert not host.renderer.errors


def test_beside_the_photon_map_the_even_light_is_only_what_it_leaves_out():
    """With bounced light from the photon map, the even light no longer adds the fixed level
    (0.06) on top of it (a room lit twice: the bathroom 1.1-1.4 times Cycles' brightness):
    it carries only what the photon map leaves out, here the lamp's light past its range."""
    levels = {}
    for range_m in (12.0, 2.0):
        room = box_room()
        lamp = room.lights[0]
        room.lights = [PointLight(lamp.position, lamp.color, lamp.intensity, range_m)]
        with OffscreenHost(W, H, photon_settings(photons__indirect="cache")) as host:
            host.set_scene(room)
            host.draw(eye_frame(host))
            with host.ctx:
                assert host.renderer.photons.photons is not None  # the photon map is drawn
                levels[range_m], _ = host.renderer.ambient_terms()
            assert not host.renderer.errors
    fixed = Settings().render.ambient
    # The whole room within the lamp's 12 m: next to nothing is left to the even light.
    assert 0.0 <= levels[12.0] < 0.05 * fixed
    # Past a 2 m range: that light, bounced round the room, is the even light's.
    assert levels[2.0] > 10.0 * levels[12.0]
