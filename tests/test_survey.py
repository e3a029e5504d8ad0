"""The study's models: SSQ scoring, the CLI, counterbalancing, protocol checks, the store."""

from __future__ import annotations

import collections
import json
from pathlib import Path

import pytest

from app.lab.cli import main
from app.survey.latin import balanced_latin_square, order_for
from app.survey.protocol import TEMPLATE, ProtocolError, load_protocol
from app.survey.questionnaires import QuestionnaireError, questionnaire, score_ssq
from app.survey.store import EventLog, StoreError, Study, export_csv

# Kennedy et al. 1993, Table 5, written out by hand: N, O, D per symptom in the data file's order.
KENNEDY = [
    ("general discomfort", 1, 1, 0),
    ("fatigue", 0, 1, 0),
    ("headache", 0, 1, 0),
    ("eye strain", 0, 1, 0),
    ("difficulty focusing", 0, 1, 1),
    ("increased salivation", 1, 0, 0),
    ("sweating", 1, 0, 0),
    ("nausea", 1, 0, 1),
    ("difficulty concentrating", 1, 1, 0),
    ("fullness of head", 0, 0, 1),
    ("blurred vision", 0, 1, 1),
    ("dizziness (eyes open)", 0, 0, 1),
    ("dizziness (eyes closed)", 0, 0, 1),
    ("vertigo", 0, 0, 1),
    ("stomach awareness", 1, 0, 0),
    ("burping", 1, 0, 0),
]


def test_the_data_file_lists_kennedys_16_symptoms_in_order():
    q = questionnaire("ssq")
    assert [i.text.lower() for i in q.items] == [k[0] for k in KENNEDY]
    assert q.labels == ("none", "slight", "moderate", "severe") and (q.lo, q.hi) == (0, 3)
    quality = questionnaire("quality")
    assert [i.id for i in quality.items] == [
        "presence",
        "speed",
        "image_quality",
        "peripheral_view",
        "game_rules",
    ]
    assert (quality.lo, quality.hi) == (1, 5)


@pytest.mark.parametrize("n", range(16))
@pytest.mark.parametrize("rating", [1, 3])
def test_each_symptom_alone_is_scored_by_kennedys_table(n, rating):
    answers = [0] * 16
    answers[n] = rating
    _, in_n, in_o, in_d = KENNEDY[n]
    s = score_ssq(answers)
    assert s.nausea == pytest.approx(rating * in_n * 9.54)
    assert s.oculomotor == pytest.approx(rating * in_o * 7.58)
    assert s.disorientation == pytest.approx(rating * in_d * 13.92)
    assert s.total == pytest.approx(rating * (in_n + in_o + in_d) * 3.74)


def test_all_symptoms_severe_give_the_published_maxima():
    s = score_ssq([3] * 16)
    assert (s.nausea, s.oculomotor, s.disorientation, s.total) == (200.34, 159.18, 292.32, 235.62)
    assert s.raw == (21, 21, 21)
    assert score_ssq([0] * 16).total == 0.0


def test_scoring_by_item_id_and_bad_answers():
    ids = questionnaire("ssq").item_ids()
    assert score_ssq(dict.fromkeys(ids, 3)).total == 235.62
    for bad in ([0] * 15, [0] * 15 + [4], [0] * 15 + [-1], [0] * 15 + ["x"], [0] * 15 + [1.5]):
        with pytest.raises(QuestionnaireError):
            score_ssq(bad)
    with pytest.raises(QuestionnaireError, match="missing burping"):
        score_ssq(dict.fromkeys(ids[:-1], 0))


def test_cli_scores_one_ssq(capsys):
    assert main(["survey", "ssq", *["3"] * 16]) == 0
    out = capsys.readouterr().out
    assert "Nausea" in out and "200.34" in out and "159.18" in out
    assert "292.32" in out and "235.62" in out
    answers = ["0"] * 16
    answers[4] = "2"  # difficulty focusing: Oculomotor and Disorientation
    assert main(["survey", "ssq", *answers, "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc == {"nausea": 0.0, "oculomotor": 15.16, "disorientation": 27.84, "total": 14.96}


@pytest.mark.parametrize("answers", [["1"] * 15, ["1"] * 15 + ["7"], ["1"] * 15 + ["two"]])
def test_cli_rejects_bad_answers_with_a_message(capsys, answers):
    assert main(["survey", "ssq", *answers]) == 2
    err = capsys.readouterr().err
    assert err.startswith("vrpreview survey: error:") and "Traceback" not in err


@pytest.mark.parametrize("n", range(1, 9))
def test_the_latin_square_is_balanced(n):
    rows = balanced_latin_square(n)
    assert len(rows) == (2 * n if n % 2 and n > 1 else n)
    for r in rows:
        assert sorted(r) == list(range(n))
    reps = len(rows) // n
    for pos in range(n):  # each condition in each position equally often
        assert collections.Counter(r[pos] for r in rows) == dict.fromkeys(range(n), reps)
    if n > 1:  # each condition immediately after each other one equally often
        pairs = collections.Counter((r[i], r[i + 1]) for r in rows for i in range(n - 1))
        expected = {(a, b): reps for a in range(n) for b in range(n) if a != b}
        assert pairs == expected
    assert [order_for(i, n) for i in range(len(rows))] == rows
    assert order_for(len(rows), n) == rows[0]


def test_two_conditions_half_the_participants_in_each_order():
    orders = [tuple(order_for(i, 2)) for i in range(4)]
    assert collections.Counter(orders) == {(0, 1): 2, (1, 0): 2}


def write(tmp_path: Path, text: str, name: str = "study.toml") -> Path:
    p = tmp_path / name
    p.write_text(text, encoding="utf-8")
    return p


def test_the_template_is_a_valid_two_condition_corridor_study(tmp_path):
    p = load_protocol(write(tmp_path, TEMPLATE))
    assert [c.name for c in p.conditions] == ["none", "cps"]
    assert p.scene == "corridor" and p.path == "corridor_walk" and p.blind
    assert sorted(c.code for c in p.conditions) == ["A", "B"]
    assert p.settings_for(p.condition("cps")).cps.mode == "cps"
    assert p.settings_for(p.condition("none")).cps.mode == "none"


def test_a_broken_protocol_lists_every_problem(tmp_path):
    bad = write(
        tmp_path,
        'exposure_s = "long"\nrest_s = -3\nblind = "yes"\ncolour = 1\nbaseline = ["sq"]\n'
        '[[conditions]]\nname = "a"\nsettings = { "cps.mode" = "wobble", "no.such" = 1 }\n'
        '[[conditions]]\nname = "a"\n',
    )
    with pytest.raises(ProtocolError) as info:
        load_protocol(bad)
    msg = str(info.value)
    for part in (
        "exposure_s",
        "rest_s",
        "blind",
        "colour",
        "unknown questionnaire sq",
        "'wobble' is not one of",
        "unknown setting 'no.such'",
        "used twice",
    ):
        assert part in msg
    with pytest.raises(ProtocolError, match="not valid TOML"):
        load_protocol(write(tmp_path, "name = [", "broken.toml"))
    with pytest.raises(ProtocolError, match="not valid JSON"):
        load_protocol(write(tmp_path, "{ nope", "broken.json"))
    with pytest.raises(ProtocolError, match="scene"):
        load_protocol(
            write(tmp_path, 'scene = "nowhere.glb"\n[[conditions]]\nname = "a"\n', "s.toml")
        )


def test_cli_check_shows_codes_and_orders_and_rejects_a_broken_file(tmp_path, capsys):
    good = write(tmp_path, TEMPLATE)
    assert main(["survey", "check", str(good)]) == 0
    out = capsys.readouterr().out
    assert "participant #1: " in out and "participant #2: " in out
    assert main(["survey", "check", str(write(tmp_path, "conditions = 3", "x.toml"))]) == 2
    assert "conditions" in capsys.readouterr().err


def test_template_command_never_overwrites(tmp_path, capsys):
    out = tmp_path / "p.toml"
    assert main(["survey", "template", "--out", str(out)]) == 0
    out.write_text("mine", encoding="utf-8")
    assert main(["survey", "template", "--out", str(out)]) == 2
    assert out.read_text(encoding="utf-8") == "mine"


def tiny_protocol(tmp_path: Path, extra: str = "") -> Path:
    return write(
        tmp_path,
        'name = "t"\nexposure_s = 1\nrest_s = 0\n' + extra + '[[conditions]]\nname = "none"\n'
        'settings = { "cps.mode" = "none" }\n[[conditions]]\nname = "cps"\n'
        'settings = { "cps.mode" = "cps" }\n',
    )


def answer_all(s, value_for=lambda q, i: q.lo):
    step = s.next_step()
    q = questionnaire(step.questionnaire)
    for n, item in enumerate(q.item_ids()):
        s.record_answer(step, item, value_for(q, n))
    s.finish_questionnaire(step)
    return step


def test_a_session_resumes_at_the_first_unanswered_item(tmp_path):
    study = Study(tmp_path / "data", load_protocol(tiny_protocol(tmp_path)))
    s = study.session("P01")
    step = s.next_step()
    assert (step.kind, step.questionnaire, step.point) == ("questionnaire", "ssq", "baseline")
    ids = questionnaire("ssq").item_ids()
    s.record_answer(step, ids[0], 2)
    s.record_answer(step, ids[1], 1)
    s.record_answer(step, ids[1], 3)  # changed: the latest counts, both are kept
    again = Study(tmp_path / "data", load_protocol(tiny_protocol(tmp_path))).session("P01")
    assert again.next_step() == step
    assert again.answers(step) == {ids[0]: 2, ids[1]: 3}
    lines = (tmp_path / "data/participants/P01.jsonl").read_text().splitlines()
    assert [json.loads(x)["type"] for x in lines].count("answer") == 3
    assert json.loads(lines[-1])["type"] == "session_resume"


def test_a_whole_session_then_export_and_no_overwrite(tmp_path):
    study = Study(tmp_path / "data", load_protocol(tiny_protocol(tmp_path)))
    s = study.session("P01")
    answer_all(s)
    kinds = []
    while (step := s.next_step()).kind != "end":
        kinds.append((step.kind, step.questionnaire))
        if step.kind == "exposure":
            s.start_exposure(step, {"cps.mode": "x"})
            s.end_exposure(step, 1.0, False, [16.0, 17.0, 18.0])
        else:
            answer_all(s, lambda q, n: q.hi)
    assert kinds == [("exposure", None), ("questionnaire", "ssq"), ("questionnaire", "quality")] * 2
    assert s.end_session() == "complete"
    summary = json.loads((tmp_path / "data/participants/P01.summary.json").read_text())
    assert summary["status"] == "complete" and summary["ssq"]["run2"]["total"] == 235.62
    with pytest.raises(StoreError, match="already finished"):
        study.session("P01")
    with pytest.raises(StoreError, match="participant id"):
        study.session("Jane Doe")
    assert study.session("P02").order == list(reversed(s.order))  # the next row of the square
    answers_csv, scores_csv = export_csv(tmp_path / "data")
    rows = answers_csv.read_text().splitlines()
    assert len(rows) == 1 + 16 + 2 * (16 + 5)
    scores = scores_csv.read_text().splitlines()
    assert scores[0].startswith("participant,status,order,point")
    assert len([r for r in scores if r.startswith("P01,")]) == 3


def test_a_stop_ends_the_session_after_that_runs_questionnaires(tmp_path):
    study = Study(tmp_path / "data", load_protocol(tiny_protocol(tmp_path)))
    s = study.session("P01")
    answer_all(s)
    step = s.next_step()
    s.start_exposure(step, {})
    s.end_exposure(step, 0.4, True, [])
    assert s.next_step().questionnaire == "ssq"
    answer_all(s)
    answer_all(s)
    assert s.next_step().kind == "end"
    assert s.end_session() == "withdrawn"


def test_a_cut_last_line_is_skipped_and_the_next_event_starts_a_new_line(tmp_path):
    path = tmp_path / "x.jsonl"
    log = EventLog(path)
    log.append("answer", value=1)
    with open(path, "ab") as fh:
        fh.write(b'{"seq":1,"type":"ans')  # what a kill -9 mid-write could leave
    log2 = EventLog(path)
    assert [e["value"] for e in log2.events] == [1] and log2.skipped_lines == 1
    log2.append("answer", value=2)
    assert [e["value"] for e in EventLog(path).events] == [1, 2]


def test_a_study_folder_refuses_a_changed_protocol(tmp_path):
    Study(tmp_path / "data", load_protocol(tiny_protocol(tmp_path)))
    changed = load_protocol(tiny_protocol(tmp_path, "blind = false\n"))
    with pytest.raises(StoreError, match="different protocol"):
        Study(tmp_path / "data", changed)


def simulate(study: Study, pid: str, ssq_post, quality_post, frame_ms=16.0):
    """One participant through the store: baseline all 0, then per condition the given
    answers (functions of the condition name and item number)."""
    s = study.session(pid)
    answer_all(s)
    while (step := s.next_step()).kind != "end":
        if step.kind == "exposure":
            s.start_exposure(step, {})
            s.end_exposure(step, 1.0, False, [frame_ms] * 5)
        elif step.kind == "questionnaire":
            fn = ssq_post if step.questionnaire == "ssq" else quality_post
            answer_all(s, lambda q, n, c=step.condition, fn=fn: fn(c, n))
        else:
            s.start_rest(step)
            s.end_rest(step)
    s.end_session()
    return s


def test_analysis_reports_changes_paired_tests_and_plots(tmp_path, capsys):
    from scipy import stats

    study = Study(tmp_path / "data", load_protocol(tiny_protocol(tmp_path)))
    totals = {"none": [], "cps": []}
    for i in range(4):
        ssq = {"none": [1 if n <= 8 + i else 0 for n in range(16)], "cps": [i % 2] + [0] * 15}
        for c in totals:
            totals[c].append(score_ssq(ssq[c]).total)
        simulate(
            study,
            f"P0{i + 1}",
            lambda c, n, i=i, ssq=ssq: ssq[c][n],
            lambda c, n, i=i: 2 + (c == "cps") + (n == 0 and i % 2),
            frame_ms=12.0 + i,
        )
    assert main(["survey", "analyse", str(tmp_path / "data")]) == 0
    assert "4 participants (4 complete)" in capsys.readouterr().out
    report = (tmp_path / "data/report.md").read_text()
    none_mean = sum(totals["none"]) / 4
    assert f"{none_mean:.2f}" in report  # mean SSQ Total change of "none" (baseline is 0)
    p = stats.ttest_rel(totals["none"], totals["cps"]).pvalue
    row = next(x for x in report.splitlines() if x.startswith("| SSQ Total change | none − cps"))
    assert f"{p:.3f}" in row
    assert "Wilcoxon" in report and "Order effects" in report and "Friedman" not in report
    assert "frame time" in report
    for name in ("ssq.png", "quality.png", "answers.csv", "scores.csv"):
        assert (tmp_path / "data" / name).stat().st_size > 0
    assert (tmp_path / "data/ssq.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_analysis_of_three_conditions_runs_a_friedman_test(tmp_path):
    from app.survey.analysis import analyse

    text = 'name = "three"\nexposure_s = 1\nrest_s = 0\n' + "".join(
        f'[[conditions]]\nname = "{m}"\nsettings = {{ "cps.mode" = "{m}" }}\n'
        for m in ("none", "black-mask", "cps")
    )
    study = Study(tmp_path / "data", load_protocol(write(tmp_path, text)))
    level = {"none": 2, "black-mask": 1, "cps": 0}
    for i in range(6):
        simulate(
            study,
            f"P{i}",
            lambda c, n, i=i: min(3, level[c] + (n < i)),
            lambda c, n: 3,
        )
    analyse(tmp_path / "data")
    report = (tmp_path / "data/report.md").read_text()
    assert "Friedman test over all conditions" in report
    assert "Friedman over runs" in report
    row = next(x for x in report.splitlines() if x.startswith("| SSQ Total change | 6 |"))
    assert float(row.split("|")[4].strip().replace("<", "")) < 0.05
