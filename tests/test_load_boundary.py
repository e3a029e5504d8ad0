"""``load_scene`` is the boundary: whatever breaks inside, the caller gets one SceneLoadError
naming the file (the traceback goes to the log), or LoadCancelled; progress runs 0 to 1."""

from __future__ import annotations

import logging
import threading

import pytest

import app.loaders
from app.loaders import LoadCancelled, LoadOptions, SceneLoadError, load_scene
from app.progress import Progress
from app.settings import Settings
from tests.test_scene_switch import box_obj


@pytest.mark.parametrize("error", [KeyError("node"), IndexError("face 9"), AttributeError("x")])
def test_an_unexpected_error_inside_becomes_one_sentence_naming_the_file(
    tmp_path, monkeypatch, caplog, error
):
    def broken(*_a, **_k):  # a bug while placing the geometry
        raise error

    monkeypatch.setattr(app.loaders, "place", broken)
    with caplog.at_level(logging.ERROR), pytest.raises(SceneLoadError) as info:
        load_scene(box_obj(tmp_path / "Kitchen v2.obj", 2))
    message = str(info.value)
    assert message.startswith("Cannot open 'Kitchen v2.obj':")
    assert type(error).__name__ in message and "log" in message
    assert "\n" not in message
    traced = [r for r in caplog.records if r.exc_info]
    assert traced and traced[0].exc_info[0] is type(error)  # the details are in the log
    for r in caplog.records:
        r.expected = True


def test_a_memory_or_recursion_error_is_explained(tmp_path, monkeypatch):
    for error, words in ((MemoryError(), "more memory"), (RecursionError(), "nested too deeply")):

        def broken(*_a, _e=error, **_k):
            raise _e

        monkeypatch.setattr(app.loaders, "place", broken)
        with pytest.raises(SceneLoadError, match=words):
            load_scene(box_obj(tmp_path / "room.obj", 1))


def test_progress_rises_to_one_and_names_its_stages(tmp_path):
    seen: list[tuple[float, str]] = []
    scene = load_scene(
        box_obj(tmp_path / "room.obj", 3), progress=Progress(lambda f, t: seen.append((f, t)))
    )
    fractions = [f for f, _t in seen]
    assert fractions == sorted(fractions) and fractions[0] == 0.0 and fractions[-1] == 1.0
    texts = " / ".join(t for _f, t in seen)
    assert "Reading room.obj" in texts and "Finding where to stand" in texts
    assert scene.triangle_count > 0


def test_a_cancelled_load_stops_with_load_cancelled(tmp_path):
    cancel = threading.Event()
    stages: list[str] = []

    def report(_f: float, text: str) -> None:
        stages.append(text)
        if text == "Checking geometry":
            cancel.set()  # the user pressed Cancel while the geometry was checked

    with pytest.raises(LoadCancelled):
        load_scene(box_obj(tmp_path / "room.obj", 3), progress=Progress(report, cancel))
    assert "Finding where to stand" not in stages


def test_load_options_follow_the_scene_settings():
    s = Settings()
    assert LoadOptions.from_settings(s.scene).unit_scale is None  # auto
    s.set("scene.unit_scale", "0.01")
    s.set("scene.max_texture_px", 2048)
    options = LoadOptions.from_settings(s.scene)
    assert options.unit_scale == 0.01 and options.max_texture_px == 2048


def test_unit_scale_turns_centimetres_into_metres(tmp_path):
    path = box_obj(tmp_path / "room.obj", 1)
    metres = load_scene(path)
    cm = load_scene(path, LoadOptions(unit_scale=0.01))
    (lo_m, hi_m), (lo_c, hi_c) = metres.bounds(), cm.bounds()
    assert cm.unit_scale == 0.01
    assert (hi_c - lo_c) == pytest.approx((hi_m - lo_m) * 0.01, rel=1e-5)
