"""The command line as a user runs it: render, bench, demo, and clear errors."""

from __future__ import annotations

import json

import numpy as np
import pytest
from PIL import Image

from app.lab import bench as bench_mod
from app.lab.cli import main


def test_render_writes_a_stereo_png_and_frame_n_is_deterministic(tmp_path):
    a, b = tmp_path / "a.png", tmp_path / "b.png"
    for out in (a, b):
        assert (
            main(
                [
                    "render",
                    "--scene",
                    "texture-test",
                    "--out",
                    str(out),
                    "--size",
                    "320x180",
                    "--frame",
                    "90",
                ]
            )
            == 0
        )
    img = np.asarray(Image.open(a))
    assert img.shape == (180, 320, 3) and img.std() > 10
    assert np.array_equal(img, np.asarray(Image.open(b)))
    c = tmp_path / "c.png"
    main(
        [
            "render",
            "--scene",
            "texture-test",
            "--out",
            str(c),
            "--size",
            "320x180",
            "--frame",
            "150",
        ]
    )
    assert not np.array_equal(img, np.asarray(Image.open(c)))  # the path moves the camera


def test_bench_writes_the_documented_fields(tmp_path):
    out = tmp_path / "bench.json"
    assert (
        main(
            [
                "bench",
                "--scene",
                "texture-test",
                "--frames",
                "6",
                "--warmup",
                "1",
                "--size",
                "320x180",
                "--set",
                "render.path=forward",
                "--out",
                str(out),
            ]
        )
        == 0
    )
    r = json.loads(out.read_text())
    assert r["frames"] == 6 and r["fps_median"] > 0
    assert r["frame_ms"]["p95"] >= r["frame_ms"]["median"] > 0
    # The forward path with its shadow maps (on by default).
    assert set(r["passes"]) == {"shadows", "forward", "present", "overlay"}
    assert all(p["median_ms"] >= 0 for p in r["passes"].values())
    assert r["texture_resident_bytes"] > 0 and r["shaded_samples"] > 0
    assert r["settings"]["render"]["path"] == "forward" and r["errors"] == []
    assert 0 < r["scene_load_s"] < 600  # the showroom's texture set is built in that time


@pytest.mark.parametrize(
    "args, message",
    [
        (["render", "--scene", "/nope/missing.glb", "--out", "x.png"], "missing.glb"),
        (
            ["render", "--scene", "texture-test", "--out", "x.png", "--set", "stereo.ipd=1"],
            "unknown setting",
        ),
        (["render", "--scene", "texture-test", "--out", "x.png", "--size", "big"], "size must"),
        (
            ["bench", "--scene", "texture-test", "--out", "x.json", "--path", "nothere.json"],
            "cannot read path",
        ),
    ],
)
def test_bad_input_is_a_clear_error_not_a_traceback(args, message, capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main(args) == 2
    err = capsys.readouterr().err
    assert err.startswith("vrpreview: error:") and message in err


def test_without_a_display_the_walkthrough_runs_headless(tmp_path, monkeypatch, capsys):
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    monkeypatch.chdir(tmp_path)
    real_demo = bench_mod.demo

    def small_demo(scene, out_dir, size, settings, **kw):
        return real_demo(scene, out_dir, (256, 144), settings, **kw)  # keep the test quick

    monkeypatch.setattr(bench_mod, "demo", small_demo)
    assert main(["--scene", "texture-test"]) == 0
    assert "no display" in capsys.readouterr().err
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert summary["frames"] > 100 and summary["fps_median"] > 0
    shots = [tmp_path / "out" / s for s in summary["screenshots"]]
    assert len(shots) >= 5 and all(s.exists() for s in shots)
    assert np.asarray(Image.open(shots[0])).shape == (144, 256, 3)


def test_render_with_automatic_exposure_shows_the_sunlit_room_metered(tmp_path):
    """`render` draws one frame; with automatic exposure that frame is shown at the EV the
    room meters (the first frame starts from the fixed EV, -1.3: a sunlit room came out
    white). The same frame at the fixed EV stays white, which is what the meter is for."""
    shots = {}
    for mode in ("auto", "manual"):
        out = tmp_path / f"{mode}.png"
        args = ["render", "--scene", "showroom", "--out", str(out), "--size", "320x180"]
        args += ["--set", "sky.enabled=true", "--set", f"render.exposure_mode={mode}"]
        assert main(args) == 0
        shots[mode] = np.asarray(Image.open(out)).astype(float)
    assert shots["manual"].mean() > 240  # the sun at EV -1.3
    assert 40 < shots["auto"].mean() < 200 and shots["auto"].std() > 20
