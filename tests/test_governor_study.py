"""The governor's measured error table (``vrpreview study governor``): from the study's rows to
the governor's choices, and the study's files (pairs at equal frame time, the marked plot)."""

from __future__ import annotations

import json
import logging

import numpy as np
import pytest
from PIL import Image

from app import governor, governor_model
from app.governor import Governor, load_error_table, measured_knobs
from app.lab import governor_study
from app.lab.governor_study import FULL, Matrix, error_table, run_governor_study
from tests.test_governor import run, walking


def _prior(key: str):
    return next(k for k in governor_model.PRIOR_KNOBS if k.key == key)


def _row(name: str, flip: float, fovea: float = 0.0, ms: float = 50.0) -> dict:
    return {"name": name, "flip": flip, "fovea_flip": fovea, "periphery_flip": flip, "frame_ms": ms}


def test_the_table_counts_each_step_from_its_base_and_the_governor_takes_the_increments():
    scales = [s["render.scale"] for s in _prior("render.scale").steps]
    flips = [0.01, 0.03, 0.02] + [0.03 + 0.01 * i for i in range(1, len(scales) - 2)]
    rows = [_row(FULL, 0.0)]
    rows += [_row(f"render.scale={s}", e) for s, e in zip(scales, flips)]
    rows.append(_row("base cps.mode=cps cps.max_level=4", 0.05))
    rows.append(_row("cps.fovea_deg=7.0", 0.06, fovea=0.01))
    table = error_table(rows)
    scale = table["knobs"]["render.scale"]
    assert [s["value"] for s in scale] == scales
    assert [s["weight"] for s in scale] == [round(f, 6) for f in flips]
    fovea = table["knobs"]["cps.fovea_deg"]
    # counted from coarse lighting (its base), the fovea's error weighted 3x
    assert fovea == [{**fovea[0], "weight": round(0.06 + 3 * 0.01 - 0.05, 6)}]

    weights = {k: [s["weight"] for s in v] for k, v in table["knobs"].items()}
    knobs = {k.key: k for k in measured_knobs(weights)}
    # 0.01, then 0.02 more; a step measured better than the one before costs the least.
    assert knobs["render.scale"].error[:4] == pytest.approx(
        (0.01, 0.02, governor_model.MIN_STEP_ERROR, 0.01)
    )
    # a knob with only some steps measured keeps its priors
    prior = {k.key: k for k in governor_model.PRIOR_KNOBS}
    assert knobs["cps.fovea_deg"].error == prior["cps.fovea_deg"].error


def test_no_shadows_keeps_its_prior_as_the_reference_cannot_measure_it():
    """The reference keeps a run's shadows off, so the step to none measures 0: the table
    stops before it and the governor keeps its prior (a last resort, dearly priced)."""
    rows = [_row(FULL, 0.0), _row("render.shadows=hard", 0.01), _row("render.shadows=off", 0.0)]
    table = error_table(rows)
    assert [s["value"] for s in table["knobs"]["render.shadows"]] == ["hard"]
    weights = {k: [s["weight"] for s in v] for k, v in table["knobs"].items()}
    shadows = {k.key: k for k in measured_knobs(weights)}["render.shadows"]
    prior = {k.key: k for k in governor_model.PRIOR_KNOBS}["render.shadows"]
    assert shadows.error == pytest.approx((0.01, prior.error[1]))


def test_a_missing_or_broken_table_keeps_the_priors(tmp_path, caplog):
    assert load_error_table(tmp_path / "none.json") == {}
    bad = tmp_path / "bad.json"
    bad.write_text("{not json", encoding="utf-8")
    with caplog.at_level(logging.WARNING):
        assert load_error_table(bad) == {}
    assert "priors" in caplog.text
    nan = tmp_path / "nan.json"
    nan.write_text(json.dumps({"knobs": {"render.scale": [{"weight": float("nan")}]}}))
    assert load_error_table(nan) == {}
    assert measured_knobs({}) == governor_model.PRIOR_KNOBS


def _first_lowered(weights: dict[str, list[float]]) -> str:
    gov = Governor(knobs=measured_knobs(weights))
    user = walking("30")
    gov, _times, _history = run(user, 8, gov=gov)
    lowered = [d.knob for d in gov.history if d.action == "lower"]
    assert lowered
    return lowered[0]


def test_the_measured_errors_decide_which_knob_goes_first():
    n_scale = len(next(k for k in governor_model.PRIOR_KNOBS if k.key == "render.scale").steps)
    n_cps = len(next(k for k in governor_model.PRIOR_KNOBS if k.key == "cps.max_level").steps)
    cheap_scale = {
        "render.scale": [0.0001 * (i + 1) for i in range(n_scale)],
        "cps.max_level": [0.5 * (i + 1) for i in range(n_cps)],
    }
    cheap_cps = {
        "render.scale": [0.5 * (i + 1) for i in range(n_scale)],
        "cps.max_level": [0.0001 * (i + 1) for i in range(n_cps)],
    }
    assert _first_lowered(cheap_scale) == "render scale"
    assert _first_lowered(cheap_cps) == "coarse lighting in the periphery"


def test_the_shipped_table_covers_every_knob_with_finite_errors():
    table = load_error_table()
    # A knob whose first step the study cannot measure (UNMEASURED) keeps its priors.
    keys = {
        k.key
        for k in governor_model.PRIOR_KNOBS
        if (k.key, k.steps[0][k.key]) not in governor_study.UNMEASURED
    }
    assert set(table) == keys
    for knob in governor_model.KNOBS:
        assert len(knob.error) == len(knob.steps)
        assert all(np.isfinite(e) and e >= governor_model.MIN_STEP_ERROR for e in knob.error)


def test_the_study_writes_the_table_the_pairs_and_marks_the_governor(tmp_path, monkeypatch):
    monkeypatch.setattr(governor_study, "PRESETS", (("preset-scale-59", ("render.scale=0.59",)),))
    errors = Matrix.of(
        governor_study.SCENE,
        governor_study.PATH,
        [
            (FULL, governor_study.BASE),
            ("render.scale=0.5", (*governor_study.BASE, "render.scale=0.5")),
        ],
        frames=2,
        stride=150,
        compare_every=1,
    )
    rows = run_governor_study(tmp_path, "320x180", errors=errors, frames=3, stride=60)
    names = [r["name"] for r in rows]
    assert names[:3] == [FULL, "preset-scale-59", "governor @ preset-scale-59"]
    gov = rows[2]
    assert "render.target_fps=" in gov["settings"]
    # run once more at the matched rate where it ran over 5 % off the preset's time
    off = abs(gov["frame_ms"] / rows[1]["frame_ms"] - 1.0) > governor_study.MATCH_TOLERANCE
    assert names[3:] == (["governor @ preset-scale-59 matched"] if off else [])
    table = json.loads((tmp_path / "governor_errors.json").read_text())
    step = table["knobs"]["render.scale"]
    assert [s["value"] for s in step] == [0.5] and step[0]["flip"] > 0
    pairs = json.loads((tmp_path / "pairs.json").read_text())["pairs"]
    assert [p["preset"] for p in pairs] == ["preset-scale-59"]
    assert np.isfinite(pairs[0]["governor_periphery_flip"])
    report = (tmp_path / "report.md").read_text()
    assert "The governor at each preset's frame rate" in report
    assert "governor @ preset-scale-59" in report
    img = np.asarray(Image.open(tmp_path / "pareto.png").convert("RGB")).astype(int)
    green = (np.abs(img - (0x1E, 0x9E, 0x3C)).max(axis=2) <= 12).sum()
    assert green > 50  # the governor's point (and its legend entry) in green


def test_full_quality_undoes_every_knob_the_governor_moves():
    from app.quality import full_quality
    from app.settings import Settings

    s = Settings()
    for key, value in governor.FULL_QUALITY.items():
        s.set(key, {"render.scale": 0.5, "cps.mode": "cps", "render.lod_bias": 4}.get(key, value))
    s.set("render.shadows", "hard")
    s.set("tcr.level_bias", 2)
    ref = full_quality(s)
    for key, value in governor.FULL_QUALITY.items():
        if key != "render.upscaler":  # at full scale nothing is enlarged
            assert ref.get(key) == value, key
    s.set("render.shadows", "off")  # no shadows stays no shadows: the same scene lit alike
    assert full_quality(s).render.shadows == "off"


def test_the_governor_is_read_at_each_presets_own_frame_time():
    rows = [
        {"name": FULL, "frame_ms": 300.0, "periphery_flip": float("inf"), "fovea_flip": 0.9},
        {"name": "preset-a", "frame_ms": 200.0, "periphery_flip": 0.05, "fovea_flip": 0.04},
        {"name": "preset-b", "frame_ms": 80.0, "periphery_flip": 0.08, "fovea_flip": 0.06},
        {"name": "governor @ preset-a", "frame_ms": 150.0, "periphery_flip": 0.06},
        {"name": "governor @ preset-b", "frame_ms": 100.0, "periphery_flip": 0.10},
    ]
    curve = governor_study.governor_curve(rows, "periphery_flip")
    # Full quality closes the curve at error 0, whatever its row holds.
    assert curve == [(100.0, 0.10), (150.0, 0.06), (300.0, 0.0)]
    # Halfway between the run at 150 ms (0.06) and full quality at 300 ms (0).
    assert governor_study.at_time(curve, 225.0) == pytest.approx(0.03)
    assert governor_study.at_time(curve, 100.0) == pytest.approx(0.10)
    assert governor_study.at_time(curve, 80.0) is None  # faster than any governor run
    assert governor_study.at_time([], 80.0) is None


def test_pairs_carry_the_governor_at_the_presets_time(monkeypatch):
    monkeypatch.setattr(governor_study, "PRESETS", (("preset-a", ()), ("preset-b", ())))
    rows = [
        {"name": FULL, "frame_ms": 300.0, "periphery_flip": 0.0, "fovea_flip": 0.0},
        {"name": "preset-a", "frame_ms": 200.0, "periphery_flip": 0.05, "fovea_flip": 0.04},
        {"name": "preset-b", "frame_ms": 80.0, "periphery_flip": 0.08, "fovea_flip": 0.06},
        {
            "name": "governor @ preset-a",
            "frame_ms": 150.0,
            "periphery_flip": 0.06,
            "fovea_flip": 0.03,
        },
        {
            "name": "governor @ preset-b",
            "frame_ms": 100.0,
            "periphery_flip": 0.10,
            "fovea_flip": 0.05,
        },
    ]
    a, b = governor_study.pairs(rows)
    assert a["governor_periphery_flip_at_preset_ms"] == pytest.approx(0.06 * 2 / 3)
    assert a["governor_fovea_flip_at_preset_ms"] == pytest.approx(0.03 * 2 / 3)
    assert b["governor_periphery_flip_at_preset_ms"] is None
    row_b = governor_study._pairs_markdown([a, b]).splitlines()[-1]
    cells = [c.strip() for c in row_b.strip("|").split("|")]
    assert cells[0] == "preset-b" and cells[-2:] == ["-", "-"]


def test_settling_frames_walk_untimed_and_let_the_governor_settle():
    """``bench(settle=N)``: N frames walked before the warm-up, none of them timed; the
    governor (asked for far more than this machine draws) has lowered its knobs before the
    first timed frame, which a run without settling starts at full quality."""
    from app.lab.bench import bench
    from app.scenes import resolve_path
    from app.settings import Settings

    s = Settings()
    s.set("render.target_fps", "240")
    walk = resolve_path("showroom_walkthrough")
    settled = bench("showroom", (320, 180), 3, s, warmup=1, path=walk, settle=12)
    assert settled.frames == 3
    first = settled.per_frame[0]["knobs"]
    assert first.get("render.scale", 1.0) < 1.0, first
    assert settled.frame_budget is not None and settled.frame_budget.governor["changes"] > 0
    cold = bench("showroom", (320, 180), 3, s, warmup=0, path=walk)
    assert cold.per_frame[0]["knobs"] == {}  # its first frame drawn at full quality


def test_a_governor_off_its_presets_time_runs_once_more_at_the_matched_rate(monkeypatch):
    """Asked for a preset's 20 fps the governor ran at 40 ms (it aims below the budget): it is
    asked once more for 16 fps, the rate that would bring it to the preset's 50 ms; one within
    5 % is not. The pair then shows the run nearest the preset's time."""
    monkeypatch.setattr(governor_study, "PRESETS", (("preset-a", ()), ("preset-b", ())))
    rows = [
        {"name": FULL, "frame_ms": 300.0, "periphery_flip": 0.0, "fovea_flip": 0.0},
        _row("preset-a", 0.08, ms=50.0),
        _row("preset-b", 0.05, ms=100.0),
        _row("governor @ preset-a", 0.10, ms=40.0),
        _row("governor @ preset-b", 0.04, ms=97.0),
    ]
    matched = governor_study.matched_runs(rows)
    assert matched == [("governor @ preset-a matched", ("render.target_fps=16.000",))]

    rows.append(_row("governor @ preset-a matched", 0.07, fovea=0.02, ms=49.0))
    a, b = governor_study.pairs(rows)
    assert a["governor_ms"] == 49.0 and a["governor_periphery_flip"] == 0.07
    # read on the curve through every governor run: 49 ms (0.07) and 97 ms (0.04)
    assert a["governor_periphery_flip_at_preset_ms"] == pytest.approx(0.07 - 0.03 / 48)
    assert b["governor_ms"] == 97.0
