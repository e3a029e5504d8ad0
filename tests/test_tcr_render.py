"""TCR on the GPU: levels reach the picture, only the levels in use are resident, and the
session drives the levels from distance, motion and a held gaze."""

from __future__ import annotations

import numpy as np
import pytest

from app.camera import StereoCamera
from app.frame import FrameInput
from app.paths import FIXED_DT
from app.scene import Material, PointLight, Scene, Texture, Viewpoint
from app.scenes import resolve, resolve_path
from app.session import Session
from app.settings import Settings
from app.tcr import level_bytes
from render.context import create_headless
from render.offscreen import OffscreenHost
from render.passes import LEVEL_TINTS
from render.texture_stream import TextureStreamer
from tests.test_render import quad

W, H = 320, 180


def texel_checker(size: int = 64) -> Texture:
    """Black and white texels alternating: every pyramid level from 1 on is flat grey."""
    yy, xx = np.mgrid[:size, :size]
    on = (xx + yy) % 2 == 0
    rgba = np.zeros((size, size, 4), np.uint8)
    rgba[on] = 255
    rgba[..., 3] = 255
    return Texture("texels", rgba, repeat=True)


def near_far_scene() -> Scene:
    """A near quad (left of view, 1 m away) and a far one (right of view, 15 m away), each with
    its own texel checker; each lit by a lamp of its own (at the eye, and before the far one)."""
    near = quad("near", (-0.45, 1.6, -1.0), 0.35, material=0, uv_scale=0.1)  # magnified
    far = quad("far", (6.0, 1.6, -15.0), 5.0, material=1, uv_scale=8.0)  # minified
    mats = [
        Material("near", (1, 1, 1, 1), 0, roughness=1.0),
        Material("far", (1, 1, 1, 1), 1, roughness=1.0),
    ]
    return Scene(
        "near-far",
        [near, far],
        mats,
        [texel_checker(), texel_checker()],
        # Light falls off with the square of the distance: the far quad has its own lamp, 14 m
        # before it (so it lights it evenly: the tests measure texture detail, not light) and
        # bright enough to show its tint without washing it out; it lies in the near quad's
        # plane, so it does not light that one.
        [
            PointLight((0, 1.6, 0), (1, 1, 1), 5.0, 100.0),
            PointLight((6.0, 1.6, -1.0), (1, 1, 1), 300.0, 100.0),
        ],
        Viewpoint((0, 1.6, 0)),
    ).sanitized()


@pytest.fixture(scope="module")
def host():
    h = OffscreenHost(W, H, Settings())
    yield h
    assert not h.renderer.errors
    h.close()


def frame(host: OffscreenHost, levels=None, pos=(0, 1.6, 0), yaw=0.0) -> FrameInput:
    cam = StereoCamera(host.settings.stereo)
    cam.set_pose(pos, yaw, 0.0)
    return FrameInput(cam.eyes(*host.eye_size), gaze=(-1, -1), levels=levels)


def configure(host: OffscreenHost, **values) -> None:
    defaults = Settings()
    for key in ("tcr.enabled", "tcr.mode", "tcr.tint", "tcr.preset", "render.path"):
        host.settings.set(key, defaults.get(key))
    for key, value in values.items():
        host.settings.set(key.replace("__", "."), value)


def nearest_tint(rgb: np.ndarray) -> int:
    """The coloured legend entry (levels 1+) whose direction in RGB is closest to ``rgb``."""
    tints = np.array(LEVEL_TINTS[1:])
    cos = tints @ rgb / (np.linalg.norm(tints, axis=1) * np.linalg.norm(rgb))
    return int(np.argmax(cos)) + 1


def level_map(ids: np.ndarray, levels: list[int]) -> np.ndarray:
    """Per pixel, the level of the object seen there (-1: background)."""
    lut = np.array([*levels, -1], np.int32)
    return lut[np.where(ids < 0, len(levels), ids)]


def test_far_object_uses_a_coarser_level_than_the_near_one(host):
    scene = near_far_scene()
    configure(host, tcr__enabled=True)
    session = Session(host.settings)
    session.set_scene(scene)
    session.walker.place((0, 1.6, 0), 0.0, 0.0)
    session.tick(FIXED_DT)
    host.set_scene(scene)
    fi = session.frame_input(*host.eye_size)
    ids = host.object_ids(fi)[0]
    lm = level_map(ids, session.levels)
    near_levels = np.unique(lm[ids == 0])
    far_levels = np.unique(lm[ids == 1])
    assert near_levels.size == 1 and far_levels.size == 1  # one level per object
    # SPEC B: at distance d + f from the eye, j = floor(log2((d + f) / f)); f = 1 m. The
    # nearest point of the near quad is 1.005 m away (j = 0), of the far quad 15.03 m (j = 3).
    assert near_levels[0] == 0 and far_levels[0] == 3
    assert far_levels[0] > near_levels[0]
    # And the renderer uses them: tinted, each object shows its level's legend colour.
    configure(host, tcr__enabled=True, tcr__tint=True)
    img = host.draw(fi)[:, : W // 2].astype(float)
    for obj, level in ((0, near_levels[0]), (1, far_levels[0])):
        mean = img[ids == obj].mean(axis=0)
        tint = np.array(LEVEL_TINTS[level])
        if level == 0:  # the finest level is not tinted: the grey texture stays grey
            assert np.ptp(mean) < 3, mean
        else:  # the tint dominates the hue: of the legend, its own colour is the closest
            assert nearest_tint(mean) == level, (obj, level, mean, tint)
            assert np.ptp(mean) > 20, mean


def test_paper_samples_exactly_level_j_and_clamp_mipmaps(host):
    scene = near_far_scene()
    host.set_scene(scene)
    ids = host.object_ids(frame(host))[0]
    near, far = ids == 0, ids == 1

    def spread(img, mask):
        """Mean step between horizontal neighbours inside the mask: texture detail, not the
        smooth fall-off of the light."""
        g = img.astype(float).mean(axis=2)
        both = mask[:, 1:] & mask[:, :-1]
        return np.abs(g[:, 1:] - g[:, :-1])[both].mean()

    configure(host)
    full = host.draw(frame(host))[:, : W // 2]
    configure(host, tcr__enabled=True, tcr__mode="paper")
    paper0 = host.draw(frame(host, [0, 0]))[:, : W // 2]
    paper2 = host.draw(frame(host, [2, 2]))[:, : W // 2]
    configure(host, tcr__enabled=True, tcr__mode="clamp")
    clamp0 = host.draw(frame(host, [0, 0]))[:, : W // 2]
    clamp2 = host.draw(frame(host, [2, 2]))[:, : W // 2]
    # Near, magnified: level 0 shows the texels, level 2 is flat grey in both modes.
    assert spread(full, near) > 4 and spread(paper0, near) > 4 and spread(clamp0, near) > 4
    assert spread(paper2, near) < 1 and spread(clamp2, near) < 1
    # Far, minified (many texels per pixel): paper at level 0 aliases, clamp filters like the
    # full-quality frame, which it equals when j = 0.
    assert spread(paper0, far) > 8 > 0.5 > spread(clamp0, far)
    assert np.abs(clamp0.astype(int) - full.astype(int)).max() <= 1


def test_only_levels_in_use_are_resident():
    ctx = create_headless()
    try:
        with ctx:
            tex = [Texture(f"t{i}", np.full((512, 512, 4), 128, np.uint8)) for i in range(4)]
            s = TextureStreamer(ctx, tex, budget_bytes=3 << 20, keep_frames=5)
            chain = [sum(level_bytes(512, 512)[k:]) for k in range(10)]
            assert chain[0] == sum(4 * (512 >> k) ** 2 for k in range(10))
            assert s.resident_bytes() == 4 * chain[0]  # start: everything (TCR off)
            for _ in range(4):
                s.update([3, 3, 3, -1])
            assert s.resident_bytes() == 4 * chain[0]  # finer levels kept a while (no thrash)
            s.update([3, 3, 3, -1])
            assert [r.base for r in s.resident] == [3, 3, 3, 9]  # unused: down to 1x1
            assert s.resident_bytes() == 3 * chain[3] + chain[9] == 3 * 21844 + 4
            assert [r.tex.size for r in s.resident] == [(64, 64)] * 3 + [(1, 1)]
            # Back to full quality: at most the budget per frame (one texture over it may go
            # alone), the finest-needed first; coarse levels stand in meanwhile.
            frames = 0
            while any(r.base for r in s.resident):
                s.update([0, 0, 0, 0])
                frames += 1
                assert s.uploaded_bytes <= max(s.budget_bytes, chain[0])
            assert frames == 2 and s.resident_bytes() == 4 * chain[0]
            s.release()
    finally:
        ctx.release()


def test_renderer_reports_resident_bytes_with_and_without_tcr(host):
    scene = resolve("tcr-cube")
    full = sum(sum(level_bytes(*t.size)) for t in scene.textures)
    configure(host)
    host.set_scene(scene)
    host.draw(frame(host, pos=(0, 1.6, 8.0)))
    assert host.renderer.texture_resident_bytes() == full
    configure(host, tcr__enabled=True)
    for _ in range(host.renderer.gpu_scene.streamer.keep_frames):
        host.draw(frame(host, [3], pos=(0, 1.6, 8.0)))
    t = scene.textures[0]
    assert host.renderer.texture_resident_bytes() == sum(level_bytes(*t.size)[3:])


def test_gazed_object_drops_one_level_while_the_gaze_is_held():
    settings = Settings()
    settings.set("tcr.enabled", True)
    settings.set("tcr.preset", "psychology")  # d, g, l
    session = Session(settings)
    session.set_scene(resolve("tcr-cube"), resolve_path("tcr_cube_gaze"))
    path = session.path
    seen = []
    for n in range(0, int(2.5 / FIXED_DT), 5):
        key = session.apply_path_frame(n)
        seen.append((key.gaze_fixed, session.gazed, session.levels[0], session.state))
    free = {s for s in seen if not s[0]}
    held = {s for s in seen if s[0]}
    assert free and held and path is not None
    # Standing 3.5 m from the cube (f = 1 m): floor(log2(3.5)) = 1; gaze held on it: 1 - 1.
    assert {(g, lvl, st) for _, g, lvl, st in free} == {(0, 1, 0)}
    assert {(g, lvl, st) for _, g, lvl, st in held} == {(0, 0, 2)}
    # Ergonomics ignores the gaze.
    settings.set("tcr.preset", "ergonomics")
    session.apply_path_frame(int(2.0 / FIXED_DT))
    assert session.gazed == 0 and session.levels == [1]


def test_a_huge_texture_set_streams_in_instead_of_freezing_the_window(monkeypatch):
    """The window's path (stream_in): past the threshold every texture starts small and the
    finer levels arrive within the per-frame budget; below it, or headless, all at once."""
    import render.texture_stream as ts

    ctx = create_headless()
    try:
        with ctx:
            tex = [Texture(f"t{i}", np.full((512, 512, 4), 90 + i, np.uint8)) for i in range(6)]
            monkeypatch.setattr(ts, "STREAM_IN_ABOVE_BYTES", 4 << 20)  # 6 x 1.4 MB is "huge"
            headless = TextureStreamer(ctx, tex)
            assert [r.base for r in headless.resident] == [0] * 6
            s = TextureStreamer(ctx, tex, budget_bytes=3 << 20, stream_in=True)
            assert [r.tex.size for r in s.resident] == [(128, 128)] * 6  # what arrives first
            frames = 0
            while any(r.base for r in s.resident):
                s.update([0] * 6)
                frames += 1
                assert s.uploaded_bytes <= 3 << 20
            assert frames == 3 and [r.tex.size for r in s.resident] == [(512, 512)] * 6
            monkeypatch.setattr(ts, "STREAM_IN_ABOVE_BYTES", 64 << 20)  # a normal room
            small = TextureStreamer(ctx, tex, stream_in=True)
            assert [r.base for r in small.resident] == [0] * 6
            for streamer in (headless, s, small):
                streamer.release()
    finally:
        ctx.release()
