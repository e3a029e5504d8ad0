"""The steps of one participant's session, in order, from the protocol and their order.

baseline questionnaires, then per condition: exposure, post-exposure questionnaires, rest
(none after the last). The runner asks :meth:`app.survey.store.ParticipantSession.next_step`
which step is due; that is worked out from the answers on disk, so a resumed session carries on
where the last one stopped.
"""

from __future__ import annotations

from dataclasses import dataclass

from app.survey.protocol import Protocol

BASELINE = "baseline"
POST = "post"


@dataclass(frozen=True)
class Step:
    kind: str  # "questionnaire", "exposure", "rest" or "end"
    position: int | None = None  # 0-based run; None for the baseline
    condition: str | None = None
    questionnaire: str | None = None  # "ssq" or "quality" for questionnaires
    point: str = BASELINE  # "baseline" or "post"

    @property
    def key(self) -> tuple:
        return (self.kind, self.position, self.questionnaire, self.point)


def steps(protocol: Protocol, order: list[str]) -> list[Step]:
    out = [Step("questionnaire", None, None, q, BASELINE) for q in protocol.baseline]
    for pos, cond in enumerate(order):
        out.append(Step("exposure", pos, cond, None, POST))
        out += [Step("questionnaire", pos, cond, q, POST) for q in protocol.after_exposure]
        if pos < len(order) - 1 and protocol.rest_s > 0:
            out.append(Step("rest", pos, cond, None, POST))
    return out
