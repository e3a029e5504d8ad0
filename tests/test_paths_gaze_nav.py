"""Recorded paths, the simulated gaze, and walking with collision."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from app.gaze import GazeModel
from app.navigation import Walker
from app.paths import CameraPath, PathError, PathKey, builtin_path
from app.raycast import RayCaster
from app.settings import GazeSettings, NavigationSettings


def box_room(half=2.0, height=3.0):
    """Inward-facing walls of a 4 x 4 x 3 m room with a 0.3 m step at x > 1."""
    tris = []

    def rect(a, b, c, d):
        tris.extend([[a, b, c], [a, c, d]])

    h, y = half, height
    rect((-h, 0, -h), (h, 0, -h), (h, 0, h), (-h, 0, h))  # floor
    rect((-h, y, -h), (h, y, -h), (h, y, h), (-h, y, h))  # ceiling
    rect((-h, 0, -h), (h, 0, -h), (h, y, -h), (-h, y, -h))  # north
    rect((-h, 0, h), (h, 0, h), (h, y, h), (-h, y, h))  # south
    rect((-h, 0, -h), (-h, 0, h), (-h, y, h), (-h, y, -h))  # west
    rect((h, 0, -h), (h, 0, h), (h, y, h), (h, y, -h))  # east
    return RayCaster(np.array(tris, float))


def test_path_interpolates_and_round_trips(tmp_path):
    p = CameraPath(
        [
            PathKey(0.0, (0, 1.6, 0), 0, 0, (0.2, 0.2), False),
            PathKey(2.0, (2, 1.6, 0), 90, 10, (0.8, 0.6), True),
        ],
        "room",
    )
    k = p.sample(1.0)
    assert k.position == pytest.approx((1, 1.6, 0)) and k.yaw_deg == pytest.approx(45)
    assert k.gaze == pytest.approx((0.5, 0.4)) and k.gaze_fixed is False
    assert p.sample(2.0).gaze_fixed is True
    assert p.sample(math.nan).position == (0, 1.6, 0) and p.sample(99).position == (2, 1.6, 0)
    assert p.frame_count() == 121 and p.at_frame(60).t == pytest.approx(1.0)
    p.save(tmp_path / "p.json")
    assert CameraPath.load(tmp_path / "p.json").to_dict() == p.to_dict()


@pytest.mark.parametrize(
    "doc, message",
    [
        ({"keys": []}, "not a vrpreview path"),
        ({"vrpreview_path": 1, "keys": []}, "no keys"),
        ({"vrpreview_path": 1, "keys": [{"t": 0}]}, "malformed"),
        ({"vrpreview_path": 1, "keys": [{"t": 0, "position": [0, "NaN", 0]}]}, "non-finite"),
    ],
)
def test_bad_paths_are_rejected_clearly(tmp_path, doc, message):
    f = tmp_path / "bad.json"
    f.write_text(json.dumps(doc))
    with pytest.raises(PathError, match=message):
        CameraPath.load(f)


def test_builtin_walkthrough_is_shipped():
    p = builtin_path("showroom_walkthrough")
    assert p.scene == "showroom" and p.duration > 5.0


def test_gaze_from_the_side_by_side_view_and_fixing():
    g = GazeModel(GazeSettings(dwell=False))
    assert g.from_view_pixel(100, 50, 800, 400) == pytest.approx((0.25, 0.125))
    assert g.from_view_pixel(500, 50, 800, 400) == pytest.approx((0.25, 0.125))  # right eye
    g.set_cursor(math.nan, 0.3)
    assert (g.state.u, g.state.v) == (0.5, 0.5)
    g.set_cursor(2.0, -1.0)
    assert (g.state.u, g.state.v) == (1.0, 0.0)
    g.button_held = True
    assert g.update(1 / 60, 95).fixed
    g.button_held = False
    assert not g.update(1 / 60, 95).fixed


def test_dwell_fixes_the_gaze_after_the_cursor_rests():
    g = GazeModel(GazeSettings(dwell=True, dwell_deg=1.0, dwell_s=0.3))
    g.set_cursor(0.5, 0.5)
    for _ in range(10):
        g.update(1 / 60, 95)
    assert not g.state.fixed  # 0.17 s still
    for _ in range(20):
        g.update(1 / 60, 95)
    assert g.state.fixed and g.state.speed_deg_s == 0.0
    g.set_cursor(0.9, 0.5)  # a saccade releases it
    assert not g.update(1 / 60, 95).fixed and g.state.speed_deg_s > 100


def test_walking_stops_at_walls_and_slides_along_them():
    w = Walker(NavigationSettings(radius_m=0.25), box_room())
    w.place((0, 1.6, 0), 0.0)  # looking north (-z)
    for _ in range(400):
        w.step(1.0, 0.0, 0.0, 1 / 60)
    assert -2.0 + 0.2 <= w.position[2] < -1.5  # at the wall, not through it
    w.place((0, 1.6, 0), 45.0)  # diagonally into the north-west corner: slides, then stops
    for _ in range(400):
        w.step(1.0, 0.0, 0.0, 1 / 60)
    assert w.position[0] > -2.0 + 0.2 and w.position[2] > -2.0 + 0.2
    assert w.position[1] == pytest.approx(1.6)  # stays at eye height on the floor


def test_walker_ignores_non_finite_input():
    w = Walker(NavigationSettings(), box_room())
    w.place((0, 1.6, 0), 0.0)
    w.step(math.nan, 1.0, 0.0, 1 / 60)
    w.look(math.inf, 0.0)
    w.place((math.nan, 0, 0), math.nan)
    assert np.isfinite(w.position).all() and w.position.tolist() == [0, 1.6, 0]
