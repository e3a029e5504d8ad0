"""The study's plot as a user reads it: the right points on the Pareto front, the front as a
step line, and a picture with axes, legend and the front in red."""

from __future__ import annotations

import numpy as np

from app.lab.study import FULL, pareto, plot, plot_data

ROWS = [
    {"name": FULL, "frame_ms": 120.0, "flip": 0.0},
    {"name": "black-mask", "frame_ms": 40.0, "flip": 0.2},
    {"name": "cps-block8", "frame_ms": 50.0, "flip": 0.05},
    {"name": "cps-block4", "frame_ms": 60.0, "flip": 0.03},
    {"name": "cps-block8-slow", "frame_ms": 55.0, "flip": 0.06},  # beaten by cps-block8
    {"name": "not-compared", "frame_ms": 30.0, "flip": None},  # no error figure: not plotted
]
RED = np.array([220, 30, 30])
BLUE = np.array([42, 90, 200])


def near(img: np.ndarray, colour: np.ndarray, tol: int = 12) -> np.ndarray:
    return np.abs(img.astype(int) - colour).max(axis=2) <= tol


def test_plot_data_puts_the_non_dominated_runs_on_a_step_line_fastest_first():
    front = pareto(ROWS)
    assert front == ["black-mask", "cps-block8", "cps-block4", FULL]
    data = plot_data(ROWS, front)
    assert [p[0] for p in data.points] == [
        FULL,
        "black-mask",
        "cps-block8",
        "cps-block4",
        "cps-block8-slow",
    ]
    assert [p[0] for p in data.front] == front
    # Along at each run's error to the next run's frame time, then down to its error.
    assert data.step_x == (40.0, 50.0, 50.0, 60.0, 60.0, 120.0, 120.0)
    assert data.step_y == (0.2, 0.2, 0.05, 0.05, 0.03, 0.03, 0.0)


def test_plot_is_a_picture_with_the_front_in_red_and_the_other_runs_in_blue():
    img = plot(ROWS, pareto(ROWS), "cps: corridor")
    assert img.shape == (600, 900, 3) and img.dtype == np.uint8
    white = (img > 245).all(axis=2).mean()
    assert 0.6 < white < 0.99  # a plot, not a blank page and not a filled one
    red, blue = near(img, RED), near(img, BLUE)
    assert red.sum() > 500  # the step line and its five dots (and the legend's)
    assert blue.sum() > 50  # the one run off the front (and its legend entry)
    # The step line's long horizontal run from 60 ms to 120 ms: a red row spanning >200 px.
    longest = max(_longest_run(row) for row in red)
    assert longest > 200


def test_plot_without_any_compared_run_says_so_instead_of_failing():
    img = plot([{"name": "a", "frame_ms": 10.0, "flip": None}], [], "empty")
    assert img.shape == (600, 900, 3) and not near(img, RED).any()


def _longest_run(row: np.ndarray) -> int:
    best = cur = 0
    for v in row:
        cur = cur + 1 if v else 0
        best = max(best, cur)
    return best
