"""Progressive refinement while still (issue 15): rest detection, samples and progress, the
jitter, the accumulated picture (smoother edges, converging to full quality, also under CPS),
refinement off as before, "auto" (in the window only), a slow turn and arriving textures
starting the mean again, the built-in stop path and its bench figures, the overlay line."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from app.camera import StereoCamera
from app.paths import CameraPath, PathKey
from app.refine import halton_jitter, jitter_index, needed, refine_on
from app.scene import Material, PointLight, Scene, Texture, Viewpoint
from app.scenes import resolve_path
from app.session import Session
from app.settings import Settings, SettingsError
from render.offscreen import OffscreenHost
from tests.test_render import quad

W, H = 128, 64  # the side-by-side view: 2 x 64 x 64
TARGET = 8


def edge_scene() -> Scene:
    """A bright, emissive square on black, its edges off the pixel grid: aliased in one frame."""
    square = quad("square", (0.113, 1.637, -2.0), 0.83)
    mats = [Material("lamp", (0.0, 0.0, 0.0, 1.0), emissive=(0.6, 0.6, 0.6), roughness=1.0)]
    return Scene(
        "edges",
        [square],
        mats,
        [],
        [PointLight((0, 1.6, 0), (1, 1, 1), 0.0, 1.0)],
        Viewpoint((0, 1.6, 0)),
    ).sanitized()


def still_then_move(still_s: float, move_s: float = 0.5) -> CameraPath:
    keys = [
        PathKey(0.0, (0.0, 1.6, 0.0)),
        PathKey(still_s, (0.0, 1.6, 0.0)),
        PathKey(still_s + move_s, (0.5, 1.6, 0.0)),
    ]
    return CameraPath(keys, "edges")


def settings(refine: bool = True) -> Settings:
    s = Settings()
    s.render.refine = "on" if refine else "off"
    s.render.refine_samples = TARGET
    s.render.overlay = False
    return s


def session(s: Settings, path: CameraPath) -> Session:
    out = Session(s)
    out.set_scene(edge_scene(), path)
    return out


@pytest.fixture(scope="module")
def host():
    h = OffscreenHost(W, H, settings())
    h.set_scene(edge_scene())
    h.set_text_image(None)
    yield h
    assert not h.renderer.errors
    h.close()


def test_still_samples_grow_and_a_move_resets() -> None:
    path = still_then_move(1.0)
    ses = session(settings(), path)
    seen = []
    for n in range(path.frame_count()):
        ses.apply_path_frame(n)
        frame = ses.frame_input(64, 64)
        seen.append((frame.refining, frame.sample, ses.refinement.progress))
        if n == 20:
            assert ses.refinement.status_line() == "refined"
        if n == 5:
            assert ses.refinement.status_line() == f"refining {int(100 * 5 / needed(TARGET))}%"
    # Frame 0 is drawn as usual, then samples 0, 1, 2 ... up to needed(TARGET) (then held).
    assert [s for r, s, _p in seen[1 : 1 + needed(TARGET) + 2]] == [
        *range(needed(TARGET) + 1),
        needed(TARGET),
    ]
    assert not seen[0][0] and all(r for r, _s, _p in seen[1:60])
    progress = [p for _r, _s, p in seen[:30]]
    assert progress == sorted(progress) and progress[-1] == 1.0
    # Walking from 1 s on: no refinement, no overlay line.
    assert not any(r for r, _s, _p in seen[62:])
    assert ses.refinement.status_line() is None and ses.refinement.progress == 0.0


def test_gaze_moving_resets_and_tcr_levels_are_finest_while_refining() -> None:
    s = settings()
    s.tcr.enabled = True
    ses = session(s, still_then_move(1.0))
    for n in range(6):
        ses.apply_path_frame(n)
        frame = ses.frame_input(64, 64)
    assert frame.refining and frame.levels is None  # finest texture levels
    ses.gaze.set_cursor(0.9, 0.5)
    ses.tick(1 / 60)
    assert ses.frame_input(64, 64).refining is False
    assert ses.refinement.status_line() is None


def test_jitter_is_low_discrepancy_and_moves_the_picture() -> None:
    assert halton_jitter(0) == (0.0, 0.0)
    points = np.array([halton_jitter(jitter_index(s, 64)) for s in range(64)])
    assert len({tuple(p) for p in points}) == 64
    assert np.all(np.abs(points) <= 0.5)
    # Each quarter of the pixel gets a quarter of the samples, for the fovea (all samples)
    # and the periphery (its share of the first 64) alike.
    for subset in (points, points[::2]):
        quarters = np.histogram2d(subset[:, 0], subset[:, 1], bins=2, range=[[-0.5, 0.5]] * 2)
        assert quarters[0].min() >= len(subset) // 4 - 1
    cam = StereoCamera()
    plain = cam.eyes(64, 64)[0]
    shifted = cam.eyes(64, 64, (0.25, -0.5))[0]
    p = np.array([0.3, 1.2, -3.0, 1.0])

    def pixel(eye):
        c = eye.view_projection @ p
        return (c[:2] / c[3] + 1) / 2 * 64

    np.testing.assert_allclose(pixel(shifted) - pixel(plain), (0.25, -0.5), atol=1e-9)
    np.testing.assert_allclose(shifted.projection[2:], plain.projection[2:])  # depth as before


def frames_at_rest(host: OffscreenHost, ses: Session, count: int) -> list[np.ndarray]:
    host.renderer.refine.forget()  # the module's host: nothing of an earlier test's mean
    out = []
    for n in range(count):
        ses.apply_path_frame(n)
        out.append(host.draw(ses.frame_input(*host.eye_size)).astype(np.float64))
    return out


def intermediate(img: np.ndarray) -> int:
    """Edge pixels partly covered: pixels of a grey level that neither the background nor the
    square (nor the gaze marker) has in one frame."""
    grey = np.round(img.mean(axis=2))
    levels, counts = np.unique(grey, return_counts=True)
    common = levels[counts > 150]  # background, square, marker
    return int(np.count_nonzero(~np.isin(grey, common)))


def test_accumulated_edges_are_smoother_and_converge(host: OffscreenHost) -> None:
    ses = session(host.settings, still_then_move(3.0))
    frames = frames_at_rest(host, ses, needed(TARGET) + 3)
    single = frames[0]
    # One frame: the square's edges are hard (pixels all black or white)
    assert intermediate(single) < 20
    refined = frames[-1]
    assert intermediate(refined) > 4 * max(1, intermediate(single)) and intermediate(refined) > 60
    assert host.renderer.refine.enabled
    # Converging: against a mean of many more jittered samples the error falls.
    reference = reference_mean(host, ses, 64)
    errors = [np.abs(f - reference).mean() for f in (frames[1], frames[-1])]
    assert errors[1] < 0.5 * errors[0]


def reference_mean(host: OffscreenHost, ses: Session, samples: int) -> np.ndarray:
    """The refined picture of the same view at ``samples`` samples (a fresh accumulation)."""
    ses.settings.render.refine_samples = samples
    try:
        host.renderer.refine.forget()
        ses.refinement.reset()
        ses.tick(1 / 60)
        for _ in range(needed(samples) + 2):
            img = host.draw(ses.frame_input(*host.eye_size))
    finally:
        ses.settings.render.refine_samples = TARGET
        host.renderer.refine.forget()  # the next run starts its own mean
    return img.astype(np.float64)


def test_refine_off_gives_the_frames_of_before() -> None:
    off = settings(refine=False)
    with OffscreenHost(W, H, off) as h:
        h.set_scene(edge_scene())
        h.set_text_image(None)
        ses = session(off, still_then_move(1.0))
        cam = StereoCamera(off.stereo)
        for n in range(12):
            ses.apply_path_frame(n)
            frame = ses.frame_input(*h.eye_size)
            assert not frame.refining and frame.jitter == (0.0, 0.0)
            img = h.draw(frame)
            # The frame of before: the eyes without any shift, nothing accumulated.
            w = ses.walker
            cam.set_pose(w.position, w.yaw_deg, w.pitch_deg)
            frame.eyes = cam.eyes(*h.eye_size)
            assert np.array_equal(img, h.draw(frame))
        assert not h.renderer.refine.enabled
        assert not h.renderer.errors


def test_first_frame_at_rest_is_the_frame_of_before(host: OffscreenHost) -> None:
    ses = session(host.settings, still_then_move(1.0))
    ses.apply_path_frame(3)
    first = host.draw(ses.frame_input(*host.eye_size))
    off = settings(refine=False)
    ses_off = session(off, still_then_move(1.0))
    ses_off.apply_path_frame(3)
    assert np.array_equal(first, host.draw(ses_off.frame_input(*host.eye_size)))


def test_showroom_stop_walks_then_stands() -> None:
    path = resolve_path("showroom_stop")
    assert path.duration == pytest.approx(7.0)
    walk = [path.at_frame(n).position for n in range(0, 121, 30)]
    assert all(np.linalg.norm(np.subtract(a, b)) > 0.1 for a, b in zip(walk, walk[1:]))
    rest = {tuple(path.at_frame(n).position) for n in range(120, path.frame_count())}
    assert len(rest) == 1


def test_window_overlay_shows_refining_and_drops_it_when_moving(qtbot) -> None:
    from PyQt6.QtCore import Qt

    from tests.test_render import checker_scene
    from ui.main_window import MainWindow

    s = Settings()
    s.render.refine = "on"  # the tests' window has no display rate: "auto" would not refine
    s.render.refine_samples = 400  # long enough to see it refining
    w = MainWindow(s, checker_scene())
    qtbot.addWidget(w)
    w.view.setFixedSize(240, 135)
    w.show()
    qtbot.waitExposed(w)
    qtbot.waitUntil(lambda: (w.view.status_line or "").startswith("refining"), timeout=20000)
    assert any(line.startswith("refining") for line in w.view.overlay_text)
    qtbot.keyPress(w.view, Qt.Key.Key_W)
    qtbot.waitUntil(lambda: w.view.status_line is None, timeout=20000)
    assert not any(line.startswith("refin") for line in w.view.overlay_text)
    qtbot.keyRelease(w.view, Qt.Key.Key_W)
    w.close()


def test_auto_refines_in_the_window_only_and_old_switch_values_load() -> None:
    assert refine_on("auto", 60.0) and not refine_on("auto", None)
    assert refine_on("on", None) and not refine_on("off", 60.0)
    s = settings()
    s.set("render.refine", "auto")
    ses = session(s, still_then_move(1.0))  # headless: no display rate
    for n in range(6):
        ses.apply_path_frame(n)
        assert not ses.frame_input(64, 64).refining
    assert ses.refinement.status_line() is None
    ses.display_hz = 60.0  # the window sets it
    ses.apply_path_frame(6)
    ses.frame_input(64, 64)
    ses.apply_path_frame(7)
    assert ses.frame_input(64, 64).refining
    for text, mode in (("true", "on"), ("no", "off"), ("Auto", "auto")):
        s.set("render.refine", text)
        assert s.render.refine == mode
    with pytest.raises(SettingsError, match="render.refine"):
        s.set("render.refine", "sometimes")


TURN_DEG = 1.6  # over 2 s: 0.8 degrees a second, "still" by TCR's speed (below 0.05 m/s)


def slow_turn() -> CameraPath:
    p = (0.0, 1.6, 0.0)
    keys = [PathKey(0.0, p), PathKey(1.0, p), PathKey(3.0, p, TURN_DEG), PathKey(5.0, p, TURN_DEG)]
    return CameraPath(keys, "edges")


def test_a_slow_turn_is_motion_and_the_picture_follows(host: OffscreenHost) -> None:
    path = slow_turn()
    ses = session(host.settings, path)
    plain = session(settings(refine=False), path)
    host.renderer.refine.forget()
    turn_end = round(3.0 / (1 / 60))
    shown = {}
    for n in range(turn_end + needed(TARGET) + 4):
        ses.apply_path_frame(n)
        img = host.draw(ses.frame_input(*host.eye_size)).astype(np.float64)
        assert ses.viewpoint_speed <= host.settings.tcr.move_off  # never "moving" by speed
        if 62 <= n <= turn_end:  # but turning: no refining (full quality) frame in between
            assert not ses.refinement.active, n
        if n in (55, turn_end, turn_end + needed(TARGET) + 3):
            plain.apply_path_frame(n)
            shown[n] = (img, host.draw(plain.frame_input(*host.eye_size)).astype(np.float64))
    before, _ = shown[55]
    end_img, end_plain = shown[turn_end]
    moved = np.abs(shown[55][1] - end_plain).mean()
    assert moved > 0.5  # the turn moves the square's edges by about a pixel
    # At the end of the turn the picture shows where the viewer looks now, not the mean held
    # from where the turn began (the mean is not reprojected: it starts again).
    assert np.abs(end_img - end_plain).mean() < 0.3 * moved
    # Standing at the new pose, it refines to the mean of the new view.
    final, _ = shown[turn_end + needed(TARGET) + 3]
    fresh = reference_mean(host, ses, TARGET)
    assert np.abs(final - fresh).mean() < 0.2 * np.abs(before - fresh).mean()


def test_window_with_a_display_rate_refines_by_default(qtbot, monkeypatch) -> None:
    from tests.test_render import checker_scene
    from ui.main_window import MainWindow

    monkeypatch.setenv("VRPREVIEW_DISPLAY_HZ", "60")  # as on a real screen (the governor too)
    s = Settings()
    assert s.render.refine == "auto"
    s.render.refine_samples = 400
    w = MainWindow(s, checker_scene())
    qtbot.addWidget(w)
    w.view.setFixedSize(240, 135)
    w.show()
    qtbot.waitExposed(w)
    qtbot.waitUntil(lambda: (w.view.status_line or "").startswith("refining"), timeout=20000)
    assert w.session.display_hz == 60.0 and w.session.last_step.refining
    assert not w.view.renderer.errors
    w.close()


def test_refining_under_cps_converges_towards_the_full_quality_frame() -> None:
    from app import scenes
    from app.quality import full_quality

    s = settings()
    s.cps.mode = "cps"  # coarse shading away from the gaze while walking
    room = scenes.BUILTIN["showroom"]()
    stand = (0.75, 1.6, 1.05)
    path = CameraPath([PathKey(0.0, stand, 5.0), PathKey(2.0, stand, 5.0)], "showroom")
    ses = Session(s)
    ses.set_scene(room, path)
    frames = []
    with OffscreenHost(160, 90, s) as h:
        h.set_scene(room)
        h.set_text_image(None)
        for n in range(needed(TARGET) + 3):
            ses.apply_path_frame(n)
            frame = ses.frame_input(*h.eye_size)
            frames.append(h.draw(frame).astype(np.float64))
        assert not h.renderer.errors
    # The full-quality frame of the same pose, drawn once without jitter.
    cam = StereoCamera(s.stereo)
    w = ses.walker
    cam.set_pose(w.position, w.yaw_deg, w.pitch_deg)
    plain = dataclasses.replace(frame, refining=False, jitter=(0.0, 0.0), eyes=cam.eyes(80, 90))
    with OffscreenHost(160, 90, full_quality(s, converged_photons=False)) as ref:
        ref.set_scene(room)
        ref.set_text_image(None)
        full = ref.draw(plain).astype(np.float64)
    first, refined = frames[0], frames[-1]
    err_first = np.abs(first - full).mean()
    err_refined = np.abs(refined - full).mean()
    assert err_refined < 0.5 * err_first


def streamed_scene() -> Scene:
    """Eight quads filling the view, each with its own texture of four colours (seeded)."""
    rng = np.random.default_rng(15)
    meshes, mats, texs = [], [], []
    for i in range(8):
        x, y = -0.75 + 0.5 * (i % 4), 1.35 + 0.5 * (i // 4)
        meshes.append(quad(f"q{i}", (x, y, -1.2), 0.25, material=i))
        mats.append(Material(f"m{i}", (1, 1, 1, 1), i, roughness=1.0))
        colours = rng.integers(0, 256, (2, 2, 4), dtype=np.uint8)
        colours[..., 3] = 255
        tex = np.repeat(np.repeat(colours, 128, axis=0), 128, axis=1)  # four flat quarters
        texs.append(Texture(f"t{i}", tex, repeat=False))
    light = PointLight((0, 1.6, 0), (1, 1, 1), 30.0, 20.0)
    return Scene("streamed", meshes, mats, texs, [light], Viewpoint((0, 1.6, 0))).sanitized()


def refined_picture(stream_in: bool) -> tuple[np.ndarray, int]:
    """The refined picture of the streamed scene standing still (``stream_in``: the textures
    arrive one a frame while it refines, as in the window); and the frames that uploaded."""
    s = settings()
    scene = streamed_scene()
    path = CameraPath([PathKey(0.0, (0, 1.6, 0)), PathKey(2.0, (0, 1.6, 0))], "streamed")
    ses = Session(s)
    ses.set_scene(scene, path)
    uploads = 0
    with OffscreenHost(W, H, s) as h:
        h.set_scene(scene, stream_in=stream_in)
        h.set_text_image(None)
        assert h.renderer.gpu_scene is not None
        h.renderer.gpu_scene.streamer.budget_bytes = 1  # one texture a frame
        for n in range(40):
            ses.apply_path_frame(n)
            img = h.draw(ses.frame_input(*h.eye_size))
            uploads += h.renderer.gpu_scene.streamer.uploaded_bytes > 0
            if h.renderer.refine_restarted:  # as the window does
                ses.refinement.restart()
        assert ses.refinement.status_line() == "refined" and not h.renderer.errors
    return img.astype(np.float64), uploads


def test_textures_arriving_while_refining_start_the_mean_again(monkeypatch) -> None:
    import render.texture_stream as stream

    monkeypatch.setattr(stream, "STREAM_IN_ABOVE_BYTES", 0)
    monkeypatch.setattr(stream, "STREAM_IN_START_PX", 1)  # first one flat colour a texture
    resident, uploads = refined_picture(stream_in=False)
    assert uploads == 0
    streamed, uploads = refined_picture(stream_in=True)
    assert uploads >= 6  # the textures kept arriving while it refined
    # The refined picture holds no sample of the blurry textures: as if all were there.
    assert np.abs(streamed - resident).mean() < 0.25


def test_bench_showroom_stop_refines_with_the_default_setting() -> None:
    from app.lab.bench import bench

    s = Settings()  # render.refine "auto": off headless, the path turns it on
    result = bench("showroom", (320, 180), 3, s, warmup=1, path=resolve_path("showroom_stop"))
    assert s.render.refine == "auto"  # given back as it was
    assert result.refine is not None and result.refine["refine_on"]
    flip = result.refine["flip_after_still_s"]
    assert list(flip) == ["0.5", "1", "2", "5"]
    assert flip["0.5"] > flip["1"] > flip["2"] and flip["2"] <= 0.02  # the target
    assert all(result.refine["wall_s_after_still_s"][k] > 0 for k in flip)
