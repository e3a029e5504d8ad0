"""Every control in the panels speaks a designer's language (issue 13, plain language).

What a new user would check, in the real window: hovering any control gives a tooltip that
explains it in a sentence, in lines that fit the screen, without a settings key, a formula
or a program name; no label shows a key; whole numbers are shown as whole numbers; there is
one brightness control. Plus a picture of the Settings tab against its reference.
"""

from __future__ import annotations

import re

import numpy as np
import pytest
from PyQt6.QtCore import Qt
from PyQt6.QtGui import QFontMetrics
from PyQt6.QtWidgets import (
    QAbstractButton,
    QCheckBox,
    QComboBox,
    QDoubleSpinBox,
    QFormLayout,
    QGroupBox,
    QLabel,
    QPushButton,
    QRadioButton,
    QSlider,
    QSpinBox,
    QTabWidget,
    QToolTip,
    QWidget,
)

from app.lab.cli import main as cli_main
from app.session import Session
from app.settings import Settings, SettingsError
from app.tcr import TcrTerms, level_for
from tests.test_gui import qimage_to_array
from tests.test_render import checker_scene
from ui.main_window import MainWindow
from ui.panels import SettingsPanel
from ui.tcr_panel import TcrPanel

INPUTS = (QCheckBox, QComboBox, QSpinBox, QDoubleSpinBox, QSlider, QPushButton, QRadioButton)
KEY = re.compile(r"\b[a-z]+\.[a-z_]+\b")  # render.lighting, cps.max_level
FORMULA = re.compile(r"\^|_|\*\*|\bself\b|\bNone\b|\bTrue\b|\bFalse\b")  # 2^n, max_level
MAX_LINE = 80  # characters per tooltip line as shown
MAX_LINE_PX = 640  # and in pixels, in the tooltip's font
SETTINGS_SECTIONS = ("stereo", "render", "navigation", "gaze", "scene")  # the Settings tab


@pytest.fixture
def window(qtbot):
    settings = Settings()
    settings.render.overlay = False
    w = MainWindow(settings, checker_scene())
    qtbot.addWidget(w)
    w.resize(1366, 768)
    w.show()
    qtbot.waitExposed(w)
    yield w
    w.close()


def _raw_forms(settings: Settings) -> set[str]:
    """How a key would read if a panel showed it: "walk speed mps", "ipd mm", "render.path"."""
    out = set()
    for key in settings.keys():
        out.add(key)
        last = key.rsplit(".", 1)[-1]
        if "_" in last:
            out.add(last.replace("_", " "))
    return out


def _dock_tabs(window: MainWindow) -> QTabWidget:
    # The dock's tab widget, however it is wrapped (a scroll area, say).
    tabs = window.dock.widget()
    if not isinstance(tabs, QTabWidget):
        tabs = window.dock.findChild(QTabWidget)
    assert isinstance(tabs, QTabWidget) and tabs.count() >= 5
    return tabs


def _row_label(widget: QWidget) -> str:
    """The text naming ``widget``: its own (a check box, a button) or its form row's label."""
    if isinstance(widget, QAbstractButton) and widget.text():
        return widget.text()
    parent = widget.parentWidget()
    while parent is not None:
        layout = parent.layout()
        if isinstance(layout, QFormLayout):
            label = layout.labelForField(widget)
            if isinstance(label, QLabel):
                return label.text()
        parent = parent.parentWidget()
    return ""


def _tooltip_problems(tip: str, font_metrics: QFontMetrics) -> list[str]:
    problems = []
    if not tip.strip():
        return ["no tooltip"]
    if Qt.mightBeRichText(tip):
        problems.append("rich text (its lines are not the ones checked here)")
    if KEY.search(tip):
        problems.append(f"names a key: {KEY.search(tip).group(0)!r}")  # type: ignore[union-attr]
    if FORMULA.search(tip):
        problems.append(f"formula or program name: {FORMULA.search(tip).group(0)!r}")  # type: ignore[union-attr]
    for line in tip.splitlines():
        if len(line) > MAX_LINE or font_metrics.horizontalAdvance(line) > MAX_LINE_PX:
            problems.append(f"line too long ({len(line)} chars): {line!r}")
    return problems


def test_every_setting_has_words_for_a_designer():
    s = Settings()
    raw = _raw_forms(s)
    for key in s.keys():
        meta = s.describe(key)
        assert meta.get("label"), f"{key}: a setting needs a label in words"
        label, help_text = s.label(key), str(meta["help"])
        assert label and label[0].isupper() and "_" not in label and label not in raw, key
        assert help_text.endswith(".") and not KEY.search(help_text), key
        assert not FORMULA.search(help_text), (key, help_text)
        value = s.get(key)
        if isinstance(value, float):
            assert "decimals" in meta, f"{key}: a float needs its decimals"
        for line in s.explain(key).splitlines():
            assert len(line) <= 60, (key, line)
    # The paper's terms are in the tooltips, with the range in the unit shown.
    assert "TCR paper: distance term d." in s.explain("tcr.use_d")
    assert "Range: 0 to 1,600%." in s.explain("render.brightness")
    assert "Range: 0 to 4,194,304 photons." in s.explain("photons.photons")


def test_every_control_in_the_dock_explains_itself(window):
    """Hover every control of every tab: a tooltip in short lines, no key, no formula."""
    tabs = _dock_tabs(window)
    fm = QFontMetrics(QToolTip.font())
    raw = _raw_forms(window.settings)
    problems: list[str] = []
    controls = 0
    for index in range(tabs.count()):
        tab_name = tabs.tabText(index)
        page = tabs.widget(index)
        for w in page.findChildren(QWidget):
            if isinstance(w, INPUTS):
                controls += 1
                where = f"{tab_name} / {_row_label(w) or type(w).__name__}"
                problems += [f"{where}: {p}" for p in _tooltip_problems(w.toolTip(), fm)]
            texts = []
            if isinstance(w, (QLabel, QAbstractButton)):
                texts.append(w.text())
            if isinstance(w, QGroupBox):
                texts.append(w.title())
            if isinstance(w, QComboBox) and not w.isEditable():
                texts += [w.itemText(i) for i in range(w.count())]
            for text in texts:
                plain = text.strip()
                if "_" in plain or KEY.search(plain) or plain in raw:
                    problems.append(f"{tab_name}: a label shows a key: {plain!r}")
    assert controls > 50  # every tab was walked (about 60 controls today)
    # The evaluation bar under the view: each figure says what it is.
    window.eval_bar.refresh()
    for name, label in window.eval_bar.labels.items():
        problems += [f"bar / {name}: {p}" for p in _tooltip_problems(label.toolTip(), fm)]
    assert window.eval_bar.labels["phase"].text() == "Adaptive textures: off"
    assert window.eval_bar.labels["state"].text() == "State 0: standing, eyes wandering"
    assert not problems, "\n".join(problems)


def test_whole_numbers_are_shown_as_whole_numbers_and_one_control_per_setting(window):
    s = window.settings
    forms = {
        "Settings": window.panel.editors,
        "TCR": {
            **window.tcr_panel.form.editors,
            **{f"tcr.use_{t}": cb for t, cb in window.tcr_panel.terms.items()},
        },
        "CPS": window.cps_panel.controls,
        "Photons": window.photon_panel.controls.editors,
        "Sun and sky": window.sky_panel.editors,
    }
    seen: dict[str, list[str]] = {}
    for tab, editors in forms.items():
        for key in editors:
            seen.setdefault(key, []).append(tab)
    # Every setting the panels show has exactly one control; hidden ones have none.
    assert {k: v for k, v in seen.items() if len(v) != 1} == {}
    assert set(seen) == set(s.shown_keys())
    assert "render.exposure" not in seen  # command line and presets only
    for key, (tab,) in seen.items():
        w = forms[tab][key]
        value = s.get(key)
        if isinstance(value, int) and not isinstance(value, bool):
            # An int is a whole-number spin box (or a list of named entries).
            assert isinstance(w, (QSpinBox, QComboBox)), key
            assert not isinstance(w, QDoubleSpinBox), key
    photons = window.photon_panel.controls.editors["photons.photons"]
    assert photons.text() == "262,144 photons"
    assert window.photon_panel.controls.editors["photons.seed"].text() == "0"
    assert window.panel.editors["stereo.fov_deg"].text() == "95°"
    assert window.panel.editors["stereo.ipd_mm"].text() == "64.0 mm"


def test_exactly_one_brightness_control(window):
    tabs = _dock_tabs(window)
    named, exposure = [], []
    for index in range(tabs.count()):
        for w in tabs.widget(index).findChildren(QWidget):
            if isinstance(w, INPUTS) and re.search(r"bright", _row_label(w), re.I):
                named.append((tabs.tabText(index), _row_label(w), w))
            if isinstance(w, INPUTS) and re.search(r"exposure", _row_label(w), re.I):
                exposure.append((tabs.tabText(index), _row_label(w)))
    assert [(tab, name) for tab, name, _w in named] == [("Settings", "Brightness")]
    # Beside it, how the picture is exposed: automatic or at a fixed value (in EV), which
    # Brightness then compensates; no second brightness anywhere.
    assert exposure == [("Settings", "Exposure"), ("Settings", "Fixed exposure value")]
    control = named[0][2]
    assert isinstance(control, QSpinBox) and control.text() == "100%"
    control.setValue(40)
    assert window.settings.render.brightness == pytest.approx(0.4)
    # The TCR tab says what the light rule reads, and where to change it.
    window.tcr_panel.poll()
    assert window.tcr_panel.brightness.text().startswith("40%")


def test_the_tcr_readout_is_in_words():
    terms = TcrTerms(d=True, v=True, g=True, l=True)
    reason = level_for(8.0, 1.0, 9, moving=True, gazed_fixed=False, brightness=1.0, terms=terms)
    text = reason.plain("sofa")
    assert text == (
        "sofa: texture level 4 of 9 (0 is full detail) from distance +3, motion +1, "
        "gaze +0, dim light +0"
    )
    far = level_for(
        float("inf"), 1.0, 5, moving=False, gazed_fixed=False, brightness=1.0, terms=terms
    )
    assert far.plain("wall") == (
        "wall: texture level 5 of 5 (0 is full detail) from distance coarsest, motion +0, "
        "gaze +0, dim light +0; 5 is its coarsest"
    )


def test_the_tcr_panel_shows_the_gazed_objects_level_in_words(qtbot):
    session = Session(Settings())
    session.set_scene(checker_scene())
    panel = TcrPanel(session)
    qtbot.addWidget(panel)
    panel.enabled.setChecked(True)
    session.tick(1 / 60)
    session.gazed = 0
    panel.poll()
    text = panel.readout.text()
    assert "texture level" in text and "0 is full detail" in text
    assert "clamped" not in text and " v " not in text
    assert panel.phase.text() == "Rules in use: Ergonomics (distance, motion, light)"


def test_old_and_hidden_keys_still_work_on_the_command_line(tmp_path, capsys):
    """The words changed, the keys did not: --list-settings, --set and presets."""
    assert cli_main(["--list-settings"]) == 0
    out = capsys.readouterr().out
    assert "render.exposure = 1.0" in out and "render.brightness = 1.0" in out
    assert "navigation.walk_speed_mps = 1.4  # How fast" in out
    s = Settings()
    s.apply(["render.exposure=2", "render.brightness=0.5", "photons.photons=4096"])
    path = tmp_path / "preset.json"
    s.save(path)
    loaded = Settings.load(path)
    assert (loaded.render.exposure, loaded.render.brightness) == (2.0, 0.5)
    with pytest.raises(SettingsError, match="render.brightness"):
        s.set("render.brightness", -1)  # the CLI's errors still name the key


def test_a_hidden_setting_from_a_preset_is_mentioned_in_the_settings_tab(qtbot):
    s = Settings()
    panel = SettingsPanel(s, SETTINGS_SECTIONS)
    qtbot.addWidget(panel)
    assert panel.hidden_note.isHidden()  # nothing set outside the panels
    s.apply(["render.exposure=2"])
    panel.refresh()  # as after loading a preset
    assert not panel.hidden_note.isHidden()
    assert (
        panel.hidden_note.text()
        == "Also set on the command line or by a preset: Exposure factor 2×."
    )


def test_a_refused_value_is_named_by_its_label(qtbot):
    panel = SettingsPanel(Settings(), SETTINGS_SECTIONS)
    qtbot.addWidget(panel)
    panel.editors["render.brightness"].valueChanged.emit(-50)
    assert panel.status.text() == "Brightness: -50% is not possible. Range: 0 to 1,600%."


def test_settings_tab_looks_as_designed(qtbot, compare_reference):
    """The Settings tab at a fixed size: labels in words, units, whole numbers."""
    panel = SettingsPanel(Settings(), SETTINGS_SECTIONS)
    qtbot.addWidget(panel)
    panel.setFixedSize(520, 900)
    panel.show()
    qtbot.waitExposed(panel)
    shot = qimage_to_array(panel.grab().toImage())
    assert shot.shape == (900, 520, 3)
    assert shot.std() > 10  # something was drawn
    compare_reference(
        "settings_tab_520x900", np.ascontiguousarray(shot), max_mean=1.0, max_frac=0.003
    )
