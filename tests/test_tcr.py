"""TCR adaptive texture mapping (SPEC B): the level formula, its fallbacks, pyramids, states."""

from __future__ import annotations

import itertools
import math
import re
import sys
import warnings

import numpy as np
import pytest
from hypothesis import example, given
from hypothesis import settings as hsettings
from hypothesis import strategies as st

from app.settings import TcrSettings
from app.tcr import (
    FAR_LEVEL,
    PRESETS,
    LevelReason,
    MotionStateMachine,
    TcrController,
    TcrTerms,
    brightness_term,
    build_pyramid,
    distance_term,
    finest_per_texture,
    level_bytes,
    level_for,
    phase_name,
    pyramid_sizes,
    terms_from_settings,
)

D_ONLY = TcrTerms(d=True, v=False, g=False, l=False)
L_ONLY = TcrTerms(d=False, v=False, g=False, l=True)
ALL = TcrTerms()
SWEEP = hsettings(derandomize=True, database=None, max_examples=400, deadline=None)
TINY = 5e-324  # the smallest denormal
EXTREMES = [
    math.nan,
    math.inf,
    -math.inf,
    0.0,
    -0.0,
    TINY,
    -TINY,
    2.2250738585072014e-308,
    1e-300,
    1e30,
    -1e30,
    sys.float_info.max,
    -sys.float_info.max,
    1.0,
    -1.0,
]


def _level(
    distance: float,
    f: float = 1.0,
    n: int = 20,
    *,
    moving: bool = False,
    gazed_fixed: bool = False,
    brightness: float = 1.0,
    terms: TcrTerms = D_ONLY,
) -> int:
    return level_for(
        distance, f, n, moving=moving, gazed_fixed=gazed_fixed, brightness=brightness, terms=terms
    ).level


# -- the formula ------------------------------------------------------------------------------


@pytest.mark.parametrize("f", [1.0, 0.25, 0.1, 0.7, 3.0])
@pytest.mark.parametrize(
    ("times_f", "expected"),
    [
        (0.5, 0),
        (1.0, 0),
        ("2f-", 0),
        (2.0, 1),
        (3.0, 1),
        ("4f-", 1),
        (4.0, 2),
        (8.0, 3),
        (1000.0, 9),
        (1024.0, 10),
    ],
)
def test_distance_table(f: float, times_f: float | str, expected: int) -> None:
    # j = floor(log2(distance / f)), exactly: a distance just short of 2f is still level 0.
    if isinstance(times_f, str):
        distance = math.nextafter(float(times_f[0]) * f, 0.0)
    else:
        distance = times_f * f
    assert distance_term(distance, f) == expected
    assert _level(distance, f) == expected


def test_distance_clamped_to_n() -> None:
    assert _level(1000.0, 1.0, n=9) == 9
    assert _level(1e6, 1.0, n=9) == 9
    assert _level(1000.0, 1.0, n=0) == 0  # a 1x1 texture has only level 0
    assert _level(1000.0, 1.0, n=-3) == 0  # negative n is treated as 0
    reason = level_for(1e6, 1.0, 9, moving=True, gazed_fixed=False, brightness=0.5, terms=ALL)
    assert (reason.raw, reason.level, reason.n) == (19 + 1 + 1, 9, 9)
    # The gaze term cannot push a level below 0.
    reason = level_for(0.5, 1.0, 9, moving=False, gazed_fixed=True, brightness=1.0, terms=ALL)
    assert (reason.raw, reason.level) == (-1, 0)


@pytest.mark.parametrize(
    "terms", [TcrTerms(*flags) for flags in itertools.product([False, True], repeat=4)]
)
def test_each_term_on_and_off(terms: TcrTerms) -> None:
    # distance 4f -> 2, moving -> +1, gazed and fixed -> -1, brightness 1/4 -> +2.
    r = level_for(4.0, 1.0, 20, moving=True, gazed_fixed=True, brightness=0.25, terms=terms)
    assert r.distance == (2 if terms.d else 0)
    assert r.v == (1 if terms.v else 0)
    assert r.g == (-1 if terms.g else 0)
    assert r.l == (2 if terms.l else 0)
    assert r.raw == r.distance + r.v + r.g + r.l
    assert r.level == max(0, r.raw)
    # With the viewpoint still and the gaze elsewhere, v and g contribute nothing even when on.
    r = level_for(4.0, 1.0, 20, moving=False, gazed_fixed=False, brightness=0.25, terms=terms)
    assert (r.v, r.g) == (0, 0)


def test_presets_and_phase_names() -> None:
    assert PRESETS["psychology"] == TcrTerms(d=True, v=False, g=True, l=True)
    assert PRESETS["ergonomics"] == TcrTerms(d=True, v=True, g=False, l=True)
    assert phase_name(PRESETS["psychology"]) == "psychology"
    assert phase_name(PRESETS["ergonomics"]) == "ergonomics"
    assert phase_name(TcrTerms()) == "custom"
    assert phase_name(TcrTerms(d=False, v=True, g=False, l=True)) == "custom"

    s = TcrSettings(preset="psychology", use_v=True, use_g=False)  # the flags are ignored
    assert terms_from_settings(s) == PRESETS["psychology"]
    s = TcrSettings(preset="ergonomics", use_v=False, use_g=True)
    assert terms_from_settings(s) == PRESETS["ergonomics"]
    s = TcrSettings(preset="custom", use_d=False, use_v=True, use_g=True, use_l=False)
    assert terms_from_settings(s) == TcrTerms(d=False, v=True, g=True, l=False)
    assert phase_name(terms_from_settings(s)) == "custom"
    # Custom flags that equal a preset name that preset.
    s = TcrSettings(preset="custom", use_d=True, use_v=False, use_g=True, use_l=True)
    assert phase_name(terms_from_settings(s)) == "psychology"


def test_brightness_term() -> None:
    assert brightness_term(1.0) == 0
    assert brightness_term(4.0) == 0  # brighter than the reference never sharpens
    assert brightness_term(0.75) == 0
    assert brightness_term(0.5) == 1
    assert brightness_term(math.nextafter(0.5, 1.0)) == 0
    assert brightness_term(0.25) == 2
    assert brightness_term(1.0 / 1024) == 10
    assert brightness_term(2.0, reference=8.0) == 2


@pytest.mark.parametrize(
    ("distance", "f", "brightness", "expected"),
    [
        (math.nan, 1.0, 1.0, 0),  # broken geometry: show quality
        (0.0, 1.0, 1.0, 0),
        (-0.0, 1.0, 1.0, 0),
        (-5.0, 1.0, 1.0, 0),
        (-math.inf, 1.0, 1.0, 0),
        (math.inf, 1.0, 1.0, 9),  # infinitely far: coarsest
        (1e30, 1.0, 1.0, 9),
        (TINY, 1.0, 1.0, 0),
        (2.0, 0.0, 1.0, 9),  # f = 0, negative or NaN: f = 1e-6, so anything beyond is coarse
        (2.0, -1.0, 1.0, 9),
        (2.0, math.nan, 1.0, 9),
        (1.5e-6, math.nan, 1.0, 0),
        (2.0, TINY, 1.0, 9),
        (1e300, math.inf, 1.0, 0),  # f = inf: every finite distance is level 0
        (math.inf, math.inf, 1.0, 9),
        (1.0, 1.0, 0.0, 9),  # no light at all: coarsest
        (1.0, 1.0, -1.0, 9),
        (1.0, 1.0, TINY, 9),
        (1.0, 1.0, math.nan, 0),  # unknown light: quality
        (1.0, 1.0, math.inf, 0),
        (1.0, 1.0, -math.inf, 9),
    ],
)
def test_documented_fallbacks(distance: float, f: float, brightness: float, expected: int) -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert _level(distance, f, 9, brightness=brightness, terms=ALL) == expected


def test_far_level_and_invalid_reference() -> None:
    assert distance_term(math.inf, 1.0) == FAR_LEVEL
    assert brightness_term(0.0) == FAR_LEVEL
    for bad in (math.nan, math.inf, 0.0, -2.0):
        assert brightness_term(0.5, reference=bad) == 1  # falls back to reference 1.0


any_float = st.floats()  # includes nan, +-inf, +-0.0 and denormals


@SWEEP
@given(
    distance=any_float,
    f=any_float,
    brightness=any_float,
    n=st.integers(-3, 20),
    moving=st.booleans(),
    gazed=st.booleans(),
    reference=any_float,
)
@example(
    distance=math.nan,
    f=math.nan,
    brightness=math.nan,
    n=0,
    moving=True,
    gazed=True,
    reference=math.nan,
)
@example(
    distance=1e30,
    f=TINY,
    brightness=TINY,
    n=20,
    moving=True,
    gazed=False,
    reference=sys.float_info.max,
)
@example(
    distance=sys.float_info.max,
    f=TINY,
    brightness=-0.0,
    n=-3,
    moving=False,
    gazed=True,
    reference=TINY,
)
@example(
    distance=-0.0, f=-0.0, brightness=-math.inf, n=5, moving=False, gazed=True, reference=-math.inf
)
def test_level_always_defined(
    distance: float,
    f: float,
    brightness: float,
    n: int,
    moving: bool,
    gazed: bool,
    reference: float,
) -> None:
    with warnings.catch_warnings(), np.errstate(all="raise"):
        warnings.simplefilter("error")
        for terms in (ALL, D_ONLY, PRESETS["psychology"], PRESETS["ergonomics"]):
            r = level_for(
                distance,
                f,
                n,
                moving=moving,
                gazed_fixed=gazed,
                brightness=brightness,
                terms=terms,
                reference_brightness=reference,
            )
            assert type(r.level) is int
            assert 0 <= r.level <= max(n, 0)
            assert r.n == max(n, 0)
            assert all(type(x) is int for x in (r.distance, r.v, r.g, r.l, r.raw))


def test_level_defined_on_extreme_grid() -> None:
    # Every combination of the awkward values, on top of the random sweep above.
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        for distance, f, brightness, n in itertools.product(
            EXTREMES, EXTREMES, EXTREMES, (-1, 0, 9)
        ):
            level = _level(
                distance, f, n, moving=True, gazed_fixed=True, brightness=brightness, terms=ALL
            )
            assert type(level) is int and 0 <= level <= max(n, 0), (distance, f, brightness, n)


@SWEEP
@given(
    a=st.floats(allow_nan=False),
    b=st.floats(allow_nan=False),
    f=any_float,
    n=st.integers(-3, 20),
    moving=st.booleans(),
    gazed=st.booleans(),
)
def test_level_monotonic_in_distance(
    a: float, b: float, f: float, n: int, moving: bool, gazed: bool
) -> None:
    near, far = min(a, b), max(a, b)
    for terms in (ALL, D_ONLY):
        kw = {"moving": moving, "gazed_fixed": gazed, "brightness": 0.3, "terms": terms}
        assert _level(near, f, n, **kw) <= _level(far, f, n, **kw)


@SWEEP
@given(
    brightness=st.floats(min_value=4 * 2.2250738585072014e-308, max_value=1.0),
    distance=st.floats(allow_nan=False),
    n=st.integers(0, 20),
)
def test_halving_brightness_adds_one_level(brightness: float, distance: float, n: int) -> None:
    for terms in (L_ONLY, ALL):
        kw = {"moving": False, "gazed_fixed": False, "terms": terms}
        before = _level(distance, 1.0, n, brightness=brightness, **kw)
        after = _level(distance, 1.0, n, brightness=brightness / 2, **kw)
        unclamped = level_for(distance, 1.0, n, brightness=brightness, **kw).raw
        assert after == min(n, max(0, unclamped + 1))
        assert after >= before
    assert brightness_term(brightness / 2) == brightness_term(brightness) + 1


def test_describe_format() -> None:
    r = LevelReason(distance=3, v=1, g=0, l=0, raw=4, level=4, n=9)
    assert r.describe("sofa") == "sofa: level 4 = distance 3 + v 1 - g 0 + l 0, clamped to [0, 9]"
    r = level_for(1e6, 1.0, 9, moving=True, gazed_fixed=True, brightness=0.5, terms=ALL)
    assert r.describe("wall") == (
        "wall: level 9 = distance 19 + v 1 - g 1 + l 1, clamped to [0, 9]"
    )


# -- pyramids ---------------------------------------------------------------------------------


def _linear_mean(level: np.ndarray) -> np.ndarray:
    c = level.astype(np.float64) / 255.0
    rgb = np.where(c[..., :3] <= 0.04045, c[..., :3] / 12.92, ((c[..., :3] + 0.055) / 1.055) ** 2.4)
    return np.concatenate([rgb.mean(axis=(0, 1)), c[..., 3:].mean(axis=(0, 1))])


def test_pyramid_sizes() -> None:
    sizes = pyramid_sizes(512, 512)
    assert len(sizes) == 10 and sizes[0] == (512, 512) and sizes[-1] == (1, 1)
    assert pyramid_sizes(640, 480) == [
        (640, 480),
        (320, 240),
        (160, 120),
        (80, 60),
        (40, 30),
        (20, 15),
        (10, 7),
        (5, 3),
        (2, 1),
        (1, 1),
    ]
    assert pyramid_sizes(1, 1) == [(1, 1)]
    assert pyramid_sizes(1, 7) == [(1, 7), (1, 3), (1, 1)]
    assert pyramid_sizes(5, 3) == [(5, 3), (2, 1), (1, 1)]
    for w, h in [(512, 512), (640, 480), (1, 1), (1, 7), (5, 3), (1000, 3)]:
        assert len(pyramid_sizes(w, h)) - 1 == math.floor(math.log2(max(w, h)))
    with pytest.raises(ValueError):
        pyramid_sizes(0, 4)


@pytest.mark.parametrize(
    ("h", "w"), [(512, 512), (480, 640), (1, 1), (1, 7), (7, 1), (3, 5), (5, 3), (2, 9), (33, 17)]
)
def test_pyramid_preserves_linear_mean(h: int, w: int) -> None:
    rng = np.random.default_rng(h * 1000 + w)
    rgba = rng.integers(0, 256, (h, w, 4), dtype=np.uint8)
    levels = build_pyramid(rgba)
    assert [(lv.shape[1], lv.shape[0]) for lv in levels] == pyramid_sizes(w, h)
    assert all(lv.dtype == np.uint8 and lv.shape[2] == 4 for lv in levels)
    assert np.array_equal(levels[0], rgba)
    mean0 = _linear_mean(rgba)
    for lv in levels[1:]:
        np.testing.assert_allclose(_linear_mean(lv), mean0, atol=1 / 255)


def test_pyramid_averages_in_linear_light() -> None:
    checker = np.zeros((2, 2, 4), np.uint8)
    checker[..., 3] = 255
    checker[0, 0, :3] = checker[1, 1, :3] = 255
    top = build_pyramid(checker)[1]
    assert top.shape == (1, 1, 4)
    assert abs(int(top[0, 0, 0]) - 188) <= 1 and top[0, 0, 3] == 255  # linear 0.5, not 128
    np.testing.assert_allclose(_linear_mean(top)[:3], 0.5, atol=1 / 255)
    # Alpha is averaged as stored.
    alpha = np.full((2, 2, 4), 255, np.uint8)
    alpha[0, :, 3] = 0
    assert abs(int(build_pyramid(alpha)[1][0, 0, 3]) - 128) <= 1


def test_pyramid_even_step_is_the_2x2_average() -> None:
    rng = np.random.default_rng(7)
    rgba = rng.integers(0, 256, (8, 4, 4), dtype=np.uint8)
    lin = _linear_mean(rgba[0:2, 0:2])  # the top-left output texel's expected linear value
    np.testing.assert_allclose(_linear_mean(build_pyramid(rgba)[1][0:1, 0:1]), lin, atol=1 / 255)
    # Row 0 stays the top: a texture white on top, black below keeps that order.
    split = np.zeros((4, 4, 4), np.uint8)
    split[:2] = 255
    level1 = build_pyramid(split)[1]
    assert level1[0, 0, 0] == 255 and level1[1, 0, 0] == 0


def test_pyramid_rejects_non_rgba8() -> None:
    with pytest.raises(ValueError):
        build_pyramid(np.zeros((4, 4, 3), np.uint8))
    with pytest.raises(ValueError):
        build_pyramid(np.zeros((4, 4, 4), np.float32))
    with pytest.raises(ValueError):
        build_pyramid(np.zeros((0, 4, 4), np.uint8))


def test_level_bytes() -> None:
    sizes = level_bytes(512, 512)
    assert sizes[0] == 512 * 512 * 4 and sizes[-1] == 4 and len(sizes) == 10
    assert abs(sum(sizes) - 4 / 3 * 512 * 512 * 4) <= 4
    assert level_bytes(5, 3, 1) == [15, 2, 1]


# -- the state machine ------------------------------------------------------------------------

DT = 1.0 / 60.0


def test_noisy_speed_around_the_thresholds_does_not_flicker() -> None:
    rng = np.random.default_rng(1996)
    sm = MotionStateMachine(move_on=0.15, move_off=0.05, window_s=0.15)
    speeds = 0.10 + rng.uniform(-0.06, 0.06, size=600)  # crosses both thresholds, 10 s at 60 Hz
    assert (speeds > 0.15).any() and (speeds < 0.05).any()
    for s in speeds:
        sm.update(DT, float(s), False)
    assert sm.transitions <= 1


def _frames_until_change(sm: MotionStateMachine, speed: float, limit: int = 600) -> int:
    start = sm.viewpoint_moving
    for frame in range(1, limit + 1):
        sm.update(DT, speed, False)
        if sm.viewpoint_moving != start:
            return frame
    raise AssertionError("state never changed")


@pytest.mark.parametrize("window", [0.15, 0.0, 0.5, 0.01])
def test_clean_step_changes_after_the_window(window: float) -> None:
    sm = MotionStateMachine(window_s=window)
    for _ in range(30):
        assert sm.update(DT, 0.0, False) == 0
    frames = _frames_until_change(sm, 1.0)  # the speed was 1 m/s for frames * DT seconds
    assert window - 1e-9 <= frames * DT < window + DT + 1e-9
    assert sm.viewpoint_moving and sm.state == 1
    frames = _frames_until_change(sm, 0.0)
    assert window - 1e-9 <= frames * DT < window + DT + 1e-9
    assert not sm.viewpoint_moving and sm.state == 0
    assert sm.transitions == 2


def test_step_not_moving_before_the_window() -> None:
    sm = MotionStateMachine(window_s=0.15)
    for _ in range(8):  # 8 / 60 s < 0.15 s
        sm.update(DT, 1.0, False)
    assert not sm.viewpoint_moving
    sm.update(DT, 0.0, False)  # one slow frame restarts the window
    for _ in range(8):
        sm.update(DT, 1.0, False)
    assert not sm.viewpoint_moving
    sm.update(DT, 1.0, False)
    assert sm.viewpoint_moving


def test_gaze_fixed_applies_at_once_and_all_states_are_reachable() -> None:
    sm = MotionStateMachine()
    seen = {sm.state}
    assert sm.update(DT, 0.0, True) == 2
    seen.add(sm.state)
    assert sm.update(DT, 0.0, False) == 0
    for _ in range(20):
        seen.add(sm.update(DT, 1.0, False))
    assert sm.state == 1
    assert sm.update(DT, 1.0, True) == 3
    seen.add(sm.state)
    assert seen == {0, 1, 2, 3}
    assert (sm.viewpoint_moving, sm.gaze_fixed) == (True, True)


@pytest.mark.parametrize(
    ("dt", "speed"),
    [
        (math.nan, 1.0),
        (math.inf, 1.0),
        (-math.inf, 1.0),
        (-1.0, 1.0),
        (DT, math.nan),
        (DT, math.inf),
        (DT, -math.inf),
        (math.nan, math.nan),
    ],
)
def test_bad_samples_do_not_change_the_state(dt: float, speed: float) -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        still = MotionStateMachine()
        for _ in range(100):
            assert still.update(dt, speed, False) == 0
        moving = MotionStateMachine()
        for _ in range(20):
            moving.update(DT, 1.0, False)
        for _ in range(100):
            assert moving.update(dt, 0.0 if math.isfinite(speed) else speed, False) == 1
        assert still.transitions == 0 and moving.transitions == 1
        # Half-way through a window, bad samples neither complete nor reset it.
        sm = MotionStateMachine(window_s=0.15)
        for _ in range(5):
            sm.update(DT, 1.0, False)
        for _ in range(50):
            sm.update(dt, speed, False)
        assert not sm.viewpoint_moving
        for _ in range(4):
            sm.update(DT, 1.0, False)
        assert sm.viewpoint_moving


def test_state_machine_parameters() -> None:
    sm = MotionStateMachine(move_on=math.nan, move_off=-1.0, window_s=math.inf)
    assert (sm.move_on, sm.move_off, sm.window_s) == (0.15, 0.05, 0.15)
    sm = MotionStateMachine(move_on=0.05, move_off=0.15)  # swapped: ordered, still hysteresis
    assert (sm.move_on, sm.move_off) == (0.15, 0.05)
    for _ in range(100):
        sm.update(DT, 0.1, False)
    assert sm.transitions == 0
    for _ in range(20):
        sm.update(DT, -1.0, False)  # a signed speed counts by its magnitude
    assert sm.viewpoint_moving


# -- the per-scene controller -----------------------------------------------------------------


def _controller() -> TcrController:
    lo = np.array(
        [[-0.5, -0.5, -5.0], [-0.5, -0.5, -101.0], [-1.0, -1.0, -1.0], [-0.5, -0.5, -17.0]]
    )
    hi = np.array([[0.5, 0.5, -4.0], [0.5, 0.5, -100.0], [1.0, 1.0, 1.0], [0.5, 0.5, -16.0]])
    return TcrController(lo, hi, [9, 9, 9, 0], ["near", "far", "around", "plain"])


EYE = np.zeros(3)


def test_controller_far_is_coarser_than_near() -> None:
    c = _controller()
    levels = c.update(EYE, None, False, False, 1.0, TcrSettings(enabled=True))
    assert levels.dtype == np.int32
    assert levels.tolist() == [2, 6, 0, 0]  # 4 m -> 2, 100 m -> 6, inside -> 0, n = 0 -> 0
    assert levels[1] > levels[0]
    np.testing.assert_allclose(c.distances, [4.0, 100.0, 0.0, 16.0])
    assert [r.level for r in c.reasons] == levels.tolist()


def test_controller_gaze_with_psychology_only() -> None:
    c = _controller()
    psychology = TcrSettings(enabled=True, preset="psychology")
    base = c.update(EYE, 0, False, False, 1.0, psychology)
    fixed = c.update(EYE, 0, False, True, 1.0, psychology)
    assert fixed[0] == base[0] - 1
    assert np.array_equal(fixed[1:], base[1:])
    assert c.reasons[0].g == -1 and c.reasons[1].g == 0
    # Moving does not matter to psychology (v off).
    assert np.array_equal(c.update(EYE, 0, True, True, 1.0, psychology), fixed)

    ergonomics = TcrSettings(enabled=True, preset="ergonomics")
    base = c.update(EYE, 0, False, False, 1.0, ergonomics)
    assert np.array_equal(c.update(EYE, 0, False, True, 1.0, ergonomics), base)
    moving = c.update(EYE, 0, True, True, 1.0, ergonomics)
    assert moving.tolist() == [3, 7, 1, 0]  # +1 everywhere, clamped to n = 0 on "plain"
    # A gazed index that is out of range or None gazes at nothing.
    for gazed in (None, -1, 99):
        assert np.array_equal(
            c.update(EYE, gazed, False, True, 1.0, psychology),
            c.update(EYE, None, False, False, 1.0, psychology),
        )


def test_controller_brightness_and_disabled() -> None:
    c = _controller()
    on = TcrSettings(enabled=True)
    assert c.update(EYE, None, False, False, 0.25, on).tolist() == [4, 8, 2, 0]
    off = TcrSettings(enabled=False)
    assert c.update(EYE, 0, True, True, 0.0, off).tolist() == [0, 0, 0, 0]
    assert all(r.level == 0 and r.raw == 0 for r in c.reasons)


def test_controller_describe() -> None:
    c = _controller()
    c.update(EYE, 1, True, True, 0.5, TcrSettings(enabled=True, preset="custom", use_g=True))
    pattern = re.compile(
        r"^\w+: level \d+ = distance \d+ \+ v [01] - g [01] \+ l \d+, "
        r"clamped to \[0, \d+\]$"
    )
    lines = [r.describe(name) for r, name in zip(c.reasons, c.names)]
    assert all(pattern.match(line) for line in lines), lines
    assert lines[1] == "far: level 7 = distance 6 + v 1 - g 1 + l 1, clamped to [0, 9]"


@pytest.mark.parametrize(
    "eye",
    [
        [math.nan, 0, 0],
        [math.inf, 0, 0],
        [-math.inf, 1e308, 0],
        [1e308, -1e308, 1e308],
        [TINY, -0.0, 0],
    ],
)
def test_controller_extreme_eye(eye: list[float]) -> None:
    c = _controller()
    with warnings.catch_warnings(), np.errstate(all="raise"):
        warnings.simplefilter("error")
        levels = c.update(
            np.array(eye, np.float64), 0, True, True, math.nan, TcrSettings(enabled=True)
        )
    assert levels.dtype == np.int32
    assert all(0 <= lv <= n for lv, n in zip(levels.tolist(), c.n_levels))


def test_controller_broken_boxes() -> None:
    lo = np.array([[math.nan, 0, 0], [1.0, 1.0, 1.0], [-1e308, -1e308, -1e308]])
    hi = np.array([[1.0, 1.0, 1.0], [-1.0, -1.0, -1.0], [1e308, 1e308, 1e308]])  # 2nd: lo > hi
    c = TcrController(lo, hi, [5, 5, -2], ["nan", "swapped", "huge"])
    with warnings.catch_warnings(), np.errstate(all="raise"):
        warnings.simplefilter("error")
        levels = c.update(
            np.array([0.0, 0.0, 3.0]), None, False, False, 1.0, TcrSettings(enabled=True)
        )
    assert levels.tolist() == [0, 1, 0]  # NaN box -> finest; swapped box is 2 m away
    with pytest.raises(ValueError):
        TcrController(np.zeros((2, 3)), np.zeros((2, 3)), [1], ["a", "b"])
    empty = TcrController(np.zeros((0, 3)), np.zeros((0, 3)), [], [])
    assert empty.update(EYE, None, False, False, 1.0, TcrSettings(enabled=True)).shape == (0,)


def test_finest_per_texture() -> None:
    c = _controller()
    c.update(EYE, None, False, False, 1.0, TcrSettings(enabled=True))
    assert c.levels.tolist() == [2, 6, 0, 0]
    assert finest_per_texture(c.levels, [0, 0, None, 1], 3) == [2, 0, -1]
    assert finest_per_texture(c.levels, [1, 0, 5, -1], 2) == [6, 2]  # out-of-range skipped
    assert finest_per_texture(c.levels, [None] * 4, 2) == [-1, -1]
    assert finest_per_texture(c.levels, [0, 0, 0, 0], 0) == []
    assert finest_per_texture([-3, 4], [0, 0], 1) == [0]  # a negative level counts as finest
    assert finest_per_texture([1], [0, 0, 0], 1) == [1]  # objects beyond the levels skipped


@hsettings(derandomize=True, database=None, max_examples=200, deadline=None)
@given(
    distances=st.lists(
        st.one_of(
            st.floats(allow_nan=True, allow_infinity=True),
            st.floats(min_value=1e-9, max_value=1e4),
        ),
        min_size=1,
        max_size=12,
    ),
    f_m=st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.floats(0.01, 2.0)),
    moving=st.booleans(),
    fixed=st.booleans(),
    gazed=st.integers(-2, 13),
    brightness=st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.floats(0.01, 4.0)),
    preset=st.sampled_from(["custom", "ergonomics", "psychology"]),
    flags=st.tuples(st.booleans(), st.booleans(), st.booleans(), st.booleans()),
    bias=st.integers(0, 2),
)
def test_controller_levels_are_level_for_of_each_object(
    distances, f_m, moving, fixed, gazed, brightness, preset, flags, bias
) -> None:
    """The controller works out every object's level at once (one LevelReason per object a
    frame cost 2.5 ms in an 850-object room); each level and reason is level_for's."""
    n = len(distances)
    c = TcrController(np.zeros((n, 3)), np.zeros((n, 3)), [3 * i % 11 for i in range(n)], [""] * n)
    c.box_distances = lambda eye: np.array(distances, np.float64)  # type: ignore[method-assign]
    d, v, g, ll = flags
    s = TcrSettings(enabled=True, preset=preset, use_d=d, use_v=v, use_g=g, use_l=ll)
    s.f_m, s.level_bias = f_m, bias
    levels = c.update(EYE, gazed, moving, fixed, brightness, s)
    terms = terms_from_settings(s)
    target = gazed if fixed and 0 <= gazed < n else -1
    want = [
        level_for(
            x,
            f_m,
            c.n_levels[i],
            moving=moving,
            gazed_fixed=i == target,
            brightness=brightness,
            terms=terms,
            bias=bias,
        )
        for i, x in enumerate(distances)
    ]
    assert levels.tolist() == [r.level for r in want]
    assert c.reasons == want
