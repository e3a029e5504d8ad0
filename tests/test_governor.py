"""The frame-time governor: a synthetic cost model for its decisions, headless renders for the
render scale and its upscaler."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from app.camera import StereoCamera
from app.frame import FrameInput
from app.governor import Governor, apply_overrides, category, cost_factors, target_fps
from app.scene import Material, Mesh, PointLight, Scene, Viewpoint
from app.settings import Settings, SettingsError
from render.offscreen import OffscreenHost

KEYS = (
    "render.scale",
    "render.lod_bias",
    "render.shadows",
    "render.shadow_updates_per_frame",
    "cps.mode",
    "cps.max_level",
    "cps.fovea_deg",
    "cps.deg_per_level",
    "render.upscaler",
)
# A frame's full-quality pass costs (ms), the shape of the showroom's at 2x640x720; CPS's
# lighting replaces the full-rate one (each is 0 where the other runs) and adds its levels.
BASE = {
    "gbuffer": 14.0,
    "shadows": 6.0,
    "lighting": 40.0,
    "cps_lighting": 40.0,
    "cps_levels": 4.0,
    "ao": 6.0,
    "present": 4.0,
}


def synthetic(
    user: Settings,
    overrides: dict,
    load: float = 1.0,
    base: dict | None = None,
    truth=cost_factors,
) -> tuple[dict, float]:
    """Pass times and frame time for these knobs: the model's own shape (``truth``: another
    one) with other numbers (geometry with a fixed vertex share, lighting following the
    shaded pixels)."""
    eff = apply_overrides(user, overrides)
    f = truth({k: eff.get(k) for k in KEYS})
    costs = BASE if base is None else base
    passes = {name: load * ms * f[category(name)] for name, ms in costs.items()}
    return passes, sum(passes.values()) + 2.0


def run(
    user: Settings,
    frames: int,
    load=lambda i: 1.0,
    gov: Governor | None = None,
    base: dict | None = None,
    truth=cost_factors,
):
    gov = gov or Governor()
    overrides: dict = {}
    times, history = [], []
    for i in range(frames):
        passes, ms = synthetic(user, overrides, load(i), base, truth)
        times.append(ms)
        overrides = gov.observe(user, passes, ms)
        history.append(dict(overrides))
    return gov, times, history


def walking(fps: str = "30") -> Settings:
    s = Settings()
    s.set("render.target_fps", fps)
    return s


def test_target_fps_parses_auto_numbers_and_rejects_the_rest():
    s = Settings()
    assert s.render.target_fps == "auto"
    assert target_fps(s, None) == 0.0  # headless: no display, fixed settings
    assert target_fps(s, 60.0) == 60.0
    s.set("render.target_fps", "30.0")
    assert s.render.target_fps == "30" and target_fps(s, 144.0) == 30.0
    s.set("render.target_fps", 0)
    assert target_fps(s, 60.0) == 0.0
    for bad in ("fast", "-5", "1000", "nan"):
        with pytest.raises(SettingsError):
            s.set("render.target_fps", bad)


def test_target_zero_changes_nothing():
    user = walking("0")
    gov, times, history = run(user, 40)
    assert all(h == {} for h in history)
    assert not gov.history and apply_overrides(user, {}) is user


def test_converges_under_budget_without_oscillation():
    user = walking("30")
    gov, times, history = run(user, 120)
    assert times[0] > 2 * 33.3  # full quality is far over
    settled = times[40:]
    assert max(settled) <= 33.4  # holds the budget
    assert max(settled) > 0.5 * 33.3  # and does not throw quality away
    assert all(h == history[40] for h in history[40:])  # no change once settled
    restores = [d for d in gov.history if d.action == "restore"]
    assert len(restores) <= 2
    # the user's own settings are untouched: the overrides go to a copy
    assert user.render.scale == 1.0 and user.cps.mode == "none"


def test_fovea_knobs_go_last_and_come_back_first():
    user = walking("30")
    gov, _, _ = run(user, 40, load=lambda i: 6.0)  # far too slow for anything but everything
    order = [d.knob for d in gov.history if d.action == "lower"]
    fovea = {"sharp area around the gaze", "detail falloff"}
    assert fovea & set(order)
    first_fovea = min(i for i, k in enumerate(order) if k in fovea)
    assert all(k in fovea for k in order[first_fovea:])
    assert gov.overrides["render.scale"] == 0.35  # everything else spent first
    run(user, 120, load=lambda i: 0.3, gov=gov)  # now there is time: quality comes back
    restores = [d.knob for d in gov.history if d.action == "restore"]
    assert restores and restores[0] in fovea
    assert gov.overrides.get("render.scale", 1.0) > 0.35


def test_coarse_lighting_that_costs_more_than_it_saves_is_given_back():
    """CPS adds passes of its own (block levels, filter): where they outweigh what it saves
    (on llvmpipe at every render scale), the governor learns it from the timers and turns CPS
    off again, for a faster and better frame, and does not try it again."""
    user = walking("30")
    dear = {**BASE, "cps_levels": 45.0}  # the prior guessed 6 ms
    gov, times, history = run(user, 150, base=dear)
    cps = [d for d in gov.history if d.knob == "coarse lighting in the periphery"]
    assert cps and cps[0].action == "lower"  # tried (the prior said it would pay) ...
    assert any(d.action == "restore" and d.value == "none" for d in cps)  # ... and given back
    assert history[-1].get("cps.mode", "none") == "none"
    assert max(times[100:]) <= 33.4  # the budget is held without it
    assert sum(d.action == "lower" for d in cps) <= 2  # no trying again and again
    # Where CPS pays (its own passes cheap), it is taken and the timers confirm it saves
    # time; given back only in a trade for another knob's step that loses less (_swap).
    gov, _, history = run(user, 150)
    cps = [d for d in gov.history if d.knob == "coarse lighting in the periphery"]
    assert cps and cps[0].action == "lower"
    for d in cps:
        if d.action == "restore":
            assert any(o.frame == d.frame and o.action == "trade" for o in gov.history)
    without = {k: v for k, v in gov.position.items() if k != "cps.max_level"}
    assert gov.predict(user, {**without, "cps.max_level": 3}) < gov.predict(user, without)


def test_coarse_lighting_taken_at_full_resolution_is_traded_for_a_lower_scale():
    """The greedy steps took coarse lighting while the picture was at full resolution (it
    saved much there), then lowered the render scale, under which it saves little for the
    same loss. Within the budget the governor trades it for a step of another knob (here
    simpler far geometry, which the showroom's table says loses nothing): less quality
    lost, no more time (and it stays so: the trade does not come back)."""
    stuck = {"cps.max_level": 3, "render.scale": 4}  # CPS 3 at scale 0.59
    gov = Governor()
    gov._knobs_all(walking("30"))  # noqa: SLF001 - the knob steps, to price the position
    _, ms = synthetic(walking("30"), gov._values(walking("30"), stuck))  # noqa: SLF001
    user = walking(f"{1000.0 / (ms / 0.9):.3f}")  # the stuck frame is 90 % of the budget
    budget = 1000.0 / float(user.render.target_fps)
    gov = Governor(position=dict(stuck))
    before = gov.error(user, stuck)
    gov, times, history = run(user, 80, gov=gov)
    assert history[-1].get("cps.mode", "none") == "none", history[-1]
    assert history[-1]["render.scale"] <= 0.59 and history[-1] != {"render.scale": 0.59}
    assert gov.error(user, gov.position) < before - 0.01
    assert max(times[20:]) <= budget
    assert all(h == history[30] for h in history[30:])  # one trade, then it holds
    trade = [d for d in gov.history if d.frame == gov.history[0].frame]
    assert [d.action for d in trade] == ["restore", "trade"]
    assert trade[1].instead == "coarse lighting in the periphery"
    assert any("in place of less coarse lighting" in line for line in gov.explain(user))


def test_a_restore_that_overshoots_is_undone_in_one_step():
    """The model can be wrong about a step back (a category it has not measured for a while,
    a view it has not seen): the frames after it are far over budget. The governor goes back
    to where it was before that change, rather than take new steps on the same model (or a
    "free" one it now mispredicts), and holds the knob back for a while."""
    user = walking("30")
    budget = 1000.0 / 30.0

    def truth(values):  # full resolution costs four times what the model says
        f = cost_factors(values)
        if float(values.get("render.scale", 1.0)) >= 0.999:
            f = {c: 4.0 * v for c, v in f.items()}
        return f

    gov = Governor(position={"render.scale": 1})  # 0.85, within budget with time to spare
    gov, times, history = run(user, 60, load=lambda i: 0.5, gov=gov, truth=truth)
    full = next(i for i, h in enumerate(history) if "render.scale" not in h)
    assert times[full + 1] > 2 * budget  # the model said full resolution fits: it does not
    undone = next(i for i in range(full + 1, len(history)) if history[i] != history[full])
    assert undone - full <= 6 and history[undone] == history[full - 1]  # back where it was
    assert all("render.scale" in h for h in history[undone:])  # not retried meanwhile
    assert max(times[undone + 2 :]) <= budget


def test_noisy_frames_after_a_free_restore_do_not_make_it_oscillate():
    """CPS costing a little more than it saves, frames varying by 10 % (a busy machine): the
    governor gives CPS back and, over budget now and then, does not take it and give it back
    again and again (a knob given back and then over budget is held back, free or not)."""
    user = walking("30")
    rng = np.random.default_rng(1)
    noise = rng.uniform(0.9, 1.1, 400)
    dear = {**BASE, "cps_levels": 30.0}
    gov, _, history = run(user, 400, load=lambda i: float(noise[i]), base=dear)
    cps = [d for d in gov.history if d.knob == "coarse lighting in the periphery"]
    assert cps and sum(d.action == "lower" for d in cps) <= 3, [
        (d.frame, d.action, d.value) for d in cps
    ]
    assert history[-1].get("cps.mode", "none") == "none"


def test_a_knob_that_saves_less_than_modelled_is_learnt():
    """A room of few triangles: simpler geometry saves nothing (the model says about half the
    geometry pass). The governor measures each one-knob change against the model and learns
    the step's real effect: its prediction of the frame at the step it came from comes close
    to the truth, where the model's own shape stays far off."""

    def few_triangles(values):
        f = cost_factors(values)
        s = float(values.get("render.scale", 1.0))
        f["geometry"] = 0.4 + 0.6 * s * s  # whatever the level of detail
        return f

    user = walking("30")  # the forward path, everything else already at its cheapest
    for key, value in (
        ("render.path", "forward"),
        ("render.scale", 0.35),
        ("render.upscaler", "bilinear"),
        ("render.shadows", "hard"),
        ("render.shadow_updates_per_frame", 1),
    ):
        user.set(key, value)
    base = {"forward": 60.0, "present": 4.0}
    heavy = lambda i: 1.3 if (i // 40) % 2 == 0 else 0.8  # noqa: E731 - views come and go

    def prediction_error(gov: Governor) -> float:
        gov, _, _ = run(user, 200, load=heavy, truth=few_triangles, gov=gov, base=base)
        assert gov.position.get("render.lod_bias", 0) >= 2  # it did try simpler geometry
        step_back = {**gov.position, "render.lod_bias": 1}  # the simplest level but one
        _, truth = synthetic(user, {"render.lod_bias": 2}, heavy(199), base, few_triangles)
        return abs(gov.predict(user, step_back) - truth) / truth

    naive = Governor()
    naive._learn_step = lambda user: None  # type: ignore[method-assign]
    learnt = Governor()
    assert prediction_error(learnt) < 0.05 < 0.2 < prediction_error(naive)
    assert max(s.get("geometry", 1.0) for s in learnt.step_scale.values()) > 1.3
    assert any(key.startswith("render.lod_bias#") for key in learnt.summary()["learnt"])
    # Another room, or the user moving a knob the steps start from: learnt afresh.
    learnt.new_scene()
    assert not learnt.step_scale and not learnt.base_ms
    gov, _, _ = run(user, 60, load=heavy, truth=few_triangles, base=base)
    assert gov.step_scale
    user.set("render.lod_bias", 2.0)
    passes, ms = synthetic(user, gov.overrides, 1.0, base, few_triangles)
    gov.observe(user, passes, ms)
    assert not gov.step_scale


def test_holds_the_budget_as_the_cost_changes():
    user = walking("30")
    load = lambda i: 1.0 if i < 80 else 1.3  # noqa: E731 - the room gets heavier
    gov, times, history = run(user, 200, load=load)
    assert max(times[150:]) <= 33.4
    assert all(h == history[150] for h in history[150:])
    assert history[150] != history[79]  # it had to lower more


def test_refining_returns_full_quality_and_keeps_the_walking_state():
    user = walking("30")
    gov, _, history = run(user, 60)
    walking_knobs = history[-1]
    assert walking_knobs.get("render.scale", 1.0) < 1.0
    passes, ms = synthetic(user, walking_knobs)
    still = gov.observe(user, passes, ms, refining=True)
    assert still["render.scale"] == 1.0 and still["cps.mode"] == "none"
    assert still["render.shadows"] == "soft"
    assert "Standing still" in " ".join(gov.explain(user))
    assert gov.observe(user, passes, ms, refining=False) == walking_knobs  # at once


def test_standing_still_leaves_shadows_the_user_turned_off_off():
    user = walking("30")
    user.set("render.shadows", "off")
    gov, _, history = run(user, 30)
    passes, ms = synthetic(user, history[-1])
    still = apply_overrides(user, gov.observe(user, passes, ms, refining=True))
    assert still.render.shadows == "off" and still.render.scale == 1.0
    user.set("render.shadows", "hard")  # the user's hard edges: full quality is soft
    still = apply_overrides(user, gov.observe(user, passes, ms, refining=True))
    assert still.render.shadows == "soft"


def test_panel_words_name_the_budget_and_the_reason():
    user = walking("30")
    gov, _, _ = run(user, 20)
    text = "\n".join(gov.explain(user))
    assert "Budget 33 ms" in text and "render scale" in text
    assert "over the 33 ms budget" in text and "largest cost" in text
    assert "Frame rate not held" in "\n".join(Governor().explain(walking("0")))


def test_the_panel_says_when_nothing_is_left_to_simplify():
    """A room this computer cannot draw at the asked rate however simple it gets: the
    governor took every step, and the panel said only what it had lowered, as if it were
    still holding the rate. It now says the rate cannot be held, and what to do."""
    user = walking("30")
    gov, times, _ = run(user, 160, load=lambda i: 40.0)  # 40x this synthetic room's cost
    assert min(times[-20:]) > 1.1 * gov.budget_ms and gov.at_floor
    text = "\n".join(gov.explain(user))
    assert "Everything it can simplify is simplified" in text and "lower frame rate" in text
    fits, _, _ = run(user, 160)  # the usual room: within budget, no such line
    assert not fits.at_floor
    assert "Everything it can simplify" not in "\n".join(fits.explain(user))


# -- the render scale and its upscaler ----------------------------------------------------------
W, H = 320, 180


def edge_scene() -> Scene:
    """A bright square on a dark wall: sharp vertical and horizontal edges."""

    def quad(name, cx, cy, cz, half, material):
        pos = np.array(
            [
                [cx - half, cy - half, cz],
                [cx + half, cy - half, cz],
                [cx + half, cy + half, cz],
                [cx - half, cy + half, cz],
            ],
            np.float32,
        )
        uv = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], np.float32)
        n = np.tile([0, 0, 1], (4, 1)).astype(np.float32)
        return Mesh(name, pos, n, uv, np.array([[0, 1, 2], [0, 2, 3]], np.uint32), material)

    return Scene(
        "edges",
        [quad("wall", 0, 1.6, -3, 4.0, 0), quad("square", 0.2, 1.6, -2, 0.5, 1)],
        [
            Material("dark", (0.05, 0.05, 0.05, 1), 0, roughness=1.0),
            Material("bright", (0.9, 0.9, 0.9, 1), 0, roughness=1.0),
        ],
        [],
        [PointLight((0, 1.6, 0), (1, 1, 1), 30.0, 20.0)],
        Viewpoint((0, 1.6, 0)),
    ).sanitized()


@pytest.fixture(scope="module")
def host(edge_host):
    """The edge scene's host (tests/conftest.py ``edge_host``)."""
    return edge_host


def frame_of(host: OffscreenHost) -> FrameInput:
    cam = StereoCamera(host.settings.stereo)
    cam.set_pose((0, 1.6, 0), 0.0, 0.0)
    return FrameInput(cam.eyes(*host.eye_size), gaze=(-1, -1))


def draw(host: OffscreenHost, scale: float, upscaler: str = "edge") -> np.ndarray:
    host.settings.set("render.scale", scale)
    host.settings.set("render.upscaler", upscaler)
    img = host.draw(frame_of(host)).astype(np.float32)
    host.settings.set("render.scale", 1.0)
    host.settings.set("render.upscaler", "edge")
    return img


def edge_width(img: np.ndarray) -> float:
    """The blur of the left eye's vertical edges, in pixels per row: each pixel on a step
    (its neighbours 3 pixels away differ by more than 50 levels) counts by how far it is
    from both sides, 0 on either plateau and 0.5 half way (a perfectly sharp edge: 0)."""
    g = img[60:120, : W // 2, 1]
    a, b, mid = g[:, :-6], g[:, 6:], g[:, 3:-3]
    step = np.abs(b - a)
    share = np.minimum(np.abs(mid - a), np.abs(mid - b)) / np.maximum(step, 1.0)
    return float(np.where(step > 50, share, 0.0).sum(axis=1).mean() / 3.0)


def test_scaled_render_is_close_to_full_and_sharper_than_bilinear(host):
    full = draw(host, 1.0)
    easu = draw(host, 0.5)
    bilinear = draw(host, 0.5, "bilinear")
    assert host.renderer.targets[0].size == (80, 90)  # the eyes were drawn at half size
    assert full.shape == easu.shape == (H, W, 3)
    assert np.abs(easu - full).mean() < 4.0  # close to the full-scale picture
    assert edge_width(easu) < edge_width(bilinear)  # edges stay crisper than bilinear
    assert edge_width(full) < edge_width(easu) < 0.8 * edge_width(bilinear)


def test_object_ids_map_to_window_pixels_at_a_reduced_scale(host):
    host.settings.set("render.scale", 1.0)
    full_ids = host.object_ids(frame_of(host))
    draw(host, 0.5)
    host.settings.set("render.scale", 0.5)
    try:
        ids = host.object_ids(frame_of(host))
    finally:
        host.settings.set("render.scale", 1.0)
    assert ids[0].shape == (H, W // 2)
    assert np.array_equal(ids[0], full_ids[0]) and np.array_equal(ids[1], full_ids[1])
    assert {0, 1} <= set(np.unique(ids[0]).tolist())


def test_a_failing_governor_leaves_the_users_settings_and_the_picture(caplog):
    s = Settings()
    s.set("render.shadows", "off")
    s.set("render.target_fps", "240")
    with OffscreenHost(W, H, s) as h:
        h.set_scene(edge_scene())
        h.set_text_image(None)
        for _ in range(6):
            h.draw(frame_of(h))
        assert h.renderer.governor.overrides  # 4 ms a frame is too little: it lowered

        def broken(*args, **kwargs):
            raise KeyError("a step the model lost")

        h.renderer.governor.observe = broken  # type: ignore[method-assign]
        h.draw(frame_of(h))
        img = h.draw(frame_of(h))  # drawn, at the user's own settings
        assert h.renderer.governor.overrides == {}
        assert any("governor" in e for e in h.renderer.errors)
        assert img.max() > 0
    for r in caplog.records:
        if "governor" in r.getMessage():
            r.expected = True  # this test's own error


def test_auto_headless_is_fixed_settings_and_deterministic():
    s = Settings()
    s.set("render.shadows", "off")
    assert s.render.target_fps == "auto"
    shots = []
    for _ in range(2):
        with OffscreenHost(W, H, s) as h:
            h.set_scene(edge_scene())
            h.set_text_image(None)
            for _ in range(6):
                img = h.draw(frame_of(h))
            assert h.renderer.governor.overrides == {}
            assert h.renderer.targets[0].size == (W // 2, H)
            shots.append(img)
    assert np.array_equal(shots[0], shots[1])


def test_frame_rate_panel_shows_the_budget_in_words(qtbot):
    from ui.governor_panel import GovernorPanel

    user = walking("30")
    gov, _, _ = run(user, 20)
    panel = GovernorPanel(lambda: gov.explain(user))
    qtbot.addWidget(panel)
    assert panel.budget.text().startswith("Budget 33 ms a frame (30 fps)")
    assert "render scale" in panel.knobs.text() and "%" in panel.knobs.text()
    assert "over the 33 ms budget" in panel.knobs.text()

    def broken() -> list[str]:
        raise RuntimeError("no renderer")

    panel.lines = broken
    panel.refresh()  # a failing source shows a line, never raises out of the timer's slot
    assert "not available" in panel.budget.text()
    panel.lines = lambda: None  # a source that returns nothing usable: the same line
    panel.budget.setText("")
    qtbot.wait(600)  # the 4 Hz timer itself calls the slot (an escape would abort the process)
    assert "not available" in panel.budget.text() and panel._warned
    panel.lines = lambda: ["Budget 20 ms a frame (50 fps); frames take 12 ms."]
    qtbot.waitUntil(lambda: panel.budget.text().startswith("Budget 20 ms"), timeout=2000)
    assert panel.knobs.text() == ""


def test_the_governors_coarse_lighting_works_without_the_users_edge_rays(host):
    """CPS off in the user's settings: the host casts no edge rays, yet the governor's CPS
    lights the periphery in coarser blocks (the user's settings stay as set)."""
    host.renderer.governor.overrides = {"cps.mode": "cps", "cps.max_level": 3, "cps.fovea_deg": 3.5}
    cam = StereoCamera(host.settings.stereo)
    cam.set_pose((0, 1.6, 0), 0.0, 0.0)
    host.draw(FrameInput(cam.eyes(*host.eye_size), gaze=(0.5, 0.5)))
    share = host.cps_stats()["level_share"]
    assert host.settings.cps.mode == "none"
    assert sum(share[1:]) > 0.3  # most of the periphery in blocks
    host.renderer.governor.overrides = {}


# A real room's triangles in view per allowed error (the bathroom's, counted by the renderer):
# its simplified levels hold a tenth of them or less.
ROOM_TRIANGLES = {0.0: 372494, 1.0: 36967, 2.0: 33854, 3.0: 20381, 4.0: 14627, 6.0: 14585}
ROOM_TRIANGLES |= {8.0: 13974, 12.0: 13402, 16.0: 13148, 24.0: 11059}


def test_triangle_share_reads_the_count_at_the_error_a_step_allows():
    from app.governor_model import triangle_share

    assert triangle_share(ROOM_TRIANGLES, 0.0, 0.35) == 1.0  # the full level, at any scale
    assert triangle_share(ROOM_TRIANGLES, 2.0, 1.0) == 33854 / 372494
    # lod_bias 2 at render scale 0.5 allows 4 pixels of the view; 0.45 allows 4.4: still 4.
    assert triangle_share(ROOM_TRIANGLES, 2.0, 0.5) == triangle_share(ROOM_TRIANGLES, 2.0, 0.45)
    assert triangle_share(ROOM_TRIANGLES, 2.0, 0.5) == 14627 / 372494
    assert triangle_share({0.0: 0}, 8.0, 1.0) == 1.0  # nothing in view: no share to speak of
    few = {e: 2968 for e in ROOM_TRIANGLES}  # the showroom: every level is the full one
    low = {"render.lod_bias": 8, "render.scale": 1.0}
    assert cost_factors(low, few)["geometry"] == cost_factors({}, few)["geometry"]
    assert cost_factors(low, ROOM_TRIANGLES)["geometry"] < 0.5 * cost_factors({})["geometry"]


def test_a_room_whose_coarse_levels_hold_a_tenth_of_it_never_restores_the_full_level():
    """The bathroom at the floor of every knob: the full level draws ten times the triangles
    of the coarsest. Priced by the renderer's count, giving the full level back is seen to
    cost about what it does (the fixed shares call it under half of that): the frame rate
    holds."""
    from app.governor_model import VERTEX_SHARE, triangle_share

    def room(values):  # the truth: the vertex part follows the triangles drawn
        f = cost_factors(values, ROOM_TRIANGLES)
        s = float(values.get("render.scale", 1.0))
        share = triangle_share(ROOM_TRIANGLES, float(values.get("render.lod_bias", 0)), s)
        f["geometry"] = 0.75 * share + 0.25 * s * s
        return f

    assert VERTEX_SHARE != 0.75  # the model's shape is not the truth's
    user = walking("30")
    base = {**BASE, "gbuffer": 90.0}

    def walk(counted: bool) -> tuple[list[float], list[dict], float]:
        gov, overrides = Governor(), {}
        times, history = [], []
        for i in range(240):
            passes, ms = synthetic(user, overrides, 1.0, base, room)
            times.append(ms)
            triangles = ROOM_TRIANGLES if counted and i % 8 == 0 else None
            overrides = gov.observe(user, passes, ms, lod_triangles=triangles)
            history.append(dict(overrides))
        full = {**gov.position, "render.lod_bias": 0}  # the same knobs with the full level
        _, truth = synthetic(user, {**overrides, "render.lod_bias": 0.0}, 1.0, base, room)
        return times, history, gov.predict(user, full) / truth

    times, history, counted = walk(counted=True)
    budget = 1000.0 / 30.0
    assert max(times[40:]) < 1.1 * budget, max(times[40:])
    assert all(h.get("render.lod_bias", 0) > 0 for h in history[40:])
    _, _, fixed = walk(counted=False)
    assert 0.65 < counted < 1.25 and fixed < 0.5, (counted, fixed)


def test_frames_that_vary_are_held_within_budget_by_aiming_lower():
    """A machine whose frames vary (one in six is a third slower: other work on the cores):
    aiming at the budget itself, the slow frames pass it by more than 10 %; the governor aims
    lower by the spread it measures, so 19 frames in 20 stay within. A steady frame rate
    keeps the budget itself as its aim."""
    user = walking("30")
    budget = 1000.0 / 30.0

    def walk(measure_spread: bool) -> tuple[Governor, list[float]]:
        rng = np.random.default_rng(0)
        gov, overrides, times = Governor(), {}, []
        aims.clear()
        if not measure_spread:
            gov.spread = lambda: 1.0  # type: ignore[method-assign]
        for _ in range(400):
            passes, ms = synthetic(user, overrides, 1.0)
            slow = 1.33 if rng.random() < 1 / 6 else 1.0
            jitter = slow * (1.0 + 0.03 * rng.standard_normal())
            passes = {k: v * jitter for k, v in passes.items()}
            times.append(ms * jitter)
            overrides = gov.observe(user, passes, ms * jitter)
            aims.append(gov.aim_ms())
        return gov, times

    def over(times: list[float]) -> float:
        return float(np.mean(np.asarray(times[100:]) > 1.1 * budget))

    aims: list[float] = []
    gov, times = walk(measure_spread=True)
    assert 0.75 * budget < np.mean(aims[100:]) < 0.9 * budget, np.mean(aims[100:])
    assert any("aiming at" in line for line in gov.explain(user))
    _, at_budget = walk(measure_spread=False)
    assert over(times) <= 0.05 < over(at_budget), (over(times), over(at_budget))
    steady, _, _ = run(user, 200)
    assert steady.spread() < 1.05 and steady.aim_ms() == pytest.approx(budget)


def test_frames_the_host_slowed_are_not_counted_in_the_spread():
    """The benchmark's full-quality reference slows the frame after it (every third frame a
    third slower): told so (``skip_next``), the governor keeps the budget as its aim and
    learns the steady cost; not told, it aims lower for frames the walk will not have."""
    user = walking("30")
    budget = 1000.0 / 30.0

    def walk(told: bool) -> Governor:
        gov, overrides = Governor(), {}
        for i in range(200):
            passes, ms = synthetic(user, overrides, 1.0)
            slow = 1.33 if i % 3 == 1 else 1.0
            overrides = gov.observe(user, {k: v * slow for k, v in passes.items()}, ms * slow)
            if told and i % 3 == 0:
                gov.skip_next()
        return gov

    told, not_told = walk(True), walk(False)
    assert told.spread() < 1.05 and told.aim_ms() == pytest.approx(budget)
    assert not_told.aim_ms() < 0.9 * budget, not_told.aim_ms()
    assert told.ema_ms is not None and told.ema_ms <= budget


def test_shadows_go_hard_then_off_and_never_back_up_from_the_users_choice():
    from app.governor import KNOBS

    knob = next(k for k in KNOBS if k.key == "render.shadows")
    user = walking("30")
    assert [s["render.shadows"] for s in knob.usable_steps(user)] == ["hard", "off"]
    user.set("render.shadows", "hard")
    assert [s["render.shadows"] for s in knob.usable_steps(user)] == ["off"]
    user.set("render.shadows", "off")
    assert knob.usable_steps(user) == []
    off = cost_factors({"render.shadows": "off"})
    assert off["shadow_mask"] == 0.0 and off["shadows"] == 0.0
    assert cost_factors({"render.shadows": "hard"})["shadow_mask"] > 0.0
    # The last resort: dearer in quality than any other step of the knobs that may go first.
    assert knob.error[-1] > max(e for k in KNOBS if not k.fovea and k is not knob for e in k.error)


def test_no_shadows_is_the_last_step_taken_and_the_first_given_back():
    user = walking("30")
    gov, _, _ = run(user, 40, load=lambda i: 6.0)  # far too slow for anything but everything
    lowered = [(d.knob, d.value) for d in gov.history if d.action == "lower"]
    fovea = {"sharp area around the gaze", "detail falloff"}
    off = lowered.index(("shadows", "off"))
    assert all(k in fovea for k, _ in lowered[off + 1 :])  # only the fovea's knobs after it
    assert len([k for k, _ in lowered[:off] if k not in fovea]) >= 8  # everything else first
    run(user, 120, load=lambda i: 0.3, gov=gov)
    restored = [(d.knob, d.value) for d in gov.history if d.action == "restore"]
    first_other = next(r for r in restored if r[0] not in fovea)
    assert first_other == ("shadows", "hard")


# -- the knobs' programs, compiled before the governor turns to them ----------------------------
def lit_scene() -> Scene:
    """The edge scene with its lamp casting shadows (the shadow modes are programs)."""
    scene = edge_scene()
    assert any(light.casts_shadows for light in scene.lights)
    return scene


def test_the_knobs_programs_are_compiled_before_a_walk_needs_them():
    s = Settings()
    s.set("render.target_fps", "30")  # the governor on: its knobs may change the programs
    s.set("render.refine", "on")  # and standing still refines at full quality
    with OffscreenHost(W, H, s) as h:
        h.set_scene(lit_scene())
        h.set_text_image(None)
        for _ in range(2):
            h.draw(frame_of(h))
        reachable = h.renderer.governor.program_variants(h.settings)
        # Every pair of shadow mode and coarse lighting the knobs reach, besides the user's.
        pairs = {(o.get("render.shadows", "soft"), o.get("cps.mode", "none")) for o in reachable}
        assert pairs == {(m, c) for m in ("soft", "hard", "off") for c in ("none", "cps")} - {
            ("soft", "none")
        }
        assert any(o.get("render.scale", 1.0) < 1.0 for o in reachable)
        assert any(o.get("render.upscaler") == "bilinear" for o in reachable)
        for _ in range(len(reachable) + 2):  # one a frame in the window
            h.draw(frame_of(h))
        compiled = len(h.renderer.shaders)
        still = dataclasses.replace(frame_of(h), refining=True, sample=0, refine_target=16)
        h.draw(still)
        assert len(h.renderer.shaders) == compiled, "the first refining frame compiled"
        for key, value in [
            ("render.shadows", "hard"),
            ("cps.mode", "cps"),
            ("render.shadows", "off"),
            ("render.scale", 0.85),
            ("render.upscaler", "bilinear"),
        ]:
            h.settings.set(key, value)
            h.renderer.governor = type(h.renderer.governor)()  # fixed: the user's values drawn
            h.settings.set("render.target_fps", "0")
            h.draw(frame_of(h))
            assert len(h.renderer.shaders) == compiled, f"{key}={value} compiled a program"
        assert not h.renderer.errors


def test_without_the_warm_up_a_knobs_first_frame_compiles():
    s = Settings()
    s.set("render.target_fps", "0")  # fixed settings: nothing to warm
    with OffscreenHost(W, H, s) as h:
        h.set_scene(lit_scene())
        h.set_text_image(None)
        for _ in range(3):
            h.draw(frame_of(h))
        compiled = len(h.renderer.shaders)
        h.settings.set("render.shadows", "hard")
        h.draw(frame_of(h))
        assert len(h.renderer.shaders) > compiled


def test_warm_frames_leave_the_next_picture_and_the_renderers_state_as_they_were():
    s = Settings()
    s.set("render.target_fps", "0")
    s.set("render.exposure_mode", "auto")  # adapting: a warm frame must not step it
    shots, states = [], []
    for warm in (False, True):
        with OffscreenHost(W, H, s) as h:
            h.set_scene(lit_scene())
            h.set_text_image(None)
            for i in range(4):
                if warm and i == 2:
                    with h.ctx:
                        assert h.renderer.warm_variants(frame_of(h), None) == 0
                    assert len(h.renderer._warmed) > 3
                img = h.draw(frame_of(h))
            shots.append(img)
            r = h.renderer
            states.append((r.frames, r.exposure_readout(), r.shadows.renders))
            assert not r.errors
    assert states[0] == states[1]
    assert np.array_equal(shots[0], shots[1])
