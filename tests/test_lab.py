"""The lab's reference cache and result schema."""

from __future__ import annotations

import json
import math

from app import scenes
from app.lab.reference import ConvergedPhotons
from app.lab.results import MeanErrors
from app.lab.runs import Run, named_runs
from app.quality import ErrorFigures
from app.settings import Settings


def test_converged_photons_are_traced_once_per_scene_and_settings():
    cache = ConvergedPhotons()
    scene = scenes.resolve("showroom-gi")
    s = Settings().photons
    s.photons = 1024
    first = cache.get(s, "showroom-gi", scene)
    assert first is not None and cache.get(s, "showroom-gi", scene) is first
    assert cache.traced == 1
    s.seed += 1
    assert cache.get(s, "showroom-gi", scene) is not first and cache.traced == 2
    s.enabled = "off"
    assert cache.get(s, "showroom-gi", scene) is None and cache.traced == 2


def test_mean_errors_one_spelling_and_identical_frames():
    rows = [ErrorFigures(math.inf, 1.0, 0.0, 10), ErrorFigures(30.0, 0.9, 0.1, 10)]
    m = MeanErrors.of(rows).to_dict()
    assert m == {"frames": 2, "identical_frames": 1, "psnr_db": 30.0, "ssim": 0.95, "flip": 0.05}
    assert MeanErrors.of([]).to_dict() == {"frames": 0}
    assert "psnr" not in json.dumps(m).replace("psnr_db", "")


def test_one_run_type_for_named_runs():
    runs = named_runs("showroom", "showroom_walkthrough", [("a", ("cps.mode=cps",))], stride=3)
    assert runs == (Run("a", "showroom", "showroom_walkthrough", ("cps.mode=cps",), stride=3),)
    assert runs[0].settings().cps.mode == "cps"
    assert "--stride 3" in runs[0].command()
