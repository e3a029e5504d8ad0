"""Study > Run a session…: one participant's session in the main window.

Baseline questionnaires, then per condition (in the participant's counterbalanced order): an
instruction page, the exposure in normal mode (scene only, no fps text) playing the protocol's
path, the post-exposure questionnaires, the rest. Esc during an exposure is the participant's
"I feel unwell, stop": the run ends at once and that is recorded. Every answer is on disk
(``app.survey.store``) before the next item shows; a session that ended early (a crash, a
closed window) is resumed by starting the same participant id again.

The window is driven through its public methods (load, wait_for_load, set_normal_mode,
view.playing); the runner restores the window's settings and mode afterwards.
"""

from __future__ import annotations

import logging
import os
import time
from pathlib import Path

from PyQt6.QtCore import QEvent, QObject, Qt, QTimer
from PyQt6.QtWidgets import (
    QApplication,
    QDialog,
    QFileDialog,
    QFormLayout,
    QHBoxLayout,
    QLabel,
    QLineEdit,
    QMessageBox,
    QPushButton,
    QVBoxLayout,
    QWidget,
)

from app.fileio import atomic_write_text
from app.paths import PathError
from app.scenes import default_path, resolve_path
from app.survey.cli import default_study_dir
from app.survey.plan import BASELINE, Step
from app.survey.protocol import TEMPLATE, Protocol, ProtocolError, load_protocol
from app.survey.questionnaires import questionnaire
from app.survey.store import ParticipantSession, StoreError, Study
from ui.survey_dialogs import (
    MessageDialog,
    QuestionnaireDialog,
    RestDialog,
    guarded,
    show_message,
)

log = logging.getLogger(__name__)
STOP_KEY = Qt.Key.Key_Escape


class SurveyRunner(QObject):
    """Drives one participant's session; ``finished`` is set to the end reason when done."""

    def __init__(self, window, session: ParticipantSession, on_finished=None) -> None:
        super().__init__(window)
        self.window = window
        self.session = session
        self.protocol: Protocol = session.protocol
        self.on_finished = on_finished
        self.dialog: QDialog | None = None
        self.finished: str | None = None
        self.final_box: QMessageBox | None = None
        self.exposing: Step | None = None
        self._frames: list[float] = []
        self._t0 = 0.0
        self._timer = QTimer(self)
        self._timer.setSingleShot(True)
        self._timer.setTimerType(Qt.TimerType.PreciseTimer)  # exposure length to the ms
        self._timer.timeout.connect(self._exposure_timeout)
        self._saved_settings = window.settings.copy()
        self._saved_normal = window.normal_mode
        self._saved_title = window.windowTitle()
        self._scene_loaded = None  # the Scene object this runner loaded

    # -- flow ----------------------------------------------------------------------------------
    def start(self) -> None:
        self.window.set_normal_mode(True)  # no panels: they would show the condition's settings
        self.window.settings_as_given = True  # the conditions' exposure as the protocol says
        QApplication.instance().installEventFilter(self)  # Tab stays off for the session
        self._advance()

    def _advance(self) -> None:
        self._close_dialog()
        step = self.session.next_step()
        self._status(step)
        if step.kind == "questionnaire":
            self._questionnaire(step)
        elif step.kind == "exposure":
            self._instructions(step)
        elif step.kind == "rest":
            self._rest(step)
        else:
            self._finish()

    def _status(self, step: Step) -> None:
        """The experimenter's line in the title bar: participant, run and condition code."""
        n = len(self.session.order)
        where = "baseline" if step.position is None else f"run {step.position + 1}/{n}"
        cond = ""
        if step.condition:
            cond = " · " + self.protocol.shown_as(self.protocol.condition(step.condition))
        self.window.setWindowTitle(
            f"Study {self.protocol.name} · {self.session.pid} · {where}{cond} · {step.kind}"
        )

    def _heading(self, step: Step) -> str:
        if step.point == BASELINE:
            return "Before the first run"
        return f"After run {step.position + 1} of {len(self.session.order)}"

    def _show(self, dialog: QDialog) -> None:
        self.dialog = dialog
        dialog.open()
        dialog.raise_()
        dialog.activateWindow()
        dialog.setFocus()

    def _close_dialog(self) -> None:
        if self.dialog is not None:
            d, self.dialog = self.dialog, None
            d.finish()

    # -- questionnaires ------------------------------------------------------------------------
    def _questionnaire(self, step: Step) -> None:
        q = questionnaire(step.questionnaire or "")
        self._show(
            QuestionnaireDialog(
                q,
                self.session.answers(step),
                self._heading(step),
                lambda item, value: self._answer(step, item, value),
                lambda: self._later(lambda: self._questionnaire_done(step)),
                self.window,
            )
        )

    def _answer(self, step: Step, item: str, value: int) -> bool:
        try:
            self.session.record_answer(step, item, value)
        except (OSError, StoreError, ValueError) as exc:
            self._fail(f"The answer could not be saved: {exc}", keep_going=True)
            return False
        return True

    def _questionnaire_done(self, step: Step) -> None:
        self.session.finish_questionnaire(step)
        self._advance()

    # -- exposure ------------------------------------------------------------------------------
    def _instructions(self, step: Step) -> None:
        n = len(self.session.order)
        text = (
            f"Run {step.position + 1} of {n}.\n\nYou will walk through the scene for about "
            f"{self.protocol.exposure_s:g} seconds; just watch.\n\nIf at any moment you feel "
            "unwell, press Esc: the run stops at once.\n\nPress Enter to start."
        )
        self._show(
            MessageDialog(
                f"Run {step.position + 1}",
                text,
                "Start (Enter)",
                lambda: self._later(lambda: self._begin_exposure(step)),
                self.window,
            )
        )

    def _begin_exposure(self, step: Step) -> None:
        self._close_dialog()
        w = self.window
        cond = self.protocol.condition(step.condition or "")
        wanted = self.protocol.settings_for(cond)
        for key in wanted.keys():  # in place: session, renderer and panels share the object
            w.settings.set(key, wanted.get(key))
        if self._scene_loaded is None or w.session.scene is not self._scene_loaded:
            w.load(self.protocol.scene)
            w.wait_for_load(timeout=300.0)
            if w.session.scene is None:
                raise RuntimeError(f"the scene {self.protocol.scene} could not be loaded")
            self._scene_loaded = w.session.scene
        try:
            path = resolve_path(self.protocol.path) if self.protocol.path else None
        except PathError as exc:
            raise RuntimeError(str(exc)) from exc
        w.session.path = path or default_path(w.session.scene)
        w._setting_changed("")  # survey: refresh panels and CPS caps (MainWindow's own slot)
        w.set_normal_mode(True)  # after the settings: normal mode turns the fps text off
        w.view._play_frame = 0  # survey: every exposure starts the path at its beginning
        self.session.start_exposure(step, cond.settings)
        self.exposing = step
        self._frames = []
        w.view.frameSwapped.connect(self._frame)
        w.view.setFocus()
        w.view.playing = True
        self._t0 = time.perf_counter()
        self._timer.start(int(self.protocol.exposure_s * 1000))

    def _frame(self) -> None:
        self._frames.append(time.perf_counter())

    def eventFilter(self, obj: QObject, event: QEvent) -> bool:
        try:
            if event.type() == QEvent.Type.KeyPress and self.finished is None:
                if event.key() == STOP_KEY and self.exposing is not None:
                    self._end_exposure(stopped=True)
                    return True
                if event.key() == Qt.Key.Key_Tab and isinstance(obj, QWidget):
                    # no evaluation mode (panels show the condition) during a session
                    return obj.window() is self.window
        except Exception:  # noqa: BLE001 - never out of an event filter
            log.exception("study: stopping the exposure failed")
            return True
        return False

    @guarded
    def _exposure_timeout(self) -> None:
        if self.exposing is not None:
            self._end_exposure(stopped=False)

    def _end_exposure(self, stopped: bool) -> None:
        step, self.exposing = self.exposing, None
        if step is None:
            return
        self._timer.stop()
        w = self.window
        w.view.playing = False
        try:
            w.view.frameSwapped.disconnect(self._frame)
        except TypeError:
            pass
        duration = time.perf_counter() - self._t0
        # frame times between swaps; the first swap follows the scene upload, so it starts
        # the clock rather than giving a frame time
        ts = self._frames
        frame_ms = [(b - a) * 1000.0 for a, b in zip(ts, ts[1:])]
        self.session.end_exposure(step, duration, stopped, frame_ms)
        self._later(self._advance)

    # -- rest and end --------------------------------------------------------------------------
    def _rest(self, step: Step) -> None:
        self.session.start_rest(step)

        def done(skipped: bool) -> None:
            self.session.end_rest(step, skipped)
            self._later(self._advance)

        self._show(RestDialog(self.protocol.rest_s, done, self.window))

    def _finish(self) -> None:
        reason = self.session.finished or self.session.end_session()
        self._restore()
        self.finished = reason
        if self.on_finished is not None:
            self.on_finished(reason)
            return
        self.final_box = show_message(
            self.window,
            "Session finished",
            f"Participant {self.session.pid}: session {reason}. Thank you!\n\n"
            f"Data: {self.session.log.path}\n"
            "Analyse with Study > Run a session… > Analyse study, or: "
            f"vrpreview survey analyse {self.session.study.folder}",
        )

    def _restore(self) -> None:
        QApplication.instance().removeEventFilter(self)
        w = self.window
        for key in self._saved_settings.keys():
            w.settings.set(key, self._saved_settings.get(key))
        w.settings_as_given = False
        w._setting_changed("")  # survey: refresh panels (MainWindow's own slot)
        w.set_normal_mode(self._saved_normal)
        w.setWindowTitle(self._saved_title)

    def abort(self, message: str) -> None:
        """End the session on screen (the file stays resumable)."""
        if self.exposing is not None:
            self.exposing = None
            self._timer.stop()
            self.window.view.playing = False
        self._close_dialog()
        self._restore()
        self.finished = "aborted"
        self.final_box = show_message(
            self.window,
            "Session stopped",
            f"{message}\n\nEvery answer given so far is saved in {self.session.log.path}. "
            f"Start participant {self.session.pid} again to resume.",
            error=True,
        )

    def _fail(self, message: str, keep_going: bool = False) -> None:
        if keep_going:
            show_message(self.window, "Study", message, error=True)
        else:
            self.abort(message)

    def _later(self, fn) -> None:
        """Run ``fn`` from the event loop, guarded: a failure ends the session with a message,
        never a traceback out of a Qt slot."""

        def call() -> None:
            try:
                fn()
            except (OSError, StoreError, ProtocolError, RuntimeError, ValueError) as exc:
                self.abort(str(exc))
            except Exception as exc:  # noqa: BLE001 - a bug: log it, keep the window
                log.exception("study runner failed")
                self.abort(f"Unexpected error: {type(exc).__name__}: {exc}")

        QTimer.singleShot(0, call)


# -- the experimenter's setup ------------------------------------------------------------------
class SetupDialog(QDialog):
    """Protocol file, study folder, participant id; Start (or resume), Analyse."""

    def __init__(self, window, protocol: str = "", folder: str = "", pid: str = "") -> None:
        super().__init__(window)
        self.window = window
        self.runner: SurveyRunner | None = None
        self.setWindowTitle("Run a study session")
        self.setMinimumWidth(640)
        layout = QVBoxLayout(self)
        form = QFormLayout()
        self.protocol_edit = QLineEdit(protocol)
        self.protocol_edit.setPlaceholderText("study.toml (TOML or JSON)")
        self.folder_edit = QLineEdit(folder)
        self.folder_edit.setPlaceholderText("default: the data folder / studies / NAME")
        self.pid_edit = QLineEdit(pid)
        self.pid_edit.setPlaceholderText("pseudonymous id, e.g. P01 (never a name)")
        form.addRow(
            "Protocol file",
            self._with_buttons(
                self.protocol_edit, self._browse_protocol, ("New…", self._new_protocol)
            ),
        )
        form.addRow("Study folder", self._with_buttons(self.folder_edit, self._browse_folder))
        form.addRow("Participant id", self.pid_edit)
        layout.addLayout(form)
        self.info = QLabel()
        self.info.setWordWrap(True)
        self.info.setTextInteractionFlags(Qt.TextInteractionFlag.TextSelectableByMouse)
        layout.addWidget(self.info)
        row = QHBoxLayout()
        self.check_button = QPushButton("Check")
        self.check_button.clicked.connect(lambda _=False: self._check())
        self.analyse_button = QPushButton("Analyse study")
        self.analyse_button.clicked.connect(lambda _=False: self._analyse())
        self.start_button = QPushButton("Start session")
        self.start_button.setDefault(True)
        self.start_button.clicked.connect(lambda _=False: self._start())
        cancel = QPushButton("Close")
        cancel.clicked.connect(self.reject)
        for b in (self.check_button, self.analyse_button, cancel, self.start_button):
            row.addWidget(b)
        layout.addLayout(row)
        self.protocol_edit.editingFinished.connect(lambda: self._check())
        if protocol:
            self._check()

    def _with_buttons(self, edit: QLineEdit, browse, *extra) -> QWidget:
        box = QWidget()
        h = QHBoxLayout(box)
        h.setContentsMargins(0, 0, 0, 0)
        h.addWidget(edit, 1)
        b = QPushButton("Browse…")
        b.clicked.connect(lambda _=False, f=browse: f())
        h.addWidget(b)
        for text, slot in extra:
            e = QPushButton(text)
            e.clicked.connect(lambda _=False, f=slot: f())
            h.addWidget(e)
        return box

    def _say(self, text: str, error: bool = False) -> None:
        self.info.setStyleSheet("color: #b00020;" if error else "")
        self.info.setText(text)

    @guarded
    def _browse_protocol(self) -> None:
        path, _ = QFileDialog.getOpenFileName(
            self, "Study protocol", "", "Protocols (*.toml *.json);;All files (*)"
        )
        if path:
            self.protocol_edit.setText(path)
            self._check()

    @guarded
    def _new_protocol(self) -> None:
        path, _ = QFileDialog.getSaveFileName(
            self, "New study protocol", "study.toml", "TOML (*.toml)"
        )
        if not path:
            return
        if Path(path).exists():
            self._say(f"{path} exists; not overwritten. Choose another name.", error=True)
            return
        atomic_write_text(path, TEMPLATE)
        self.protocol_edit.setText(path)
        self._check()
        self._say(
            f"Wrote an example protocol (none vs CPS on the corridor) to {path}. Edit it in a "
            "text editor if needed (times, conditions), then press Check.\n\n" + self.info.text()
        )

    @guarded
    def _browse_folder(self) -> None:
        path = QFileDialog.getExistingDirectory(self, "Study folder")
        if path:
            self.folder_edit.setText(path)
            self._check()

    def _folder(self, protocol: Protocol | None) -> Path | None:
        text = self.folder_edit.text().strip()
        if text:
            return Path(text).expanduser()
        return default_study_dir(protocol.name) if protocol else None

    def _load(self) -> Protocol | None:
        text = self.protocol_edit.text().strip()
        if not text:
            self._say("Choose a protocol file (or New… for an example).", error=True)
            return None
        try:
            return load_protocol(Path(text).expanduser())
        except ProtocolError as exc:
            self._say(str(exc), error=True)
            return None

    @guarded
    def _check(self) -> Study | None:
        p = self._load()
        if p is None:
            return None
        folder = self._folder(p)
        try:
            study = Study(folder, p)
        except (StoreError, OSError) as exc:
            self._say(str(exc), error=True)
            return None
        people = study.participants()
        status = ", ".join(f"{pid} ({study.status(pid)})" for pid in people) or "none yet"
        conds = ", ".join(p.shown_as(c) for c in p.conditions)
        self._say(
            f"Protocol {p.name}: {len(p.conditions)} conditions ({conds}), scene {p.scene}, "
            f"exposure {p.exposure_s:g} s, rest {p.rest_s:g} s.\nStudy folder: {folder}\n"
            f"Participants: {status}"
        )
        if not self.pid_edit.text().strip():
            self.pid_edit.setText(study.suggest_id())
        return study

    @guarded
    def _start(self) -> None:
        study = self._check()
        if study is None:
            return
        pid = self.pid_edit.text().strip()
        try:
            session = study.session(pid)
        except (StoreError, OSError) as exc:
            self._say(str(exc), error=True)
            return
        self.accept()
        self.runner = SurveyRunner(self.window, session)
        self.runner.start()

    @guarded
    def _analyse(self) -> None:
        p = self._load()
        if p is None:
            return
        from app.survey.analysis import analyse

        try:
            result = analyse(self._folder(p))
        except (StoreError, OSError, ValueError) as exc:
            self._say(str(exc), error=True)
            return
        self._say(f"Analysis: {result.summary()}\nReport: {result.report}")


def open_session_dialog(window, protocol: str = "", folder: str = "", pid: str = "") -> SetupDialog:
    """Study > Run a session…: the setup dialog (non-blocking)."""
    dialog = SetupDialog(window, protocol, folder, pid)
    dialog.open()
    return dialog


def start_session(
    window, protocol_file: str | os.PathLike[str], folder, pid: str, on_finished=None
) -> SurveyRunner:
    """Start (or resume) a participant straight away (scripts, tests)."""
    study = Study(folder, load_protocol(protocol_file))
    runner = SurveyRunner(window, study.session(pid), on_finished)
    runner.start()
    return runner


def run_standalone(protocol_file, folder, pid: str | None, size: str = "1600x900") -> int:
    """``vrpreview survey run``: the window with the setup dialog filled in."""
    from app.frame import parse_size
    from ui.main_window import MainWindow, create_app

    app = create_app()
    window = MainWindow()
    window.resize(*parse_size(size))
    window.show()
    open_session_dialog(window, str(protocol_file), str(folder), pid or "")
    return app.exec()
