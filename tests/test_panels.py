"""Panels are built one way from the settings metadata and show a refused value, never raise.

An exception escaping a PyQt6 slot aborts the process, so each case drives the real signal
with a value the model refuses (as a widget might deliver one) and checks the panel's status
line, the model and the control afterwards. No GL is needed: the panels are built alone.
"""

from __future__ import annotations

import pytest
from PyQt6.QtWidgets import QCheckBox, QComboBox, QDoubleSpinBox, QSpinBox

from app.cps import MAX_LEVEL
from app.session import Session
from app.settings import Settings
from ui.cps_panel import CpsPanel
from ui.panels import SettingsForm, SettingsPanel, setting_label
from ui.photon_panel import PhotonPanel
from ui.tcr_panel import TcrPanel


@pytest.fixture
def settings() -> Settings:
    return Settings()


def _panels(settings: Settings, qtbot, changes: list[str]) -> dict:
    panels = {
        "settings": SettingsPanel(settings, ("stereo", "render"), changes.append),
        "tcr": TcrPanel(Session(settings), changes.append),
        "cps": CpsPanel(settings, dict, changes.append),
        "photons": PhotonPanel(settings, dict, changes.append),
    }
    for panel in panels.values():
        qtbot.addWidget(panel)
    return panels


def test_controls_come_from_the_metadata(settings, qtbot):
    form = SettingsForm(settings)
    ipd = form.control("stereo.ipd_mm")
    assert isinstance(ipd, QDoubleSpinBox) and (ipd.minimum(), ipd.maximum()) == (0.0, 100.0)
    assert ipd.toolTip() == settings.explain("stereo.ipd_mm")
    assert ipd.toolTip().startswith("How far apart the two eye cameras are")
    assert ipd.suffix() == " mm" and ipd.decimals() == 1
    assert isinstance(form.control("cps.rays_per_side"), QSpinBox)
    assert isinstance(form.control("render.overlay"), QCheckBox)
    lighting = form.control("render.lighting")
    assert isinstance(lighting, QComboBox)
    assert [lighting.itemData(i) for i in range(lighting.count())] == ["compute", "fragment"]
    assert lighting.currentText() == "Graphics pipeline (fragment shader)"  # the choice's label
    f = form.control("tcr.f_m")
    assert f.minimum() == pytest.approx(0.01)  # the model's 1e-6, rounded up to what it shows
    assert setting_label(settings, "tcr.f_m") == "Eye-to-screen distance"
    assert setting_label(settings, "stereo.ipd_mm") == "Distance between the eyes"
    # A fraction shown in per cent, in whole numbers: brightness 1.0 is "100%".
    brightness = form.control("render.brightness")
    assert isinstance(brightness, QSpinBox) and brightness.text() == "100%"
    brightness.setValue(50)
    assert settings.render.brightness == pytest.approx(0.5)


def test_cps_levels_follow_the_model(settings, qtbot):
    panel = CpsPanel(settings, dict)
    qtbot.addWidget(panel)
    assert panel.max_level.count() == MAX_LEVEL + 1
    assert panel.max_level.currentData() == settings.cps.max_level


@pytest.mark.parametrize(
    ("name", "control", "key", "bad"),
    [
        ("settings", lambda p: p.editors["stereo.ipd_mm"], "stereo.ipd_mm", -5.0),
        ("settings", lambda p: p.editors["render.path"], "render.path", -1),
        ("tcr", lambda p: p.f, "tcr.f_m", 1e9),
        ("settings", lambda p: p.editors["render.brightness"], "render.brightness", -50),
        ("tcr", lambda p: p.mode, "tcr.mode", -1),
        ("cps", lambda p: p.fovea, "cps.fovea_deg", -1.0),
        ("cps", lambda p: p.max_level, "cps.max_level", -1),
        ("cps", lambda p: p.rays, "cps.rays_per_side", 0),
        ("photons", lambda p: p.controls.editors["photons.radius_m"], "photons.radius_m", 0.0),
    ],
)
def test_a_refused_value_is_shown_and_does_not_raise(settings, qtbot, name, control, key, bad):
    changes: list[str] = []
    panel = _panels(settings, qtbot, changes)[name]
    before = settings.get(key)
    w = control(panel)
    # What the widget would send: the combo boxes' index -1 carries no choice at all.
    signal = w.currentIndexChanged if isinstance(w, QComboBox) else w.valueChanged
    signal.emit(bad)
    status = panel.form.status if hasattr(panel, "form") else panel.controls.status
    # Named by its label, not its key.
    assert not status.isHidden() and settings.label(key) in status.text()
    assert key not in status.text()
    assert settings.get(key) == before and changes == []
    if isinstance(w, QComboBox):
        assert w.currentData() == before  # the control shows the model's value again
    # The next accepted edit clears the message.
    good = {"stereo.ipd_mm": 60.0, "tcr.f_m": 2.0, "cps.fovea_deg": 12.0}
    if key in good:
        w.setValue(good[key])
        assert settings.get(key) == good[key] and changes == [key] and status.isHidden()
