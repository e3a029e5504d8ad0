"""The speed/accuracy study: files a user opens, the Pareto front, and resuming."""

from __future__ import annotations

import csv
import json

import numpy as np
import pytest
from PIL import Image

from app.lab import study
from app.lab.study import FULL, Matrix, pareto, run_study


def tiny() -> Matrix:
    return Matrix.of(
        "showroom",
        "showroom_walkthrough",
        [
            (FULL, ("cps.mode=none",)),
            ("cps-block16", ("cps.mode=cps", "cps.max_level=4")),
            ("black-mask", ("cps.mode=black-mask",)),
        ],
        frames=2,
        stride=150,
        compare_every=1,
    )


def test_study_writes_results_table_plot_and_resumes(tmp_path, monkeypatch):
    seen = []
    rows = run_study("cps", tmp_path, "320x180", lambda i, n, name: seen.append(name), tiny())
    assert [r["name"] for r in rows] == [FULL, "cps-block16", "black-mask"]
    assert seen == [FULL, "cps-block16", "black-mask"]
    data = json.loads((tmp_path / "results.json").read_text())
    assert FULL in data["pareto"]  # no error at all: always on the front
    cps = next(r for r in rows if r["name"] == "cps-block16")
    assert cps["fovea_max_diff"] == 0 and cps["periphery_flip"] > 0
    assert cps["shaded_samples"] < rows[0]["shaded_samples"]
    with open(tmp_path / "results.csv", newline="") as f:
        table = list(csv.DictReader(f))
    assert [r["name"] for r in table] == [FULL, "cps-block16", "black-mask"]
    assert "cps-block16" in (tmp_path / "report.md").read_text()
    img = np.asarray(Image.open(tmp_path / "pareto.png"))
    assert img.shape == (600, 900, 3) and img.std() > 5
    front_red = (np.abs(img.astype(int) - (220, 30, 30)).max(axis=2) <= 12).sum()
    assert front_red > 100  # the Pareto front is drawn (in red)

    # Interrupted after the first run: only the missing ones run again.
    data["rows"] = data["rows"][:1]
    (tmp_path / "results.json").write_text(json.dumps(data))
    ran = []
    real = study.bench
    monkeypatch.setattr(study, "bench", lambda *a, **k: ran.append(1) or real(*a, **k))
    rows = run_study("cps", tmp_path, "320x180", None, tiny())
    assert len(ran) == 2 and [r["name"] for r in rows] == [FULL, "cps-block16", "black-mask"]


@pytest.mark.parametrize(
    ("points", "front"),
    [
        ([("a", 10, 0.1), ("b", 5, 0.2), ("c", 6, 0.3), ("d", 20, 0.0)], ["b", "a", "d"]),
        ([("a", 1, 0.5), ("b", 1, 0.5)], ["a", "b"]),  # equal points dominate neither
        ([("a", 1, float("nan")), ("b", 2, 0.1)], ["b"]),  # no error figure: not plotted
    ],
)
def test_pareto_front(points, front):
    rows = [{"name": n, "frame_ms": t, "flip": e} for n, t, e in points]
    assert pareto(rows) == front
