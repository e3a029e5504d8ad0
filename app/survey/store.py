"""Nothing lost: every answer is appended to the participant's JSON-lines file at once.

A study folder holds::

    protocol.json                 the protocol as first used (a later, different one is refused)
    participants/P01.jsonl        P01's events, one JSON object a line, append-only
    participants/P01.summary.json the scores so far (rewritten atomically, derived data only)
    answers.csv, scores.csv       ``vrpreview survey export`` (and analyse)

Each event is one ``os.write`` of one line to a file opened ``O_APPEND``, then ``fsync``; the
folder is fsync'd when a file is created. A ``kill -9`` can at worst cut the line being
written: on reading, a cut last line is skipped (and the next event starts a new line), so
every answer given before it is still there. The raw file is never rewritten or truncated.
"""

from __future__ import annotations

import csv
import io
import json
import logging
import os
import re
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from app.fileio import atomic_write_json, atomic_write_text
from app.stats import summarize
from app.survey.plan import BASELINE, POST, Step, steps
from app.survey.protocol import Protocol, ProtocolError, protocol_from_dict
from app.survey.questionnaires import SCORE_KEYS, questionnaire, score_ssq

log = logging.getLogger(__name__)
ID_PATTERN = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_-]{0,31}$")


class StoreError(ValueError):
    """A study folder or participant file that cannot be used as asked."""


def _fsync_dir(folder: Path) -> None:
    try:
        fd = os.open(folder, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


class EventLog:
    """An append-only JSON-lines file; ``listener`` is told of each event once it is on disk."""

    def __init__(self, path: Path, listener: Callable[[dict], None] | None = None) -> None:
        self.path = path
        self.listener = listener
        self.events: list[dict] = []
        self.skipped_lines = 0
        self._needs_newline = False
        if path.exists():
            self._read()

    def _read(self) -> None:
        data = self.path.read_bytes()
        lines = data.split(b"\n")
        self._needs_newline = bool(data) and not data.endswith(b"\n")
        for n, line in enumerate(lines):
            if not line.strip():
                continue
            try:
                ev = json.loads(line)
                if not isinstance(ev, dict) or "type" not in ev:
                    raise ValueError("not an event")
            except ValueError:
                self.skipped_lines += 1
                cut = n == len(lines) - 1 and self._needs_newline
                log.warning(
                    "%s line %d: %s, skipped",
                    self.path,
                    n + 1,
                    "cut short" if cut else "unreadable",
                )
                continue
            self.events.append(ev)

    def append(self, type_: str, **fields: Any) -> dict:
        event = {"seq": len(self.events), "time": time.time(), "type": type_, **fields}
        line = json.dumps(event, allow_nan=False, separators=(",", ":")) + "\n"
        if self._needs_newline:
            line = "\n" + line  # a cut line before must not swallow this one
        created = not self.path.exists()
        self.path.parent.mkdir(parents=True, exist_ok=True)
        fd = os.open(self.path, os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o644)
        try:
            data = line.encode("utf-8")
            written = os.write(fd, data)
            while written < len(data):  # a short write (rare): finish the line
                written += os.write(fd, data[written:])
            os.fsync(fd)
        finally:
            os.close(fd)
        if created:
            _fsync_dir(self.path.parent)
        self._needs_newline = False
        self.events.append(event)
        if self.listener is not None:
            self.listener(event)
        return event


class Study:
    """A study folder bound to one protocol."""

    def __init__(self, folder: str | os.PathLike[str], protocol: Protocol) -> None:
        self.folder = Path(folder)
        self.protocol = protocol
        frozen = self.folder / "protocol.json"
        if frozen.exists():
            try:
                doc = json.loads(frozen.read_text("utf-8"))
            except (OSError, json.JSONDecodeError) as exc:
                raise StoreError(f"{frozen}: unreadable ({exc})") from exc
            if doc != protocol.to_dict():
                raise StoreError(
                    f"{self.folder} was started with a different protocol ({frozen}); "
                    "use a new study folder for a changed protocol"
                )
        else:
            if self.participants():
                raise StoreError(f"{self.folder} has participant files but no protocol.json")
            atomic_write_json(frozen, protocol.to_dict())

    @classmethod
    def open(cls, folder: str | os.PathLike[str]) -> Study:
        """An existing study folder, with the protocol it was started with."""
        frozen = Path(folder) / "protocol.json"
        try:
            doc = json.loads(frozen.read_text("utf-8"))
        except FileNotFoundError:
            raise StoreError(f"{folder} is not a study folder (no protocol.json)") from None
        except (OSError, json.JSONDecodeError) as exc:
            raise StoreError(f"{frozen}: unreadable ({exc})") from exc
        try:
            protocol = protocol_from_dict(doc, str(frozen))
        except ProtocolError as exc:
            raise StoreError(str(exc)) from exc
        return cls(folder, protocol)

    @property
    def participants_dir(self) -> Path:
        return self.folder / "participants"

    def participants(self) -> list[str]:
        if not self.participants_dir.is_dir():
            return []
        return sorted(p.stem for p in self.participants_dir.glob("*.jsonl"))

    def status(self, pid: str) -> str:
        """ "new", "in progress", "complete" or "withdrawn"."""
        path = self.participants_dir / f"{pid}.jsonl"
        if not path.exists():
            return "new"
        ends = [e for e in EventLog(path).events if e["type"] == "session_end"]
        return ends[-1]["reason"] if ends else "in progress"

    def suggest_id(self) -> str:
        taken = set(self.participants())
        n = 1
        while f"P{n:02d}" in taken:
            n += 1
        return f"P{n:02d}"

    def session(
        self, pid: str, listener: Callable[[dict], None] | None = None
    ) -> ParticipantSession:
        """Start a new participant, or resume one whose session did not finish."""
        if not ID_PATTERN.match(pid or ""):
            raise StoreError(
                f"participant id {pid!r}: use 1-32 letters, digits, - or _ (a pseudonym such as "
                "P07, never a name)"
            )
        path = self.participants_dir / f"{pid}.jsonl"
        if path.exists():
            s = ParticipantSession(self, pid, EventLog(path, listener))
            if s.started is None:
                raise StoreError(f"{path}: no session start in the file")
            if s.finished:
                raise StoreError(
                    f"participant {pid} has already finished ({s.finished}); nothing is "
                    "overwritten: choose another id"
                )
            s.resume()
            return s
        index = sum(
            1 for p in self.participants() if (self.participants_dir / f"{p}.jsonl").stat().st_size
        )
        log_ = EventLog(path, listener)
        order = self.protocol.order(index)
        log_.append(
            "session_start",
            participant=pid,
            index=index,
            order=[c.name for c in order],
            codes=[c.code for c in order],
            protocol=self.protocol.name,
        )
        return ParticipantSession(self, pid, log_)


@dataclass
class Exposure:
    position: int
    condition: str
    code: str
    duration_s: float
    stopped: bool
    reason: str
    frame_ms: list[float]


class ParticipantSession:
    """One participant's events and what is due next; every change goes to the log first."""

    def __init__(self, study: Study, pid: str, log_: EventLog) -> None:
        self.study = study
        self.protocol = study.protocol
        self.pid = pid
        self.log = log_

    # -- derived from the events ---------------------------------------------------------------
    @property
    def started(self) -> dict | None:
        return next((e for e in self.log.events if e["type"] == "session_start"), None)

    @property
    def order(self) -> list[str]:
        return list(self.started["order"]) if self.started else []

    @property
    def index(self) -> int:
        return int(self.started["index"]) if self.started else 0

    @property
    def finished(self) -> str | None:
        ends = [e for e in self.log.events if e["type"] == "session_end"]
        return ends[-1]["reason"] if ends else None

    def code(self, condition: str | None) -> str:
        try:
            return self.protocol.condition(condition).code if condition else ""
        except KeyError:
            return "?"

    def _done(self, step: Step) -> bool:
        for e in self.log.events:
            if step.kind == "questionnaire" and e["type"] == "questionnaire_done":
                if (e["questionnaire"], e["point"], e["position"]) == (
                    step.questionnaire,
                    step.point,
                    step.position,
                ):
                    return True
            elif step.kind == "exposure" and e["type"] == "exposure_end":
                if e["position"] == step.position:
                    return True
            elif step.kind == "rest" and e["type"] == "rest_end":
                if e["position"] == step.position:
                    return True
        return False

    def exposures(self) -> dict[int, Exposure]:
        out: dict[int, Exposure] = {}
        for e in self.log.events:
            if e["type"] == "exposure_end":
                out[e["position"]] = Exposure(
                    e["position"],
                    e["condition"],
                    e.get("code", ""),
                    float(e["duration_s"]),
                    bool(e["stopped"]),
                    e.get("reason", ""),
                    list(e.get("frame_ms", [])),
                )
        return out

    def plan(self) -> list[Step]:
        """The steps still to be taken into account: after an "I feel unwell" stop with
        ``on_stop = "end"``, only that run's questionnaires remain."""
        all_steps = steps(self.protocol, self.order)
        if self.protocol.on_stop != "end":
            return all_steps
        stops = [x.position for x in self.exposures().values() if x.stopped]
        if not stops:
            return all_steps
        last = min(stops)
        return [
            s
            for s in all_steps
            if s.position is None or s.position < last or (s.position == last and s.kind != "rest")
        ]

    def next_step(self) -> Step:
        if self.finished:
            return Step("end")
        for s in self.plan():
            if not self._done(s):
                return s
        return Step("end")

    def answers(self, step: Step) -> dict[str, int]:
        """Answers given so far for a questionnaire step (a changed answer: the latest)."""
        out: dict[str, int] = {}
        for e in self.log.events:
            if (
                e["type"] == "answer"
                and e["questionnaire"] == step.questionnaire
                and e["point"] == step.point
                and e["position"] == step.position
            ):
                out[e["item"]] = int(e["value"])
        return out

    # -- recording -----------------------------------------------------------------------------
    def resume(self) -> None:
        started = {e["position"] for e in self.log.events if e["type"] == "exposure_start"}
        ended = {e["position"] for e in self.log.events if e["type"] == "exposure_end"}
        noted = {e["position"] for e in self.log.events if e["type"] == "exposure_interrupted"}
        for pos in sorted(started - ended - noted):
            self.log.append("exposure_interrupted", position=pos, note="session ended mid-run")
        self.log.append("session_resume", next=self.next_step().kind)

    def record_answer(self, step: Step, item: str, value: int) -> None:
        q = questionnaire(step.questionnaire or "")
        value = q.check(item, value)
        self.log.append(
            "answer",
            questionnaire=q.key,
            point=step.point,
            position=step.position,
            condition=step.condition,
            code=self.code(step.condition),
            item=item,
            value=value,
        )

    def finish_questionnaire(self, step: Step) -> dict:
        q = questionnaire(step.questionnaire or "")
        answers = self.answers(step)
        missing = [i for i in q.item_ids() if i not in answers]
        if missing:
            raise StoreError(f"{q.title}: unanswered items {', '.join(missing)}")
        fields: dict[str, Any] = dict(
            questionnaire=q.key,
            point=step.point,
            position=step.position,
            condition=step.condition,
            code=self.code(step.condition),
            answers={i: answers[i] for i in q.item_ids()},
        )
        if q.key == "ssq":
            fields["scores"] = score_ssq(answers).as_dict()
        ev = self.log.append("questionnaire_done", **fields)
        self.write_summary()
        return ev

    def start_exposure(self, step: Step, settings: dict[str, Any]) -> None:
        self.log.append(
            "exposure_start",
            position=step.position,
            condition=step.condition,
            code=self.code(step.condition),
            scene=self.protocol.scene,
            path=self.protocol.path,
            planned_s=self.protocol.exposure_s,
            settings=settings,
        )

    def end_exposure(
        self, step: Step, duration_s: float, stopped: bool, frame_ms: list[float]
    ) -> None:
        self.log.append(
            "exposure_end",
            position=step.position,
            condition=step.condition,
            code=self.code(step.condition),
            duration_s=round(float(duration_s), 3),
            planned_s=self.protocol.exposure_s,
            stopped=bool(stopped),
            reason="participant stopped (felt unwell)" if stopped else "completed",
            frame_ms=[round(float(v), 3) for v in frame_ms],
        )
        self.write_summary()

    def start_rest(self, step: Step) -> None:
        self.log.append("rest_start", position=step.position, planned_s=self.protocol.rest_s)

    def end_rest(self, step: Step, skipped: bool = False) -> None:
        self.log.append("rest_end", position=step.position, skipped=skipped)

    def end_session(self) -> str:
        stopped = any(x.stopped for x in self.exposures().values())
        reason = "withdrawn" if stopped and self.protocol.on_stop == "end" else "complete"
        self.log.append("session_end", reason=reason)
        self.write_summary()
        return reason

    # -- summaries -----------------------------------------------------------------------------
    def summary(self) -> dict:
        done = [e for e in self.log.events if e["type"] == "questionnaire_done"]
        ssq = {}
        quality = {}
        for e in done:
            key = "baseline" if e["point"] == BASELINE else f"run{e['position'] + 1}"
            if e["questionnaire"] == "ssq":
                ssq[key] = {"condition": e["condition"], **e["scores"]}
            else:
                quality[key] = {"condition": e["condition"], **e["answers"]}
        exposures = {
            f"run{x.position + 1}": {
                "condition": x.condition,
                "code": x.code,
                "duration_s": x.duration_s,
                "stopped": x.stopped,
                "frames": len(x.frame_ms),
                "frame_ms": summarize(x.frame_ms),
            }
            for x in self.exposures().values()
        }
        return {
            "participant": self.pid,
            "index": self.index,
            "order": self.order,
            "status": self.finished or "in progress",
            "ssq": ssq,
            "quality": quality,
            "exposures": exposures,
            "note": "derived from " + self.log.path.name + " (the raw, append-only record)",
        }

    def write_summary(self) -> Path:
        return atomic_write_json(
            self.log.path.with_name(f"{self.pid}.summary.json"), self.summary()
        )


# -- reading a whole study ---------------------------------------------------------------------
@dataclass
class Record:
    """One participant as read back for export and analysis."""

    pid: str
    index: int
    order: list[str]
    status: str
    ssq: dict[str, dict[str, float]]  # "baseline" or condition -> scores
    quality: dict[str, dict[str, int]]  # condition -> item -> rating
    position: dict[str, int]  # condition -> 0-based run
    exposures: dict[str, Exposure]  # condition -> the exposure
    answers: list[dict]  # every answer event


def read_study(folder: str | os.PathLike[str]) -> tuple[Study, list[Record]]:
    study = Study.open(folder)
    records = []
    for pid in study.participants():
        s = ParticipantSession(study, pid, EventLog(study.participants_dir / f"{pid}.jsonl"))
        if s.started is None:
            continue
        ssq: dict[str, dict[str, float]] = {}
        quality: dict[str, dict[str, int]] = {}
        for e in s.log.events:
            if e["type"] != "questionnaire_done":
                continue
            key = BASELINE if e["point"] == BASELINE else e["condition"]
            if e["questionnaire"] == "ssq":
                ssq[key] = dict(e["scores"])
            elif e["point"] == POST:
                quality[key] = dict(e["answers"])
        exposures = {x.condition: x for x in s.exposures().values()}
        records.append(
            Record(
                pid,
                s.index,
                s.order,
                s.finished or "in progress",
                ssq,
                quality,
                {c: i for i, c in enumerate(s.order)},
                exposures,
                [e for e in s.log.events if e["type"] == "answer"],
            )
        )
    return study, records


def export_csv(folder: str | os.PathLike[str]) -> list[Path]:
    """answers.csv (every answer as given, changes included) and scores.csv (one row per
    participant and questionnaire point), written atomically."""
    study, records = read_study(folder)
    out = Path(folder)
    buf = io.StringIO()
    w = csv.writer(buf)
    w.writerow(
        [
            "participant",
            "time",
            "questionnaire",
            "point",
            "run",
            "code",
            "condition",
            "item",
            "value",
        ]
    )
    for r in records:
        for e in r.answers:
            pos = e["position"]
            w.writerow(
                [
                    r.pid,
                    f"{e['time']:.3f}",
                    e["questionnaire"],
                    e["point"],
                    "" if pos is None else pos + 1,
                    e.get("code", ""),
                    e.get("condition") or "",
                    e["item"],
                    e["value"],
                ]
            )
    answers = atomic_write_text(out / "answers.csv", buf.getvalue())
    q_items = questionnaire("quality").item_ids()
    buf = io.StringIO()
    w = csv.writer(buf)
    w.writerow(
        [
            "participant",
            "status",
            "order",
            "point",
            "run",
            "code",
            "condition",
            *SCORE_KEYS,
            *[f"quality_{i}" for i in q_items],
            "exposure_s",
            "stopped",
            "frames",
            "frame_ms_median",
            "frame_ms_p95",
        ]
    )
    codes = {c.name: c.code for c in study.protocol.conditions}
    for r in records:
        order = " ".join(codes.get(c, "?") for c in r.order)
        if BASELINE in r.ssq:
            w.writerow(
                [
                    r.pid,
                    r.status,
                    order,
                    BASELINE,
                    "",
                    "",
                    "",
                    *[r.ssq[BASELINE][k] for k in SCORE_KEYS],
                    *[""] * len(q_items),
                    "",
                    "",
                    "",
                    "",
                    "",
                ]
            )
        for c in r.order:
            if c not in r.exposures and c not in r.ssq and c not in r.quality:
                continue
            x = r.exposures.get(c)
            fm = summarize(x.frame_ms) if x else None
            w.writerow(
                [
                    r.pid,
                    r.status,
                    order,
                    POST,
                    r.position[c] + 1,
                    codes.get(c, "?"),
                    c,
                    *[r.ssq.get(c, {}).get(k, "") for k in SCORE_KEYS],
                    *[r.quality.get(c, {}).get(i, "") for i in q_items],
                    x.duration_s if x else "",
                    int(x.stopped) if x else "",
                    len(x.frame_ms) if x else "",
                    f"{fm['median']:.2f}" if fm and x and x.frame_ms else "",
                    f"{fm['p95']:.2f}" if fm and x and x.frame_ms else "",
                ]
            )
    scores = atomic_write_text(out / "scores.csv", buf.getvalue())
    return [answers, scores]
