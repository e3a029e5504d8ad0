import json

import pytest

from app.settings import Settings, SettingsError


def test_dotted_keys_get_and_set_with_types():
    s = Settings()
    assert s.get("stereo.ipd_mm") == 64.0
    s.set("stereo.ipd_mm", "60.5")
    assert s.stereo.ipd_mm == 60.5
    s.set("render.overlay", "off")
    assert s.render.overlay is False
    s.apply(["render.path=forward", "navigation.eye_height_m=1.7"])
    assert s.render.path == "forward" and s.navigation.eye_height_m == 1.7
    assert "stereo.ipd_mm" in s.keys() and "render.lighting" in s.keys()


@pytest.mark.parametrize(
    "assignment, message",
    [
        ("stereo.nope=1", "unknown setting"),
        ("stereo=1", "section"),
        ("stereo.ipd_mm=abc", "cannot use"),
        ("stereo.ipd_mm=nan", "cannot use"),
        ("stereo.ipd_mm=1e9", "outside"),
        ("render.path=raytrace", "not one of"),
        ("render.overlay=maybe", "cannot use"),
        ("stereo.ipd_mm", "expected key=value"),
    ],
)
def test_bad_assignments_are_clear_errors(assignment, message):
    s = Settings()
    with pytest.raises(SettingsError, match=message):
        s.apply([assignment])
    assert s.stereo.ipd_mm == 64.0  # nothing half-applied


def test_preset_round_trip_and_atomic_file(tmp_path):
    s = Settings()
    s.set("stereo.fov_deg", 100)
    s.set("render.lighting", "fragment")
    path = tmp_path / "preset.json"
    s.save(path)
    assert Settings.load(path).to_dict() == s.to_dict()
    assert not list(tmp_path.glob(".*.tmp"))  # the temp file was renamed, not left behind
    path.write_text(json.dumps({"settings": {"stereo": {"ipd_mm": "wide"}}}))
    with pytest.raises(SettingsError):
        Settings.load(path)
    path.write_text("{ broken")
    with pytest.raises(SettingsError, match="cannot read"):
        Settings.load(path)
