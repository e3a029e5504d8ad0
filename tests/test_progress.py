"""CLI progress: tqdm bars with an ETA on a terminal, nothing at all in a log or a pipe."""

from __future__ import annotations

import io

from app.lab.bench import FrameProgress, TraceProgress
from app.lab.cli import main
from app.lab.study import RunProgress


class Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_on_a_terminal_the_bar_counts_with_an_eta_and_ends_full():
    out = Terminal()
    with FrameProgress("bench", file=out, mininterval=0.0) as progress:
        for done in range(1, 4):
            progress(done, 10)
    text = out.getvalue()
    assert "bench" in text and "3/10" in text and "frame" in text
    assert "<" in text  # tqdm's elapsed<remaining: the ETA
    assert text.rstrip().splitlines()[-1].split("\r")[-1].count("10/10") == 1  # left done


def test_study_bar_names_the_running_run_and_counts_those_done():
    out = Terminal()
    progress = RunProgress(file=out)
    progress(1, 3, "full-quality")
    progress(2, 3, "cps-block16")
    assert "1/3" in out.getvalue() and "cps-block16" in out.getvalue()
    progress.finish()
    assert "3/3" in out.getvalue() and progress.bar is None


def test_photon_trace_bar_goes_to_100_percent_once():
    out = Terminal()
    trace = TraceProgress(file=out, mininterval=0.0)
    for f in (0.0, 0.5, 1.0, 1.0):
        trace(f)
    text = out.getvalue()
    assert "50%" in text and "<" in text  # the ETA
    assert text.count("\n") == 1 and text.rstrip().endswith("]") and trace.bar is None


def test_not_a_terminal_no_progress_text_at_all():
    out = io.StringIO()
    with FrameProgress("bench", file=out) as progress:
        for done in range(1, 11):
            progress(done, 10)
    trace = TraceProgress(file=out)
    trace(0.5)
    trace(1.0)
    assert out.getvalue() == ""


def test_bench_command_writes_no_progress_into_a_captured_stderr(tmp_path, capsys):
    out = tmp_path / "bench.json"
    args = ["bench", "--scene", "texture-test", "--frames", "4", "--warmup", "1"]
    assert main([*args, "--size", "160x90", "--out", str(out)]) == 0
    captured = capsys.readouterr()
    assert "\r" not in captured.err and "frame/s" not in captured.err
    assert "fps" in captured.out and out.exists()
