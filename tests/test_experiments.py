"""The benchmark tables: CPS and TCR benches with error figures, the report, the run lists."""

from __future__ import annotations

import json

from app.lab.cli import main
from app.lab.experiments import EXPERIMENTS
from app.scenes import resolve_path
from app.settings import Settings


def test_every_experiment_run_is_a_valid_bench(tmp_path):
    for which, runs in EXPERIMENTS.items():
        names = [r.name for r in runs()]
        assert len(names) == len(set(names)), which
        for run in runs():
            s = Settings()
            s.apply(list(run.sets))  # raises on a bad key or value
            assert resolve_path(run.path).frame_count() > 0
            assert run.command().startswith("vrpreview bench --scene")


def test_cps_bench_reports_fovea_and_periphery_errors_and_the_report_tabulates_it(tmp_path, capsys):
    out = tmp_path / "cps.json"
    assert (
        main(
            [
                "bench",
                "--scene",
                "showroom",
                "--frames",
                "4",
                "--warmup",
                "1",
                "--stride",
                "30",
                "--size",
                "320x180",
                "--compare-every",
                "2",
                "--set",
                "cps.mode=cps",
                "--set",
                "render.lighting=fragment",
                "--out",
                str(out),
            ]
        )
        == 0
    )
    r = json.loads(out.read_text())
    assert [f["path_frame"] for f in r["per_frame"]] == [0, 30, 60, 90] and r["stride"] == 30
    err = r["error_vs_full_quality"]
    assert err["fovea_max_abs_diff"] == 0  # full-rate pixels are the full-rate frame's
    assert err["periphery"]["frames"] == 2 and err["periphery"]["psnr_db"] < 60
    assert 0 < r["shaded_samples"] < 320 * 180  # lighting once per block, not per pixel
    capsys.readouterr()
    assert main(["report", str(out)]) == 0
    table = capsys.readouterr().out
    assert "periphery PSNR dB" in table and "| cps |" in table
