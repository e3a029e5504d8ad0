"""The lab's plots as a user reads them: the right points on the Pareto front, the front as a
step line, the front in red, a bar per experiment run in its passes' colours."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from app.frame_log import OTHER, pass_colour
from app.lab.plots import RunTimes, plot_data, run_times_plot
from app.lab.study import FULL, pareto, plot

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


RUNS = [
    RunTimes("fragment", 80.0, 95.0, {"gbuffer": 10.0, "light_cull": 0.0, "lighting": 55.0}, 0.0),
    RunTimes("black-mask", 30.0, 35.0, {"gbuffer": 10.0, "cps_mask": 3.0, "lighting": 12.0}, 0.2),
    RunTimes("cps", 42.0, 50.0, {"gbuffer": 10.0, "cps_lighting": 20.0}, 0.04),
    RunTimes("not-compared", 45.0, 60.0, {"gbuffer": 10.0, "cps_lighting": 22.0}),
]


def test_a_run_bar_is_its_passes_then_the_rest_of_the_frame():
    assert RUNS[0].layers() == [("gbuffer", 10.0), ("lighting", 55.0), (OTHER, 15.0)]
    busy = RunTimes("gpu-bound", 20.0, 21.0, {"gbuffer": 12.0, "lighting": 9.0})
    assert busy.layers()[-1] == (OTHER, 0.0)  # never a negative rest
    result = SimpleNamespace(
        frame_ms=SimpleNamespace(median=42.0, p95=50.0),
        passes={"gbuffer": SimpleNamespace(median_ms=10.0)},
        error_vs_full_quality=SimpleNamespace(frame=SimpleNamespace(frames=2, flip=0.04)),
    )
    assert RunTimes.of("cps", result) == RunTimes("cps", 42.0, 50.0, {"gbuffer": 10.0}, 0.04)
    result.error_vs_full_quality = None
    assert RunTimes.of("cps", result).flip is None


def test_experiment_plot_shows_each_pass_colour_and_the_front_of_the_compared_runs():
    img = run_times_plot(RUNS, "experiments cps")
    assert img.dtype == np.uint8 and img.shape == (420, 1800, 3)
    for name in ("gbuffer", "lighting", "cps_mask", "cps_lighting", OTHER):
        colour = np.array([int(pass_colour(name)[i : i + 2], 16) for i in (1, 3, 5)])
        assert near(img, colour, tol=3).sum() > 200, name
    assert near(img[:, 1100:], RED).sum() > 300  # the second panel's Pareto front
    alone = run_times_plot(RUNS[3:], "experiments cps")  # nothing compared: the bars only
    assert alone.shape == (420, 1100, 3)
    many = run_times_plot(RUNS * 8, "experiments cps")
    assert many.shape[0] == 90 + 24 * 32  # a row per run
