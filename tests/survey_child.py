"""A participant session in its own process, answered by a timer, for the SIGKILL test.

python tests/survey_child.py PROTOCOL FOLDER PID: prints ``EVENT {json}`` once each event is
on disk, ``ITEM id`` before each answer, and ``FINISHED reason`` at the end.
"""

from __future__ import annotations

import json
import sys

from PyQt6.QtCore import Qt, QTimer
from PyQt6.QtTest import QTest

from app.survey.protocol import load_protocol
from app.survey.store import Study
from ui.main_window import MainWindow, create_app
from ui.survey_dialogs import MessageDialog, QuestionnaireDialog
from ui.survey_runner import SurveyRunner


def value_for(q, point: str, position, n: int) -> int:
    """Deterministic answers the parent can predict."""
    return q.lo + (n + (0 if position is None else position + 1)) % (q.hi - q.lo + 1)


def main() -> int:
    protocol, folder, pid = sys.argv[1:4]
    app = create_app()
    window = MainWindow()
    window.view.setFixedSize(320, 180)
    window.show()

    def said(event: dict) -> None:
        print("EVENT " + json.dumps(event), flush=True)

    study = Study(folder, load_protocol(protocol))
    session = study.session(pid, listener=said)

    def finished(reason: str) -> None:
        print(f"FINISHED {reason}", flush=True)
        app.quit()

    runner = SurveyRunner(window, session, on_finished=finished)

    def drive() -> None:
        d = runner.dialog
        if isinstance(d, QuestionnaireDialog) and d.isVisible():
            step = session.next_step()
            n = d.q.item_ids().index(d.current_item)
            print(f"ITEM {d.current_item}", flush=True)
            QTest.keyClick(d, str(value_for(d.q, step.point, step.position, n)))
        elif isinstance(d, MessageDialog) and d.isVisible():
            QTest.keyClick(d, Qt.Key.Key_Return)

    timer = QTimer()
    timer.timeout.connect(drive)
    timer.start(30)
    QTimer.singleShot(0, runner.start)
    return app.exec()


if __name__ == "__main__":
    sys.exit(main())
