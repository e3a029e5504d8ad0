"""CPS reference model (SPEC C): edge rays and side caps, the detail map, the filters."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import settings as hsettings
from hypothesis import strategies as st

from app.camera import EyeView, StereoCamera
from app.cps import (
    MAX_LEVEL,
    SIDES,
    SideCaps,
    angle_deg,
    bilinear_filter,
    block_centres,
    block_image,
    cap_at,
    cap_from_distance,
    desired_level,
    detail_map,
    edge_rays,
    hierarchical_filter,
    level_shares,
    shaded_samples,
    side_caps,
    view_rays,
)
from app.raycast import RayCaster
from app.settings import CpsSettings, StereoSettings

SWEEP = hsettings(derandomize=True, database=None, max_examples=150, deadline=None)
ALL_MAX = dict.fromkeys(SIDES, MAX_LEVEL)


def _eye(width: int = 160, height: int = 90, index: int = 0, fov_deg: float = 95.0) -> EyeView:
    return StereoCamera(StereoSettings(fov_deg=fov_deg)).eyes(width, height)[index]


def _cps(**changes) -> CpsSettings:
    return dataclasses.replace(CpsSettings(), **changes)


# -- rays -------------------------------------------------------------------------------------


def test_view_rays_match_eye_ray() -> None:
    eye = _eye(123, 77, index=1)
    points = [
        (0.0, 0.0),
        (1.0, 1.0),
        (0.3, 0.8),
        (0.5, 0.5),
        (-2.0, 0.4),
        (0.2, 7.0),
        (math.nan, 0.1),
        (0.9, math.inf),
    ]
    u = np.array([p[0] for p in points])
    v = np.array([p[1] for p in points])
    got = view_rays(eye, u, v)
    assert got.shape == (len(points), 3)
    for k, (pu, pv) in enumerate(points):
        np.testing.assert_allclose(got[k], eye.ray(pu, pv), atol=1e-12)


def test_angle_is_accurate_at_tiny_and_straight_angles() -> None:
    a = np.array([0.0, 0.0, -1.0])
    tiny = np.array([1e-9, 0.0, -1.0])
    assert angle_deg(a, tiny) == pytest.approx(math.degrees(1e-9), rel=1e-6)
    assert angle_deg(a, -a) == pytest.approx(180.0)
    assert angle_deg(a, np.array([1.0, 0.0, 0.0])) == pytest.approx(90.0)


@pytest.mark.parametrize("n", [1, 4, 7])
def test_edge_rays_go_through_the_view_edges(n: int) -> None:
    eye = _eye(200, 100)
    rays = edge_rays(eye, n)
    assert set(rays) == set(SIDES)
    t = (np.arange(n) + 0.5) / n
    for side, (origins, dirs) in rays.items():
        assert origins.shape == dirs.shape == (n, 3)
        np.testing.assert_array_equal(origins, np.broadcast_to(eye.position, (n, 3)))
        np.testing.assert_allclose(np.linalg.norm(dirs, axis=1), 1.0)
        # Back to NDC: a point along the ray projects onto the expected edge coordinate.
        points = np.c_[eye.position + dirs, np.ones(n)] @ eye.view_projection.T
        ndc = points[:, :2] / points[:, 3:4]
        if side == "left":
            np.testing.assert_allclose(ndc[:, 0], -1.0, atol=1e-9)
            np.testing.assert_allclose(ndc[:, 1], 1 - 2 * t, atol=1e-9)
        elif side == "right":
            np.testing.assert_allclose(ndc[:, 0], 1.0, atol=1e-9)
            np.testing.assert_allclose(ndc[:, 1], 1 - 2 * t, atol=1e-9)
        else:
            np.testing.assert_allclose(ndc[:, 0], 2 * t - 1, atol=1e-9)
            np.testing.assert_allclose(ndc[:, 1], -1.0, atol=1e-9)


def test_edge_rays_take_at_least_one_per_side() -> None:
    rays = edge_rays(_eye(), 0)
    assert all(o.shape == (1, 3) for o, _d in rays.values())


# -- side caps --------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("distance", "expected"),
    [
        (-1.0, 4),
        (0.0, 4),
        (0.5, 4),
        (1.0, 4),  # at or nearer than near_m: max_level
        (2.25, 3),  # 4 * 3.75 / 5 = 3.0
        (2.875, 3),  # 4 * 0.625 = 2.5: half rounds up
        (2.876, 2),
        (3.5, 2),
        (5.0, 1),
        (5.37, 1),
        (5.38, 0),
        (6.0, 0),
        (100.0, 0),
        (math.inf, 0),
        (math.nan, 0),
        (-math.inf, 0),
    ],
)
def test_cap_from_distance(distance: float, expected: int) -> None:
    assert cap_from_distance(distance, _cps(max_level=4, near_m=1.0, far_m=6.0)) == expected


@pytest.mark.parametrize(
    ("near", "far", "distance", "expected"),
    [
        (2.0, 2.0, 2.0, 5),
        (2.0, 2.0, 2.0001, 0),
        (2.0, 2.0, 0.1, 5),
        (3.0, 1.0, 2.0, 5),
        (3.0, 1.0, 3.5, 0),
        (0.0, 0.0, 0.0, 5),
        (0.0, 0.0, 1e-9, 0),
        (3.0, 1.0, math.nan, 0),
        (2.0, 2.0, math.inf, 0),
        (math.nan, 6.0, 0.5, 0),
        (1.0, math.inf, 0.5, 0),
    ],
)
def test_cap_when_far_is_not_beyond_near(
    near: float, far: float, distance: float, expected: int
) -> None:
    assert cap_from_distance(distance, _cps(max_level=5, near_m=near, far_m=far)) == expected


def test_cap_is_zero_without_levels() -> None:
    assert cap_from_distance(0.0, _cps(max_level=0)) == 0
    assert cap_from_distance(0.0, _cps(max_level=99)) == MAX_LEVEL  # set around validation


def _quad(corners: list[tuple[float, float, float]]) -> np.ndarray:
    a, b, c, d = (np.array(p, np.float64) for p in corners)
    return np.array([[a, b, c], [a, c, d]])


class _CountingCaster(RayCaster):
    calls = 0

    def cast_many(self, origins, directions, t_max: float = math.inf):
        self.calls += 1
        return super().cast_many(origins, directions, t_max)


def test_side_caps_without_a_scene() -> None:
    caps = side_caps(None, _eye(), _cps())
    assert caps.caps == dict.fromkeys(SIDES, 0)
    assert caps.distances == dict.fromkeys(SIDES, math.inf)
    assert caps.hits.shape == (0, 3)


def test_wall_on_the_left_caps_only_the_left() -> None:
    # A wall 0.5 m left of the head (x = -0.5), from eye height (1.6 m) up: the upper left edge
    # rays hit it, the right and bottom rays (all going down) see nothing.
    wall = _quad([(-0.5, 1.6, 10.0), (-0.5, 1.6, -10.0), (-0.5, 10.0, -10.0), (-0.5, 10.0, 10.0)])
    caster = _CountingCaster(wall)
    eye = _eye(160, 90)
    settings = _cps(max_level=4, near_m=1.0, far_m=6.0, rays_per_side=6)
    caps = side_caps(caster, eye, settings)
    assert caster.calls == 1  # all 3n rays of the eye in one batch
    assert caps.caps == {"left": 4, "right": 0, "bottom": 0}
    assert 0.5 < caps.distances["left"] <= 1.0
    assert caps.distances["right"] == caps.distances["bottom"] == math.inf
    assert 1 <= len(caps.hits) <= 6
    np.testing.assert_allclose(caps.hits[:, 0], -0.5, atol=1e-6)
    assert (caps.hits[:, 1] >= 1.6 - 1e-6).all()


def test_side_caps_follow_the_nearest_hit_per_side() -> None:
    floor = _quad([(-50.0, 0.0, 50.0), (50.0, 0.0, 50.0), (50.0, 0.0, -50.0), (-50.0, 0.0, -50.0)])
    right_wall = _quad(
        [(3.0, -5.0, 20.0), (3.0, -5.0, -20.0), (3.0, 20.0, -20.0), (3.0, 20.0, 20.0)]
    )
    caster = RayCaster(np.concatenate([floor, right_wall]))
    eye = _eye(160, 90, index=1)
    n = 5
    settings = _cps(max_level=5, near_m=0.5, far_m=8.0, rays_per_side=n)
    caps = side_caps(caster, eye, settings)
    rays = edge_rays(eye, n)
    # Analytic nearest hits: the floor for the bottom rays, the wall or floor for the others.
    _o, bottom = rays["bottom"]
    expected_bottom = float(np.min(-eye.position[1] / bottom[:, 1]))
    _o, right = rays["right"]
    to_wall = (3.0 - eye.position[0]) / right[:, 0]
    to_floor = np.where(
        right[:, 1] < 0, -eye.position[1] / np.minimum(right[:, 1], -1e-300), np.inf
    )
    expected_right = float(np.min(np.minimum(to_wall, to_floor)))
    assert caps.distances["bottom"] == pytest.approx(expected_bottom, rel=1e-6)
    assert caps.distances["right"] == pytest.approx(expected_right, rel=1e-6)
    for side in SIDES:
        assert caps.caps[side] == cap_from_distance(caps.distances[side], settings)
    assert caps.caps["bottom"] > 0 and caps.caps["right"] > 0
    _o, left = rays["left"]  # only the left rays that go down meet the floor
    assert len(caps.hits) == 2 * n + int((left[:, 1] < -1e-9).sum())


def test_side_caps_of_a_broken_eye_reduce_nothing() -> None:
    eye = _eye()
    eye.position = np.array([math.nan, 0.0, 0.0])
    floor = _quad([(-50.0, 0.0, 50.0), (50.0, 0.0, 50.0), (50.0, 0.0, -50.0), (-50.0, 0.0, -50.0)])
    caps = side_caps(RayCaster(floor), eye, _cps(near_m=100.0, far_m=200.0))
    assert caps.caps == dict.fromkeys(SIDES, 0)
    assert caps.hits.shape == (0, 3)


# -- desired level and cap field ----------------------------------------------------------------


@pytest.mark.parametrize(
    ("theta", "cap", "expected"),
    [
        (0.0, 5, 0),
        (10.0, 5, 0),
        (10.0001, 5, 1),
        (15.99, 5, 1),
        (16.0, 5, 2),
        (21.9, 5, 2),
        (22.0, 5, 3),
        (28.0, 5, 4),
        (100.0, 5, 4),
        (179.9, 5, 4),
        (math.inf, 5, 4),
        (100.0, 2, 2),
        (100.0, 0, 0),
        (100.0, -3, 0),
        (100.0, 2.7, 2),
        (100.0, math.nan, 0),
        (math.nan, 5, 0),
        (-5.0, 5, 0),
        (-math.inf, 5, 0),
    ],
)
def test_desired_level(theta: float, cap: float, expected: int) -> None:
    settings = _cps(max_level=4, fovea_deg=10.0, deg_per_level=6.0)
    assert int(desired_level(theta, cap, settings)) == expected


def test_desired_level_fallbacks() -> None:
    assert int(desired_level(50.0, 5, _cps(fovea_deg=math.nan))) == 0
    assert int(desired_level(10.5, 5, _cps(fovea_deg=10.0, deg_per_level=0.0, max_level=3))) == 3
    assert int(desired_level(10.5, 5, _cps(fovea_deg=10.0, deg_per_level=math.nan))) == 4
    assert int(desired_level(10.5, 5, _cps(fovea_deg=10.0, deg_per_level=math.inf))) == 1
    assert int(desired_level(180.0, 5, _cps(fovea_deg=180.0))) == 0
    out = desired_level(np.array([[0.0, 50.0]]), np.array([[5], [1]]), _cps())
    assert out.shape == (2, 2) and out.dtype == np.int64


@SWEEP
@given(
    a=st.floats(0, 180),
    b=st.floats(0, 180),
    cap=st.integers(-2, 8),
    fovea=st.floats(0, 180),
    step=st.floats(0.1, 180),
    max_level=st.integers(0, 5),
)
def test_desired_level_grows_with_angle_and_respects_limits(
    a: float, b: float, cap: int, fovea: float, step: float, max_level: int
) -> None:
    settings = _cps(fovea_deg=fovea, deg_per_level=step, max_level=max_level)
    lo, hi = sorted((a, b))
    la, lb = int(desired_level(lo, cap, settings)), int(desired_level(hi, cap, settings))
    assert 0 <= la <= lb <= min(max(cap, 0), max_level)


def test_cap_field() -> None:
    caps = {"left": 4, "right": 2, "bottom": 5}
    # Left cap on the left quarter, right cap on the right quarter, linear between; the bottom
    # cap ramps in over the lower half (v from the top).
    u = np.array([0.0, 0.25, 0.375, 0.5, 0.5, 0.625, 0.75, 1.0, 0.5, 0.5, 0.0])
    v = np.array([0.2, 0.2, 0.2, 0.0, 0.5, 0.2, 0.2, 0.2, 0.625, 1.0, 1.0])
    np.testing.assert_array_equal(cap_at(u, v, caps), [4, 4, 3, 3, 3, 2, 2, 2, 3, 5, 5])
    assert int(cap_at(0.0, 0.0, {})) == 0  # missing sides count as 0
    assert int(cap_at(0.0, 1.0, SideCaps(caps={"left": 1, "right": 0, "bottom": 3}))) == 3


def test_block_centres() -> None:
    np.testing.assert_array_equal(block_centres(5, 0), [0.5, 1.5, 2.5, 3.5, 4.5])
    np.testing.assert_array_equal(block_centres(10, 2), [2.0, 6.0, 9.5])  # last block clipped
    np.testing.assert_array_equal(block_centres(1, 5), [0.5])


# -- detail map -------------------------------------------------------------------------------


def _reference_map(
    eye: EyeView,
    w: int,
    h: int,
    gaze: tuple[float, float],
    caps: dict[str, int],
    settings: CpsSettings,
) -> np.ndarray:
    """The detail map by the letter of its definition, one pixel and one level at a time."""
    g = eye.ray(*gaze)
    max_level = min(MAX_LEVEL, settings.max_level)
    out = np.zeros((h, w), np.uint8)

    def desired(cx: float, cy: float) -> int:
        u, v = cx / w, 1 - cy / h
        d = eye.ray(u, v)
        theta = math.degrees(math.atan2(float(np.linalg.norm(np.cross(d, g))), float(d @ g)))
        t = min(1.0, max(0.0, (u - 0.25) / 0.5))
        wb = min(1.0, max(0.0, (v - 0.5) / 0.25))
        left, right = caps.get("left", 0), caps.get("right", 0)
        cap = math.floor(max(left + (right - left) * t, caps.get("bottom", 0) * wb))
        e = (
            0
            if theta <= settings.fovea_deg
            else math.floor((theta - settings.fovea_deg) / settings.deg_per_level) + 1
        )
        return max(0, min(e, cap, max_level))

    for y in range(h):
        for x in range(w):
            for s in range(max_level, 0, -1):
                b = 2**s
                ox, oy = x & ~(b - 1), y & ~(b - 1)
                cx = min(max(ox + b / 2, 0.5), w - 0.5)
                cy = min(max(oy + b / 2, 0.5), h - 0.5)
                if desired(cx, cy) >= s:
                    out[y, x] = s
                    break
    return out


def _assert_blocks_uniform(level_map: np.ndarray) -> None:
    """Every aligned 2^s block that holds a pixel of level s holds only level s."""
    h, w = level_map.shape
    for s in range(1, MAX_LEVEL + 1):
        b = 2**s
        ys, xs = np.nonzero(level_map == s)
        for oy, ox in {(y & ~(b - 1), x & ~(b - 1)) for y, x in zip(ys, xs)}:
            block = level_map[oy : min(oy + b, h), ox : min(ox + b, w)]
            assert (block == s).all(), f"level {s} block at ({ox}, {oy}) is not uniform"


@pytest.mark.parametrize(
    ("gaze", "caps", "max_level"),
    [
        ((0.5, 0.5), ALL_MAX, 5),
        ((0.8, 0.2), {"left": 5, "right": 2, "bottom": 3}, 5),
        ((0.1, 0.9), {"left": 1, "right": 4, "bottom": 0}, 3),
        ((-0.3, 1.7), ALL_MAX, 4),
    ],
)
def test_detail_map_matches_its_definition(
    gaze: tuple[float, float], caps: dict[str, int], max_level: int
) -> None:
    w, h = 45, 27  # not multiples of any block: clipped blocks at the right and top
    eye = _eye(w, h, fov_deg=110.0)
    settings = _cps(max_level=max_level, fovea_deg=8.0, deg_per_level=5.0)
    got = detail_map(eye, w, h, gaze, caps, settings)
    assert got.dtype == np.uint8 and got.shape == (h, w)
    np.testing.assert_array_equal(got, _reference_map(eye, w, h, gaze, caps, settings))
    assert got.max() > 0


def test_all_caps_zero_gives_full_detail() -> None:
    eye = _eye()
    got = detail_map(eye, 160, 90, (0.5, 0.5), dict.fromkeys(SIDES, 0), _cps(fovea_deg=0.0))
    assert not got.any()
    assert not detail_map(eye, 160, 90, (0.5, 0.5), {}, _cps(fovea_deg=0.0)).any()


def _pixel_theta(eye: EyeView, w: int, h: int, gaze: tuple[float, float]) -> np.ndarray:
    x = (np.arange(w) + 0.5)[None, :] / w
    y = 1 - (np.arange(h) + 0.5)[:, None] / h
    return angle_deg(view_rays(eye, x, y), view_rays(eye, *gaze))


def _margin_deg(h: int, fov_deg: float, max_level: int) -> float:
    """Largest angle between a pixel centre and the centre of any block holding it.

    The gnomonic projection only stretches distances, so an angle is at most the distance on
    the image plane at unit depth: half a block diagonal of 2^(s-1) sqrt 2 pixels of
    2 tan(fov / 2) / H each.
    """
    px = 2 * math.tan(math.radians(fov_deg) / 2) / h
    return math.degrees(2**max_level * math.sqrt(2) / 2 * px)


def test_fovea_keeps_full_detail() -> None:
    w, h = 320, 180
    eye = _eye(w, h)
    for gaze in [(0.5, 0.5), (0.2, 0.7), (0.9, 0.9)]:
        settings = _cps(max_level=3, fovea_deg=15.0, deg_per_level=4.0)
        got = detail_map(eye, w, h, gaze, ALL_MAX, settings)
        inner = _pixel_theta(eye, w, h, gaze) < 15.0 - _margin_deg(h, 95.0, 3)
        assert inner.sum() > 100
        assert not got[inner].any()


def test_levels_grow_with_angle() -> None:
    """Sandwich: e(theta - m) <= level <= e(theta + m), m the largest pixel-to-block angle."""
    w, h = 384, 192
    eye = _eye(w, h)
    settings = _cps(max_level=3, fovea_deg=5.0, deg_per_level=5.0)
    gaze = (0.15, 0.5)
    got = detail_map(eye, w, h, gaze, ALL_MAX, settings)
    theta = _pixel_theta(eye, w, h, gaze)
    m = _margin_deg(h, 95.0, 3)
    assert m < settings.deg_per_level
    assert (got <= desired_level(theta + m, MAX_LEVEL, settings)).all()
    # Where every block centre lies in the outer left quarter the cap is 5, so the bound holds
    # from below too, and the level there follows the angle alone.
    left = np.s_[:, : w // 4 - 8]
    assert (got[left] >= desired_level(theta - m, MAX_LEVEL, settings)[left]).all()
    assert set(np.unique(got[left]).tolist()) == {0, 1, 2, 3}
    # The mean level over rings of angle never falls there.
    bins = np.digitize(theta[left], np.arange(0, 90, 2.5))
    means = [got[left][bins == k].mean() for k in np.unique(bins)]
    assert all(a <= b for a, b in zip(means, means[1:]))


def test_never_above_max_level_or_the_side_cap() -> None:
    w, h = 256, 128
    eye = _eye(w, h)
    caps = {"left": 3, "right": 1, "bottom": 2}
    for max_level in range(6):
        settings = _cps(max_level=max_level, fovea_deg=0.0, deg_per_level=1.0)
        got = detail_map(eye, w, h, (0.5, 0.5), caps, settings)
        assert got.max() == min(max_level, 3)
        for s in range(1, max_level + 1):
            ys, xs = np.nonzero(got == s)
            b = 2**s
            cx = np.minimum((xs & ~(b - 1)) + b / 2, w - 0.5)
            cy = np.minimum((ys & ~(b - 1)) + b / 2, h - 0.5)
            assert (cap_at(cx / w, 1 - cy / h, caps) >= s).all()


def test_left_cap_fades_out_towards_the_right() -> None:
    w, h = 128, 64
    eye = _eye(w, h)
    got = detail_map(eye, w, h, (0.5, 0.5), {"left": 4}, _cps(fovea_deg=0.0, max_level=5))
    assert not got[:, 3 * w // 4 :].any()  # the right quarter keeps the right cap, 0
    assert got[:, : w // 4].min() > 0 and got.max() == 4


@SWEEP
@given(
    w=st.integers(1, 80),
    h=st.integers(1, 80),
    gu=st.floats(-0.5, 1.5),
    gv=st.floats(-0.5, 1.5),
    cl=st.integers(0, 5),
    cr=st.integers(0, 5),
    cb=st.integers(0, 5),
    fovea=st.floats(0, 60),
    step=st.floats(0.1, 30),
    max_level=st.integers(0, 5),
)
def test_level_blocks_are_uniform(
    w: int,
    h: int,
    gu: float,
    gv: float,
    cl: int,
    cr: int,
    cb: int,
    fovea: float,
    step: float,
    max_level: int,
) -> None:
    eye = _eye(w, h, fov_deg=120.0)
    settings = _cps(fovea_deg=fovea, deg_per_level=step, max_level=max_level)
    got = detail_map(eye, w, h, (gu, gv), {"left": cl, "right": cr, "bottom": cb}, settings)
    assert got.shape == (h, w) and got.max(initial=0) <= max_level
    _assert_blocks_uniform(got)


@pytest.mark.parametrize(("w", "h"), [(1, 1), (1, 50), (50, 1), (2, 3)])
def test_detail_map_of_tiny_viewports(w: int, h: int) -> None:
    eye = _eye(w, h)
    got = detail_map(eye, w, h, (0.0, 1.0), ALL_MAX, _cps(fovea_deg=0.0, deg_per_level=0.1))
    assert got.shape == (h, w)
    np.testing.assert_array_equal(
        got, _reference_map(eye, w, h, (0.0, 1.0), ALL_MAX, _cps(fovea_deg=0.0, deg_per_level=0.1))
    )
    _assert_blocks_uniform(got)
    assert detail_map(eye, 0, -3, (0.5, 0.5), ALL_MAX, _cps()).shape == (1, 1)


def test_detail_map_extremes() -> None:
    w, h = 96, 64
    eye = _eye(w, h)
    assert not detail_map(eye, w, h, (0.5, 0.5), ALL_MAX, _cps(max_level=0)).any()
    assert not detail_map(eye, w, h, (0.5, 0.5), ALL_MAX, _cps(fovea_deg=180.0)).any()
    settings = _cps(fovea_deg=2.0, deg_per_level=3.0)
    for outside, clamped in [
        ((-1.0, 2.0), (0.0, 1.0)),
        ((7.0, -0.5), (1.0, 0.0)),
        ((math.nan, math.inf), (0.5, 0.5)),
    ]:
        np.testing.assert_array_equal(
            detail_map(eye, w, h, outside, ALL_MAX, settings),
            detail_map(eye, w, h, clamped, ALL_MAX, settings),
        )


# -- shares and samples -----------------------------------------------------------------------


def test_level_shares() -> None:
    level_map = np.array([[0, 0, 1, 1], [5, 5, 5, 2]])
    assert level_shares(level_map) == [0.25, 0.25, 0.125, 0.0, 0.0, 0.375]
    assert level_shares(level_map, max_level=2) == [0.25, 0.25, 0.125]
    assert level_shares(np.zeros((0, 0))) == [0.0] * 6


@pytest.mark.parametrize("s", range(6))
def test_shaded_samples_of_a_uniform_map(s: int) -> None:
    level_map = np.full((64, 128), s, np.uint8)
    assert shaded_samples(level_map) == 64 * 128 // 4**s
    assert shaded_samples(level_map) == pytest.approx((1.0 / 4.0**level_map).sum())


def test_shaded_samples_count_clipped_blocks_once() -> None:
    assert shaded_samples(np.full((33, 33), 5)) == 4
    assert shaded_samples(np.full((1, 1), 5)) == 1
    assert shaded_samples(np.zeros((0, 4))) == 0


def test_shaded_samples_of_a_detail_map() -> None:
    w, h = 256, 128  # multiples of 32: no clipped block, so samples = sum of 1 / 4^s
    got = detail_map(_eye(w, h), w, h, (0.3, 0.6), ALL_MAX, _cps(max_level=5, fovea_deg=3.0))
    samples = shaded_samples(got)
    assert samples == pytest.approx((1.0 / 4.0**got).sum())
    assert samples < w * h / 2


# -- filters ----------------------------------------------------------------------------------


def _weights(level_map: np.ndarray, fn=hierarchical_filter) -> np.ndarray:
    """(H, W, H, W): the weight each output pixel gives each input pixel (a linear filter)."""
    h, w = level_map.shape
    one_hot = np.eye(h * w).reshape(h, w, h * w)
    return fn(one_hot, level_map).reshape(h, w, h, w)


def _taps(weights: np.ndarray, x: int, y: int) -> dict[tuple[int, int], float]:
    """Non-zero weights of output pixel (x, y), keyed by input pixel (x, y)."""
    ys, xs = np.nonzero(weights[y, x])
    return {(int(px), int(py)): float(weights[y, x, py, px]) for py, px in zip(ys, xs)}


def _assert_taps(got: dict[tuple[int, int], float], expected: dict[tuple[int, int], float]) -> None:
    assert set(got) == set(expected), (got, expected)
    for key, value in expected.items():
        assert got[key] == pytest.approx(value, abs=1e-12), key


GRID4 = np.full((12, 12), 2)  # 3 x 3 blocks of 4 x 4 pixels


@pytest.mark.parametrize(
    ("pixel", "expected"),
    [
        # Next to the centre of the middle block: l = (-1/8, -1/8), ties take x as a0.
        ((5, 5), {(5, 5): 0.765625, (3, 5): 0.109375, (5, 3): 0.109375, (3, 3): 0.015625}),
        # On the block's left edge: l = (-3/8, -1/8).
        ((4, 5), {(4, 5): 0.546875, (3, 5): 0.328125, (4, 3): 0.078125, (3, 3): 0.046875}),
        # Its bottom edge: l = (-1/8, -3/8), so a0 is y.
        ((5, 4), {(5, 4): 0.546875, (5, 3): 0.328125, (3, 4): 0.078125, (3, 3): 0.046875}),
        # Its corner: l = (-3/8, -3/8).
        ((4, 4), {(4, 4): 0.390625, (3, 4): 0.234375, (4, 3): 0.234375, (3, 3): 0.140625}),
        # The top-right corner pixel of it looks up and right: l = (3/8, 3/8).
        ((7, 7), {(7, 7): 0.390625, (8, 7): 0.234375, (7, 8): 0.234375, (8, 8): 0.140625}),
        # Screen corner: every neighbour clamps back into the pixel's own block.
        ((0, 0), {(0, 0): 1.0}),
        # Screen bottom border: only the x interpolation is left.
        ((1, 0), {(1, 0): 0.875, (0, 0): 0.125}),
        # Screen right border, in the lower part of the top block row: x clamps, y looks up.
        ((11, 6), {(11, 6): 0.875, (11, 8): 0.125}),
    ],
)
def test_hierarchical_weights_in_a_uniform_grid(
    pixel: tuple[int, int], expected: dict[tuple[int, int], float]
) -> None:
    _assert_taps(_taps(_weights(GRID4), *pixel), expected)


def test_hierarchical_weights_where_block_sizes_meet() -> None:
    # A 4x4 block at the bottom-left, 2x2 blocks right of it, a row of 4x4 blocks above.
    level_map = np.full((8, 8), 2)
    level_map[0:4, 4:8] = 1
    weights = _weights(level_map)
    # Big block, looking right into a small one: P0 = (4, 1) in the 2x2 block at (4, 0);
    # Q clamps into the own block; R = (4, 0) (below the clamp); l2 = (1.5 / 2) - 0.5 = 1/4.
    _assert_taps(
        _taps(weights, 3, 1),
        {(3, 1): 0.625 * 0.875, (3, 0): 0.625 * 0.125, (4, 1): 0.375 * 0.75, (4, 0): 0.375 * 0.25},
    )
    # Small block, looking left into the big one: l = (-1/4, 1/4), a0 = x; P0 = (3, 1) in the
    # 4x4 block; Q = (4, 2); R crosses the big block's top: (3, 4); l2 = 1.5 / 4 - 0.5 = -1/8.
    _assert_taps(
        _taps(weights, 4, 1),
        {(4, 1): 0.75 * 0.75, (4, 2): 0.75 * 0.25, (3, 1): 0.25 * 0.875, (3, 4): 0.25 * 0.125},
    )


def test_bilinear_taps_sit_at_block_centre_pixels() -> None:
    # Uniform 4x4 grid: f = 5.5 / 4 - 0.5 = 0.875 per axis, blocks 0 and 1 read at pixels 2, 6.
    _assert_taps(
        _taps(_weights(GRID4, bilinear_filter), 5, 5),
        {(2, 2): 0.015625, (6, 2): 0.109375, (2, 6): 0.109375, (6, 6): 0.765625},
    )
    # Where sizes meet it keeps its own 4x4 grid: x taps 2 and 6 (6 lies in two different 2x2
    # blocks at y = 0 and y = 2), y taps -2 (clamped to 0) and 2.
    level_map = np.full((8, 8), 2)
    level_map[0:4, 4:8] = 1
    _assert_taps(
        _taps(_weights(level_map, bilinear_filter), 3, 1),
        {
            (2, 0): 0.625 * 0.125,
            (6, 0): 0.375 * 0.125,
            (2, 2): 0.625 * 0.875,
            (6, 2): 0.375 * 0.875,
        },
    )


def test_level_zero_pixels_are_returned_exactly() -> None:
    rng = np.random.default_rng(3)
    colours = rng.random((17, 23, 3)) * 1e3
    level_map = rng.integers(0, 4, (17, 23))
    level_map[5:9, 2:11] = 0
    out = hierarchical_filter(colours, level_map)
    np.testing.assert_array_equal(out[level_map == 0], colours[level_map == 0])
    np.testing.assert_array_equal(hierarchical_filter(colours, np.zeros((17, 23), int)), colours)
    np.testing.assert_array_equal(bilinear_filter(colours, np.zeros((17, 23), int)), colours)


level_maps = st.integers(1, 9).flatmap(
    lambda h: st.integers(1, 9).flatmap(
        lambda w: st.lists(st.integers(0, 5), min_size=h * w, max_size=h * w).map(
            lambda v: np.array(v).reshape(h, w)
        )
    )
)


@SWEEP
@given(level_map=level_maps)
def test_filter_weights_are_convex(level_map: np.ndarray) -> None:
    """Any level map, block-uniform or not: at most 4 taps, weights in [0, 1] summing to 1."""
    for fn in (hierarchical_filter, bilinear_filter):
        weights = _weights(level_map, fn)
        flat = weights.reshape(level_map.shape + (-1,))
        assert (flat >= 0).all()
        np.testing.assert_allclose(flat.sum(axis=-1), 1.0, atol=1e-12)
        assert ((flat > 0).sum(axis=-1) <= 4).all()


@SWEEP
@given(level_map=level_maps, colour=st.floats(-1e6, 1e6))
def test_uniform_colour_stays_uniform(level_map: np.ndarray, colour: float) -> None:
    colours = np.full(level_map.shape + (3,), colour)
    for fn in (hierarchical_filter, bilinear_filter):
        np.testing.assert_allclose(fn(colours, level_map), colour, rtol=1e-12, atol=1e-9)


def test_output_stays_within_the_inputs() -> None:
    eye = _eye(160, 90)
    level_map = detail_map(eye, 160, 90, (0.7, 0.3), ALL_MAX, _cps(max_level=5, fovea_deg=2.0))
    colours = block_image(np.random.default_rng(1).random((90, 160, 3)), level_map)
    for fn in (hierarchical_filter, bilinear_filter):
        out = fn(colours, level_map)
        assert out.shape == colours.shape
        assert (out >= colours.min(axis=(0, 1)) - 1e-12).all()
        assert (out <= colours.max(axis=(0, 1)) + 1e-12).all()


@SWEEP
@given(s=st.integers(0, 5), w=st.integers(1, 70), h=st.integers(1, 70), seed=st.integers(0, 99))
def test_filters_agree_where_the_level_is_uniform(s: int, w: int, h: int, seed: int) -> None:
    level_map = np.full((h, w), s)
    colours = block_image(np.random.default_rng(seed).random((h, w, 2)), level_map)
    np.testing.assert_allclose(
        hierarchical_filter(colours, level_map), bilinear_filter(colours, level_map), atol=1e-12
    )


@pytest.mark.parametrize("s", [1, 2, 3, 4])
@pytest.mark.parametrize("fn", [bilinear_filter, hierarchical_filter])
def test_linear_ramps_are_reproduced(s: int, fn) -> None:
    size = 2**s
    h, w = 4 * size, 6 * size
    level_map = np.full((h, w), s)
    y, x = np.indices((h, w))
    ramp = lambda px, py: 0.3 * px - 0.7 * py + 2.0  # noqa: E731 - continuous GL coordinates
    # Each block holds the ramp at its geometric centre.
    colours = ramp(x - x % size + size / 2, y - y % size + size / 2)
    out = fn(colours, level_map)
    # Between the first and last block centres the reconstruction is exact.
    inside = (
        (x + 0.5 >= size / 2)
        & (x + 0.5 <= w - size / 2)
        & (y + 0.5 >= size / 2)
        & (y + 0.5 <= h - size / 2)
    )
    np.testing.assert_allclose(out[inside], ramp(x + 0.5, y + 0.5)[inside], atol=1e-12)
    # block_image samples the pixel O + L // 2, half a pixel past the geometric centre.
    sampled = fn(block_image(ramp(x + 0.5, y + 0.5), level_map), level_map)
    np.testing.assert_allclose(sampled[inside], ramp(x + 1.0, y + 1.0)[inside], atol=1e-12)


def test_block_image() -> None:
    rng = np.random.default_rng(0)
    image = rng.integers(0, 255, (10, 13, 3), dtype=np.uint8)
    np.testing.assert_array_equal(block_image(image, np.zeros((10, 13), int)), image)
    out = block_image(image, np.full((10, 13), 2))
    assert out.dtype == np.uint8
    np.testing.assert_array_equal(out[0:4, 0:4], np.broadcast_to(image[2, 2], (4, 4, 3)))
    np.testing.assert_array_equal(out[8:10, 12:13], np.broadcast_to(image[9, 12], (2, 1, 3)))


def test_filters_accept_grey_images_and_reject_mismatched_maps() -> None:
    rng = np.random.default_rng(2)
    grey = rng.random((9, 11))
    level_map = rng.integers(0, 3, (9, 11))
    rgb = np.repeat(grey[..., None], 3, axis=2)
    for fn in (hierarchical_filter, bilinear_filter):
        np.testing.assert_allclose(
            fn(rgb, level_map), fn(grey, level_map)[..., None].repeat(3, axis=2)
        )
        with pytest.raises(ValueError):
            fn(grey, level_map[:, :5])
        assert fn(np.zeros((0, 0, 3)), np.zeros((0, 0), int)).shape == (0, 0, 3)
    # Out-of-range levels are clamped into 0..5 rather than indexing out of the image.
    np.testing.assert_array_equal(hierarchical_filter(grey, np.full((9, 11), -2)), grey)
    np.testing.assert_allclose(
        hierarchical_filter(grey, np.full((9, 11), 9)),
        hierarchical_filter(grey, np.full((9, 11), 5)),
    )
