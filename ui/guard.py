"""The app's last guard: an exception that escapes a Qt slot, timer or event handler.

PyQt6 aborts the process on such an exception unless ``sys.excepthook`` has been replaced;
:func:`install` replaces it for the window's process. The traceback goes to the log, the user
gets an error dialog, and the window (and the scene loaded in it) keeps running.
"""

from __future__ import annotations

import logging
import sys
from types import TracebackType

from PyQt6.QtWidgets import QApplication, QMessageBox

log = logging.getLogger(__name__)
_dialogs: list[QMessageBox] = []  # open error dialogs, kept alive until closed


def _hook(kind: type[BaseException], exc: BaseException, tb: TracebackType | None) -> None:
    if issubclass(kind, KeyboardInterrupt):
        sys.__excepthook__(kind, exc, tb)
        return
    log.error("unexpected error (the app keeps running): %s", exc, exc_info=(kind, exc, tb))
    try:
        if QApplication.instance() is None:
            return
        parent = QApplication.activeWindow()
        box = QMessageBox(QMessageBox.Icon.Critical, "Unexpected error", "", parent=parent)
        box.setText(f"Something went wrong: {exc or kind.__name__}")
        box.setInformativeText(
            "The app keeps running and nothing was closed. The details are in the log."
        )
        box.finished.connect(lambda _=0, b=box: _dialogs.remove(b) if b in _dialogs else None)
        _dialogs.append(box)
        box.open()  # not exec(): no nested event loop inside the hook
    except Exception:  # noqa: BLE001 - the hook itself must never raise
        log.exception("could not show the error dialog")


def install() -> None:
    """Route exceptions from slots and timers to the log and a dialog instead of an abort."""
    sys.excepthook = _hook
