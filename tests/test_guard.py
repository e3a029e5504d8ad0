"""An exception that escapes a Qt slot is logged and shown; the app keeps running."""

from __future__ import annotations

import logging

import pytest
from PyQt6.QtWidgets import QApplication, QMessageBox

from app.settings import Settings
from ui import guard
from ui.main_window import MainWindow, create_app


@pytest.mark.qt_no_exception_capture  # pytest-qt's own hook would stand in for the app's
def test_exception_in_a_slot_shows_a_dialog_and_keeps_the_scene(qtbot, caplog, monkeypatch):
    create_app()
    guard.install()  # pytest-qt swapped the hook during setup; the window's process has this one
    w = MainWindow(Settings())
    qtbot.addWidget(w)
    w.show()
    qtbot.waitExposed(w)
    scene = w.session.scene

    def broken(*_args) -> None:  # a bad state deep inside the settings slot
        raise IndexError("gazed object 7 of 3")

    monkeypatch.setattr(w.panel, "refresh", broken)
    box = w.tcr_panel.enabled  # the TCR tab's own check box, its real signal
    box.setChecked(not box.isChecked())
    qtbot.waitUntil(lambda: bool(guard._dialogs), timeout=5000)
    dialog = guard._dialogs[-1]
    assert isinstance(dialog, QMessageBox) and dialog.isVisible()
    assert "gazed object 7 of 3" in dialog.text()
    records = [r for r in caplog.records if r.levelno >= logging.ERROR]
    assert records and "gazed object 7 of 3" in records[-1].getMessage()
    for r in records:
        r.expected = True  # this test's own error, not a failure of another part
    assert w.isVisible() and w.session.scene is scene  # still running, same scene
    dialog.close()
    QApplication.processEvents()
    assert not guard._dialogs
