"""The study's questionnaires (SSQ and the CPS paper's quality items) and SSQ scoring.

Item texts, scales and Kennedy's scoring table live in ``questionnaires.json`` beside this
module; nothing here hard-codes an item. An SSQ symptom may count in two subscales (general
discomfort counts in Nausea and Oculomotor, for instance): each subscale's raw score is the sum
of the symptoms that count in it, weighted by 9.54, 7.58 and 13.92, and the Total is the sum of
the three raw sums times 3.74 (Kennedy et al. 1993, Table 5).
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from functools import cache
from importlib import resources
from typing import Any

SUBSCALES = ("nausea", "oculomotor", "disorientation")
SCORE_KEYS = (*SUBSCALES, "total")


class QuestionnaireError(ValueError):
    """An answer set that cannot be scored (wrong count, out of range, not a number)."""


@dataclass(frozen=True)
class Item:
    id: str
    text: str
    subscales: tuple[str, ...] = ()


@dataclass(frozen=True)
class Questionnaire:
    key: str  # "ssq" or "quality"
    title: str
    instructions: str
    lo: int
    hi: int
    labels: tuple[str, ...]  # one per scale point, lo..hi
    items: tuple[Item, ...]

    def item_ids(self) -> list[str]:
        return [i.id for i in self.items]

    def check(self, item_id: str, value: Any) -> int:
        """The answer as an int, or QuestionnaireError naming what is wrong."""
        if item_id not in self.item_ids():
            raise QuestionnaireError(f"{self.key}: unknown item '{item_id}'")
        return _rating(value, self.lo, self.hi, item_id)


@dataclass(frozen=True)
class SsqScore:
    """Kennedy's four scores and the three raw sums they come from."""

    nausea: float
    oculomotor: float
    disorientation: float
    total: float
    raw: tuple[int, int, int]

    def as_dict(self) -> dict[str, float]:
        return {k: getattr(self, k) for k in SCORE_KEYS}


@cache
def _data() -> dict[str, Any]:
    text = resources.files("app.survey").joinpath("questionnaires.json").read_text("utf-8")
    doc = json.loads(text)
    if doc.get("vrpreview_questionnaires") != 1:
        raise RuntimeError("app/survey/questionnaires.json: unknown format")
    return doc


@cache
def questionnaire(key: str) -> Questionnaire:
    """``ssq`` or ``quality``, as written in the data file."""
    doc = _data()
    if key not in ("ssq", "quality"):
        raise QuestionnaireError(f"unknown questionnaire '{key}' (known: ssq, quality)")
    q = doc[key]
    scale = q["scale"]
    items = tuple(Item(i["id"], i["text"], tuple(i.get("subscales", ()))) for i in q["items"])
    return Questionnaire(
        key,
        q["title"],
        q.get("instructions", ""),
        int(scale["min"]),
        int(scale["max"]),
        tuple(scale["labels"]),
        items,
    )


def ssq_weights() -> dict[str, float]:
    """Kennedy's weights: the three subscales and the total."""
    doc = _data()["ssq"]
    out = {k: float(doc["subscales"][k]["weight"]) for k in SUBSCALES}
    out["total"] = float(doc["total"]["weight"])
    return out


def _rating(value: Any, lo: int, hi: int, what: str) -> int:
    if isinstance(value, bool):
        raise QuestionnaireError(f"{what}: {value!r} is not a rating")
    try:
        as_float = float(value)
    except (TypeError, ValueError):
        raise QuestionnaireError(f"{what}: {value!r} is not a number {lo}-{hi}") from None
    if not math.isfinite(as_float) or as_float != int(as_float):
        raise QuestionnaireError(f"{what}: {value!r} is not a whole number {lo}-{hi}")
    out = int(as_float)
    if not lo <= out <= hi:
        raise QuestionnaireError(f"{what}: {out} is outside {lo}-{hi}")
    return out


def score_ssq(answers: list[Any] | dict[str, Any]) -> SsqScore:
    """Score 16 ratings 0-3, in the data file's item order (a list) or by item id (a dict)."""
    q = questionnaire("ssq")
    ids = q.item_ids()
    if isinstance(answers, dict):
        missing = [i for i in ids if i not in answers]
        extra = [k for k in answers if k not in ids]
        if missing or extra:
            raise QuestionnaireError(
                "SSQ answers: "
                + "; ".join(
                    p
                    for p in (
                        f"missing {', '.join(missing)}" if missing else "",
                        f"unknown {', '.join(extra)}" if extra else "",
                    )
                    if p
                )
            )
        values = [answers[i] for i in ids]
    else:
        values = list(answers)
        if len(values) != len(ids):
            raise QuestionnaireError(f"the SSQ has {len(ids)} items; got {len(values)} answers")
    ratings = [
        _rating(v, q.lo, q.hi, f"answer {n + 1} ({item.text})")
        for n, (v, item) in enumerate(zip(values, q.items))
    ]
    raw = {s: 0 for s in SUBSCALES}
    for r, item in zip(ratings, q.items):
        for s in item.subscales:
            raw[s] += r
    w = ssq_weights()
    # The weights have two decimals, so every score has at most two: rounding drops float noise.
    scores = {s: round(raw[s] * w[s], 2) for s in SUBSCALES}
    total = round(sum(raw.values()) * w["total"], 2)
    return SsqScore(
        scores["nausea"],
        scores["oculomotor"],
        scores["disorientation"],
        total,
        (raw["nausea"], raw["oculomotor"], raw["disorientation"]),
    )
