"""kill -9 in the middle of a session loses no given answer, and the session resumes."""

from __future__ import annotations

import json
import os
import queue
import signal
import subprocess
import sys
import threading
from pathlib import Path

import pytest

from app.survey.questionnaires import questionnaire

ROOT = Path(__file__).resolve().parents[1]
CHILD = ROOT / "tests" / "survey_child.py"
pytestmark = pytest.mark.skipif(
    not os.environ.get("DISPLAY"), reason="the child process opens the window (needs X)"
)


class Child:
    def __init__(self, protocol: Path, folder: Path, pid: str, tmp: Path) -> None:
        env = {**os.environ, "PYTHONPATH": str(ROOT), "VRPREVIEW_DATA": str(tmp / "data")}
        self.proc = subprocess.Popen(
            [sys.executable, str(CHILD), str(protocol), str(folder), pid],
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
            text=True,
            env=env,
            cwd=ROOT,
        )
        self.lines: queue.Queue[str] = queue.Queue()
        self.seen: list[str] = []
        threading.Thread(target=self._read, daemon=True).start()

    def _read(self) -> None:
        for line in self.proc.stdout:
            self.lines.put(line.rstrip("\n"))
        self.lines.put("<EOF>")

    def until(self, predicate, timeout: float = 120.0) -> str:
        while True:
            try:
                line = self.lines.get(timeout=timeout)
            except queue.Empty:
                self.kill()
                pytest.fail("child timed out; output:\n" + "\n".join(self.seen[-30:]))
            self.seen.append(line)
            if line == "<EOF>":
                pytest.fail("child ended early; output:\n" + "\n".join(self.seen[-30:]))
            if predicate(line):
                return line

    def kill(self) -> None:
        self.proc.send_signal(signal.SIGKILL)
        self.proc.wait(timeout=30)


def events(path: Path) -> list[dict]:
    return [json.loads(x) for x in path.read_text().splitlines() if x.strip()]


def is_event(kind: str):
    return lambda line: line.startswith("EVENT ") and json.loads(line[6:])["type"] == kind


def test_sigkill_mid_session_keeps_every_answer_and_resumes(tmp_path):
    protocol = tmp_path / "study.toml"
    protocol.write_text(
        'name = "kill"\nexposure_s = 3\nrest_s = 0\n[[conditions]]\nname = "none"\n'
        'settings = { "cps.mode" = "none" }\n[[conditions]]\nname = "cps"\n'
        'settings = { "cps.mode" = "cps" }\n',
        encoding="utf-8",
    )
    folder = tmp_path / "study"
    log = folder / "participants" / "P01.jsonl"
    ids = questionnaire("ssq").item_ids()

    # 1: killed in the middle of the baseline SSQ, just after its 7th answer reached the disk
    c = Child(protocol, folder, "P01", tmp_path)
    count = [0]

    def seventh(line: str) -> bool:
        count[0] += is_event("answer")(line)
        return count[0] == 7

    c.until(seventh)
    c.kill()
    answers = [e for e in events(log) if e["type"] == "answer"]
    assert [(a["item"], a["value"]) for a in answers] == [(ids[n], n % 4) for n in range(7)]
    before = log.read_bytes()

    # 2: resumes at the 8th item; killed in the middle of the first exposure
    c = Child(protocol, folder, "P01", tmp_path)
    first = c.until(lambda line: line.startswith("ITEM "))
    assert first == f"ITEM {ids[7]}"
    c.until(is_event("exposure_start"))
    c.kill()
    ev = events(log)
    assert log.read_bytes().startswith(before)  # nothing written before was changed
    assert [e["type"] for e in ev].count("answer") == 16
    assert any(e["type"] == "questionnaire_done" and e["point"] == "baseline" for e in ev)
    assert ev[-1]["type"] == "exposure_start"
    before = log.read_bytes()

    # 3: resumes: the cut exposure is recorded as interrupted and run again, then to the end
    c = Child(protocol, folder, "P01", tmp_path)
    c.until(lambda line: line.startswith("FINISHED"), timeout=300.0)
    assert c.seen[-1] == "FINISHED complete"
    c.proc.wait(timeout=30)
    assert log.read_bytes().startswith(before)
    ev = events(log)
    kinds = [e["type"] for e in ev]
    assert kinds.count("session_resume") == 2 and kinds.count("exposure_interrupted") == 1
    assert kinds.count("answer") == 16 + 2 * (16 + 5)
    ends = [e for e in ev if e["type"] == "exposure_end"]
    assert [e["position"] for e in ends] == [0, 1] and not any(e["stopped"] for e in ends)
    summary = json.loads((folder / "participants" / "P01.summary.json").read_text())
    assert summary["status"] == "complete" and set(summary["ssq"]) == {"baseline", "run1", "run2"}
