"""The experimenter's path through the window: protocol from the template, four participants
driven by keystrokes (pytest-qt), the Esc stop, then the report with plots."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from PyQt6.QtCore import Qt
from PyQt6.QtWidgets import QApplication, QMessageBox

from app.lab.cli import main
from app.settings import Settings
from app.survey.questionnaires import questionnaire
from ui.main_window import MainWindow
from ui.survey_dialogs import MessageDialog, QuestionnaireDialog, RestDialog
from ui.survey_runner import SetupDialog, SurveyRunner

EXPOSURE_S = 1.5


@pytest.fixture
def window(qtbot):
    w = MainWindow(Settings())
    qtbot.addWidget(w)
    w.view.setFixedSize(320, 180)  # llvmpipe: small is quick
    w.show()
    qtbot.waitExposed(w)
    qtbot.waitUntil(lambda: w.view.renderer is not None, timeout=10000)
    yield w
    w.close()


def make_protocol(tmp_path: Path) -> Path:
    """What an experimenter does: the template, with shorter times typed in."""
    path = tmp_path / "study.toml"
    assert main(["survey", "template", "--out", str(path)]) == 0
    text = path.read_text(encoding="utf-8")
    text = text.replace("exposure_s = 60 ", f"exposure_s = {EXPOSURE_S} ")
    text = text.replace("rest_s = 120 ", "rest_s = 0.3 ")
    path.write_text(text, encoding="utf-8")
    return path


def menu_action(window, text: str):
    for menu_action_ in window.menuBar().actions():
        menu = menu_action_.menu()
        if menu is None:
            continue
        for a in menu.actions():
            if a.text().startswith(text):
                return a
    raise AssertionError(f"no menu entry {text}")


def rating(pid_n: int, condition: str, q, n: int) -> int:
    """A simulated participant: CPS makes them a little less sick and they like it better."""
    if q.key == "ssq":
        return min(3, (n + pid_n) % 3 // 2 + (condition == "none") * ((n + pid_n) % 2))
    return min(5, 2 + (condition == "cps") + (n + pid_n) % 2)


def drive(qtbot, runner: SurveyRunner, pid_n: int, stop_in_run: int | None = None) -> list:
    """Answer every page with keystrokes until the runner is finished."""
    seen = []
    while runner.finished is None:
        QApplication.processEvents()
        d = runner.dialog
        if runner.exposing is not None:
            if stop_in_run is not None and runner.exposing.position == stop_in_run:
                qtbot.wait(200)
                qtbot.keyClick(runner.window.view, Qt.Key.Key_Escape)  # "I feel unwell, stop"
            else:
                qtbot.wait(50)
            continue
        if isinstance(d, QuestionnaireDialog) and d.isVisible():
            step = runner.session.next_step()
            q = d.q
            n = q.item_ids().index(d.current_item)
            value = q.lo if step.point == "baseline" else rating(pid_n, step.condition, q, n)
            seen.append((step.questionnaire, d.current_item, value))
            qtbot.keyClick(d, str(value))
        elif isinstance(d, MessageDialog) and d.isVisible():
            assert "Esc" in d.label.text()  # the participant is told how to stop
            for c in runner.protocol.conditions:  # the participant never sees a condition
                assert c.name not in d.label.text()
            qtbot.keyClick(d, Qt.Key.Key_Return)
        elif isinstance(d, RestDialog):
            qtbot.wait(100)
        else:
            qtbot.wait(20)
    return seen


def test_an_experimenter_runs_four_participants_and_gets_the_report(window, qtbot, tmp_path):
    protocol = make_protocol(tmp_path)
    folder = tmp_path / "study"
    stop_for = {4: 1}  # participant 4 stops the second run
    for pid_n in range(1, 5):
        menu_action(window, "Run a session").trigger()
        setup = window.findChildren(SetupDialog)[-1]
        qtbot.waitUntil(setup.isVisible)
        qtbot.keyClicks(setup.protocol_edit, str(protocol))
        qtbot.keyClicks(setup.folder_edit, str(folder))
        setup.check_button.click()
        assert setup.pid_edit.text() == f"P0{pid_n}"  # suggested, pseudonymous
        info = setup.info.text()
        assert "condition A" in info and "condition A (" not in info  # blind: codes only
        qtbot.mouseClick(setup.start_button, Qt.MouseButton.LeftButton)
        runner = setup.runner
        assert runner is not None and window.normal_mode
        assert window.settings_as_given  # the protocol's exposure, not the window's choice
        qtbot.keyClick(window.view, Qt.Key.Key_Tab)
        assert window.normal_mode and not window.dock.isVisible()  # no panels mid-session
        seen = drive(qtbot, runner, pid_n, stop_for.get(pid_n))
        box = runner.final_box
        assert box is not None and "Thank you" in box.text()
        box.close()
        assert not window.normal_mode and window.dock.isVisible()  # the window is given back
        assert not window.settings_as_given
        n_expected = 16 + (16 + 5) * 2  # the stopped run's questionnaires are still asked
        assert len(seen) == n_expected
        events = [
            json.loads(x)
            for x in (folder / "participants" / f"P0{pid_n}.jsonl").read_text().splitlines()
        ]
        answers = [
            (e["questionnaire"], e["item"], e["value"]) for e in events if e["type"] == "answer"
        ]
        assert answers == seen  # every keystroke is on disk, in order
        ends = [e for e in events if e["type"] == "exposure_end"]
        if pid_n == 4:
            assert ends[-1]["stopped"] and ends[-1]["duration_s"] < EXPOSURE_S
            assert events[-1] == {**events[-1], "type": "session_end", "reason": "withdrawn"}
        else:
            assert not any(e["stopped"] for e in ends)
            assert events[-1]["reason"] == "complete"
            assert all(e["duration_s"] >= EXPOSURE_S - 0.01 for e in ends), ends
        for e in ends:  # the frame-time log of each exposure is kept with the answers
            assert len(e["frame_ms"]) >= 2 and all(v > 0 for v in e["frame_ms"])
        starts = [e for e in events if e["type"] == "exposure_start"]
        assert [s["settings"]["cps.mode"] for s in starts] == [e["condition"] for e in ends]
    orders = [
        json.loads((folder / "participants" / f"P0{i}.jsonl").read_text().splitlines()[0])["order"]
        for i in range(1, 5)
    ]
    assert sorted(map(tuple, orders)) == [("cps", "none")] * 2 + [("none", "cps")] * 2

    menu_action(window, "Run a session").trigger()
    setup = window.findChildren(SetupDialog)[-1]
    qtbot.keyClicks(setup.protocol_edit, str(protocol))
    qtbot.keyClicks(setup.folder_edit, str(folder))
    setup.analyse_button.click()
    assert "4 participants (3 complete)" in setup.info.text()
    report = (folder / "report.md").read_text()
    assert "SSQ Total change | none − cps | 4 |" in report
    for name in ("ssq.png", "quality.png", "answers.csv", "scores.csv"):
        assert (folder / name).stat().st_size > 1000 or name.endswith(".csv")
    setup.reject()
    assert questionnaire("ssq").items[0].text == "General discomfort"


def test_a_broken_protocol_is_a_message_not_a_traceback(window, qtbot, tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text('exposure_s = "soon"\n[[conditions]]\nname = "x"\n', encoding="utf-8")
    menu_action(window, "Run a session").trigger()
    setup = window.findChildren(SetupDialog)[-1]
    qtbot.keyClicks(setup.protocol_edit, str(bad))
    qtbot.keyClicks(setup.folder_edit, str(tmp_path / "s"))
    qtbot.mouseClick(setup.start_button, Qt.MouseButton.LeftButton)
    assert "exposure_s" in setup.info.text() and setup.runner is None
    assert setup.isVisible() and not (tmp_path / "s").exists()
    setup.reject()


def test_an_answer_that_cannot_be_saved_is_not_skipped(window, qtbot, tmp_path, monkeypatch):
    from app.survey import store
    from ui.survey_runner import start_session

    runner = start_session(window, make_protocol(tmp_path), tmp_path / "s", "P01")
    d = runner.dialog
    qtbot.waitUntil(d.isVisible)
    qtbot.keyClick(d, "1")
    assert d.current_item == "fatigue"

    def disk_full(self, *a, **k):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(store.EventLog, "append", disk_full)
    qtbot.keyClick(d, "2")
    assert d.current_item == "fatigue" and runner.finished is None  # stays, nothing lost
    boxes = [b for b in window.findChildren(QMessageBox) if "No space left" in b.text()]
    assert boxes and boxes[-1].isVisible()
    boxes[-1].close()
    monkeypatch.undo()
    qtbot.keyClick(d, "2")
    assert d.current_item == "headache"
    assert runner.session.answers(runner.session.next_step()) == {
        "general_discomfort": 1,
        "fatigue": 2,
    }
    runner.abort("test over")
    runner.final_box.close()
    assert not window.normal_mode
