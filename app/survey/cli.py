"""``vrpreview survey ...``: score an SSQ, write and check protocols, run, export, analyse.

app/cli.py registers this with two hook lines (:func:`add_parser` and :func:`run`).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from collections.abc import Callable
from pathlib import Path

EXIT_USAGE = 2


def default_study_dir(name: str) -> Path:
    """Where a study's data goes unless the experimenter picks a folder (VRPREVIEW_DATA)."""
    base = os.environ.get("VRPREVIEW_DATA") or Path.home() / ".local" / "share" / "vrpreview"
    return Path(base) / "studies" / name


def add_parser(sub: argparse._SubParsersAction) -> argparse.ArgumentParser:
    p = sub.add_parser(
        "survey",
        help="user studies (SSQ + quality questionnaires, counterbalanced conditions)",
        description="User studies as in the CPS paper: write a protocol (template), check it, "
        "run participants in the window (run), then export and analyse the answers.",
    )
    ss = p.add_subparsers(dest="survey_command", metavar="COMMAND", required=True)
    q = ss.add_parser("ssq", help="score one set of 16 SSQ answers (0-3, in the item order)")
    q.add_argument("answers", nargs="*", metavar="A", help="16 ratings, 0 none ... 3 severe")
    q.add_argument("--json", action="store_true", help="print a JSON object instead")
    t = ss.add_parser("template", help="print (or write) an example protocol: none vs CPS")
    t.add_argument("--out", help="write it to this file (not overwritten if it exists)")
    c = ss.add_parser("check", help="validate a protocol and list the participants' orders")
    c.add_argument("protocol", help="the protocol file (.toml or .json)")
    c.add_argument("--participants", type=int, default=0, help="orders to list (default: 1 square)")
    r = ss.add_parser("run", help="open the window and run one participant's session")
    r.add_argument("protocol", help="the protocol file (.toml or .json)")
    r.add_argument("--dir", help="study folder (default: VRPREVIEW_DATA/studies/NAME)")
    r.add_argument("--participant", help="pseudonymous id, e.g. P07 (asked if not given)")
    r.add_argument("--size", default="1600x900", help="window size, WxH")
    for name in ("analyse", "analyze"):
        a = ss.add_parser(name, help="write report.md, CSV files and plots for a study folder")
        a.add_argument("dir", help="the study folder")
    e = ss.add_parser("export", help="write answers.csv and scores.csv for a study folder")
    e.add_argument("dir", help="the study folder")
    return p


# Opens the session runner in the window: (protocol file, study folder, participant, size) ->
# exit code. The window is ui's; the ``vrpreview`` launcher hands it in, so no model imports ui.
OpenRunner = Callable[[str, Path, "str | None", str], int]


def run(args: argparse.Namespace, open_runner: OpenRunner | None = None) -> int:
    from app.survey.protocol import ProtocolError
    from app.survey.questionnaires import QuestionnaireError
    from app.survey.store import StoreError

    try:
        return _run(args, open_runner)
    except (ProtocolError, QuestionnaireError, StoreError, OSError) as exc:
        print(f"vrpreview survey: error: {exc}", file=sys.stderr)
        return EXIT_USAGE


def _run(args: argparse.Namespace, open_runner: OpenRunner | None) -> int:
    cmd = args.survey_command
    if cmd == "ssq":
        return _ssq(args)
    if cmd == "template":
        from app.fileio import atomic_write_text
        from app.survey.protocol import TEMPLATE

        if not args.out:
            sys.stdout.write(TEMPLATE)
            return 0
        out = Path(args.out)
        if out.exists():
            print(f"vrpreview survey: error: {out} exists; not overwritten", file=sys.stderr)
            return EXIT_USAGE
        atomic_write_text(out, TEMPLATE)
        print(f"wrote {out}; edit it, then: vrpreview survey check {out}")
        return 0
    if cmd == "check":
        return _check(args)
    if cmd in ("analyse", "analyze"):
        from app.survey.analysis import analyse

        result = analyse(args.dir)
        print(result.summary())
        return 0
    if cmd == "export":
        from app.survey.store import export_csv

        paths = export_csv(args.dir)
        print("wrote " + ", ".join(str(p) for p in paths))
        return 0
    if cmd == "run":
        from app.survey.protocol import load_protocol

        protocol = load_protocol(args.protocol)
        folder = Path(args.dir) if args.dir else default_study_dir(protocol.name)
        if open_runner is None:
            print(
                "vrpreview survey: error: the session runner needs the window; start it with "
                "the vrpreview command (or Study > Run a session… in the window)",
                file=sys.stderr,
            )
            return EXIT_USAGE
        return int(open_runner(args.protocol, folder, args.participant, args.size))
    raise AssertionError(cmd)


def _ssq(args: argparse.Namespace) -> int:
    from app.survey.questionnaires import QuestionnaireError, questionnaire, score_ssq

    q = questionnaire("ssq")
    if len(args.answers) != len(q.items):
        order = ", ".join(f"{n + 1} {i.text.lower()}" for n, i in enumerate(q.items))
        raise QuestionnaireError(
            f"expected {len(q.items)} answers (0-3), got {len(args.answers)}; the order: {order}"
        )
    score = score_ssq(args.answers)
    if args.json:
        print(json.dumps(score.as_dict()))
    else:
        for key, label in (
            ("nausea", "Nausea"),
            ("oculomotor", "Oculomotor"),
            ("disorientation", "Disorientation"),
            ("total", "Total"),
        ):
            print(f"{label:<15}{getattr(score, key):8.2f}")
    return 0


def _check(args: argparse.Namespace) -> int:
    from app.survey.protocol import load_protocol

    p = load_protocol(args.protocol)
    square = p.square()
    n = args.participants or len(square)
    print(f"protocol {p.name}: OK")
    print(f"  scene {p.scene}, path {p.path or '(the scene default)'}")
    print(
        f"  exposure {p.exposure_s:g} s, rest {p.rest_s:g} s, blind: {'yes' if p.blind else 'no'}"
    )
    print(
        f"  baseline: {', '.join(p.baseline) or '-'}; after each exposure: "
        f"{', '.join(p.after_exposure) or '-'}"
    )
    for c in p.conditions:
        shown = ", ".join(f"{k}={v}" for k, v in c.settings.items()) or "defaults"
        print(f"  code {c.code}: {c.name} ({shown})")
    print(f"  balanced Latin square of {len(square)} orders; participant orders (codes):")
    for i in range(n):
        print(f"    participant #{i + 1}: " + " ".join(c.code for c in p.order(i)))
    return 0
