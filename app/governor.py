"""The frame-time governor: each frame, the next frame's knobs for a target frame rate.

Funkhouser & Séquin 1993 (adaptive display) as a greedy step per frame: a cost model learnt
online from the per-pass timers predicts each candidate's frame time, an error model says
how much quality a knob step costs, and the governor takes the step with the least error per
millisecond saved when over budget, and gives back the step with the most error per
millisecond when there is time. Hysteresis (a dead band between ``RESTORE_BELOW`` and 1.0 of
the budget, ``MIN_FRAMES`` between changes and a back-off for a restore that overshot) keeps
it from oscillating. The fovea's knobs (sharp area, falloff) go last and come back first.

Qt-free: the renderer calls :meth:`Governor.observe` after each frame and applies
:attr:`Governor.overrides` to a copy of the user's settings for the next one. The knobs, their
errors and the cost model's shape are :mod:`app.governor_model` (re-exported here).
"""

from __future__ import annotations

import logging
import math
from collections import deque
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from app.governor_model import (
    CATEGORIES,
    CATEGORY_PRIORS,
    CATEGORY_WORDS,
    ERROR_TABLE,
    FOVEA_WEIGHT,
    KNOBS,
    LOD_ERRORS,
    LOD_SHARE,
    PRIOR_KNOBS,
    Knob,
    category,
    cost_factors,
    load_error_table,
    measured_knobs,
    shown_value,
    step_weight,
)
from app.governor_programs import program_key, program_variants
from app.settings import Settings, SettingsError

__all__ = [
    "CATEGORIES",
    "ERROR_TABLE",
    "FOVEA_WEIGHT",
    "KNOBS",
    "LOD_ERRORS",
    "LOD_SHARE",
    "PRIOR_KNOBS",
    "Decision",
    "Governor",
    "Knob",
    "apply_overrides",
    "category",
    "cost_factors",
    "load_error_table",
    "measured_knobs",
    "program_key",
    "step_weight",
    "still_overrides",
    "target_fps",
]

log = logging.getLogger(__name__)

#: Act when the frame-time average is over the budget; give quality back below this share.
RESTORE_BELOW = 0.8
#: Aim a degrading step at this share of the budget; a restore must be predicted below
#: RESTORE_AIM (lower: a frame's time varies by 10 % as the view moves, and a restore that
#: lands at the top of the band is lowered again a few frames later, each change a spike).
AIM = 0.9
RESTORE_AIM = 0.85
#: Frames between two changes (the timers settle on the new knobs first).
MIN_FRAMES = 4
#: Unless each frame since (the first aside) took over FAR_OVER x the budget: the next step
#: comes after FAST_FRAMES (a scene just opened, a view with far more lights).
FAR_OVER = 1.5
FAST_FRAMES = 3
#: Weight of the exponential moving averages (frame time, per-category costs).
EMA = 0.3
#: Frames not learnt from (shader variants compile, targets are made).
WARMUP_FRAMES = 1
#: Knob steps one decision may take: many when far over the budget, else a few.
MAX_STEPS_FAR, MAX_STEPS_NEAR = 6, 2

#: A step back that the model predicts faster by at least this much is taken at once.
FREE_RESTORE_MS = 0.5
#: A trade of knobs (one given back, another lowered: :meth:`Governor._swap`) is made where
#: the model says it loses this much less quality (the smallest measured steps' size) and
#: takes no more time; looked for every SWAP_EVERY frames while the frame rate holds.
SWAP_GAIN = 0.01
SWAP_EVERY = 2 * 4
#: Frames within budget counts those up to this share over it (the benchmark's +10 %).
WITHIN = 1.1
#: The recent frames whose spread sets the aim (:meth:`Governor.aim_ms`): the steadiest
#: frame rate holds its budget as is, one whose frames vary (the view, the machine's other
#: work) aims lower so that nine frames in ten stay within it.
SPREAD_FRAMES = 96
SPREAD_QUANTILE = 0.9
MAX_SPREAD = 1.5


#: What the governor shows while the picture refines (the viewer stands still).
FULL_QUALITY: dict[str, Any] = {
    "render.scale": 1.0,
    "cps.mode": "none",
    "render.lod_bias": 0,
    "tcr.level_bias": 0,
    "render.shadows": "soft",
    "render.upscaler": "edge",
}


def still_overrides(user: Settings) -> dict[str, Any]:
    """The governor's overrides while the picture refines: :data:`FULL_QUALITY`, but shadows
    the user turned off stay off (the same room lit alike, as ``app.quality.full_quality``
    has it; hard shadows, the governor's or the user's, become soft)."""
    out = {k: v for k, v in FULL_QUALITY.items() if _exists(user, k)}
    if _exists(user, "render.shadows") and user.render.shadows == "off":
        out.pop("render.shadows", None)
    return out


def target_fps(settings: Settings, display_hz: float | None) -> float:
    """The frame rate to hold: the number, or for ``auto`` the display's refresh (0 where
    there is no display: headless hosts keep fixed settings, so runs are deterministic)."""
    text = str(settings.render.target_fps)
    if text == "auto":
        return float(display_hz) if display_hz and math.isfinite(display_hz) else 0.0
    return float(text)


@dataclass
class Decision:
    """One change the governor made, in words for the panel and the benchmark."""

    frame: int
    action: str  # "lower", "restore" or "trade" (lowered in place of a restore)
    knob: str
    value: Any
    frame_ms: float
    budget_ms: float
    largest: str  # the costliest category then
    instead: str = ""  # a trade (action "trade"): the knob given back for this one's step


#: The range of a learnt step factor (one measurement sets it: the model's shape can be off
#: by 2x, a view's changing content by about 20 %).
STEP_SCALE_RANGE = (0.25, 4.0)


@dataclass
class _StepTrial:
    """A change of one knob, measured: each category's steady cost before, its costs after."""

    key: str
    before_position: dict[str, int]
    after_position: dict[str, int]
    before: dict[str, float]
    after: list[dict[str, float]] = field(default_factory=list)


@dataclass
class Governor:
    """The walking state: each knob's step (0: the user's value), the learnt cost model."""

    position: dict[str, int] = field(default_factory=dict)
    knobs: tuple[Knob, ...] = KNOBS  # with their errors (measured_knobs of another table)
    base_ms: dict[str, float] = field(default_factory=dict)  # category cost at full quality
    overhead_ms: float | None = None
    ema_ms: float | None = None
    since_change: int = MIN_FRAMES  # the first measured frame may act at once
    frames: int = 0
    budget_ms: float = 0.0
    overrides: dict[str, Any] = field(default_factory=dict)
    history: list[Decision] = field(default_factory=list)
    refining: bool = False
    _backoff: dict[str, int] = field(default_factory=dict)  # knob -> frames it may not restore
    _overshoots: dict[str, int] = field(default_factory=dict)  # restores of a knob that overshot
    # _knobs_all and the user's knob values, for this frame's settings
    _steps: tuple[Settings, list, dict[str, Any]] | None = None
    # The last restore (or trade), when, and the position before it: a frame over budget
    # soon after it undoes it (overshoot check).
    _restored: tuple[str, int, dict[str, int]] | None = None
    # What the timers taught of each knob step: (key, step) -> category -> a factor on the
    # model's (the model's shape can be wrong for a scene: simpler geometry saves nothing
    # where the frame is not drawing triangles; CPS's lighting saves less than modelled).
    step_scale: dict[tuple[str, int], dict[str, float]] = field(default_factory=dict)
    category_ms: dict[str, float] = field(default_factory=dict)  # measured, steady (EMA)
    _pending: _StepTrial | None = None  # a one-knob change being measured
    _user_values: dict[str, Any] | None = None  # the user's knob values last frame
    # The renderer's count of the triangles in view per allowed error (LOD_ERRORS): what
    # each level-of-detail step draws in this room (None: the LOD_SHARE priors).
    lod_triangles: dict[float, int] | None = None
    _recent: deque[float] = field(default_factory=lambda: deque(maxlen=SPREAD_FRAMES))
    _local: deque[float] = field(default_factory=lambda: deque(maxlen=8))  # raw frame times
    _skip: bool = False  # the next frame's time the host's own work made slower (skip_next)
    at_floor: bool = False  # the last time over budget, no step was left to take

    # -- the knobs -----------------------------------------------------------------------------
    def _knobs(self, user: Settings) -> list[tuple[Knob, list[dict[str, Any]]]]:
        out = []
        for knob, steps in self._knobs_all(user):
            if knob.key.startswith("cps.") and user.render.path != "deferred":
                continue
            if knob.key == "tcr.level_bias" and not user.tcr.enabled:
                continue
            if knob.fovea and not self._cps_on(user):
                continue
            if knob.key == "cps.max_level" and user.cps.mode not in ("none", "cps"):
                continue
            out.append((knob, steps))
        return out

    def _cps_on(self, user: Settings) -> bool:
        return user.cps.mode == "cps" or self.position.get("cps.max_level", 0) > 0

    def _values(self, user: Settings, position: dict[str, int]) -> dict[str, Any]:
        """Every knob key's value at ``position`` (user values where the step is 0)."""
        knobs = self._knobs_all(user)
        assert self._steps is not None
        values = dict(self._steps[2])
        for knob, steps in knobs:
            i = position.get(knob.key, 0)
            if i > 0:
                values.update(steps[min(i, len(steps)) - 1])
        return values

    def _knobs_all(self, user: Settings) -> list[tuple[Knob, list[dict[str, Any]]]]:
        """Every knob with steps below the user's values (worked out once per frame)."""
        if self._steps is not None and self._steps[0] is user:
            return self._steps[1]
        knobs = [(k, steps) for k in self.knobs if (steps := k.usable_steps(user))]
        values: dict[str, Any] = {}
        for knob in self.knobs:
            for key in {knob.key, *(k for s in knob.steps for k in s)}:
                if _exists(user, key):
                    values[key] = user.get(key)
        self._steps = (user, knobs, values)
        return knobs

    def _overrides(self, user: Settings) -> dict[str, Any]:
        out: dict[str, Any] = {}
        for knob, steps in self._knobs_all(user):
            i = self.position.get(knob.key, 0)
            if i > 0:
                out.update(steps[min(i, len(steps)) - 1])
        return out

    # -- the cost model ------------------------------------------------------------------------
    def _factors(self, user: Settings, position: dict[str, int]) -> dict[str, float]:
        """The model's factors at ``position`` times what the timers taught of each knob
        step (:meth:`_learn_step`)."""
        f = cost_factors(self._values(user, position), self.lod_triangles)
        for key, i in position.items():
            for c, scale in self.step_scale.get((key, i), {}).items():
                f[c] *= scale
        return f

    def predict(self, user: Settings, position: dict[str, int]) -> float:
        """Predicted frame time (ms) at ``position``."""
        f = self._factors(user, position)
        return (self.overhead_ms or 0.0) + sum(self._base(c) * f[c] for c in CATEGORIES)

    def _base(self, c: str) -> float:
        """Category ``c``'s learnt cost at full quality, or its prior from a measured one."""
        if c in self.base_ms:
            return self.base_ms[c]
        other, share = CATEGORY_PRIORS.get(c, ("", 0.0))
        return self.base_ms.get(other, 0.0) * share

    def new_scene(self) -> None:
        """Another room: what was learnt of the costs is forgotten (the walking state
        stays: a heavier room lowers more from where it is)."""
        self.base_ms.clear()
        self.lod_triangles = None
        self._recent.clear()
        self._local.clear()
        self.overhead_ms = None
        self.ema_ms = None
        self.at_floor = False
        self._forget_steps()

    def skip_next(self) -> None:
        """The host did work of its own between this frame and the next (the benchmark's
        full-quality reference: the next frame measured 20-25 % slower on llvmpipe): the next
        frame's time is neither learnt from nor counted in the spread."""
        self._skip = True

    def _forget_steps(self) -> None:
        self.step_scale.clear()
        self.category_ms.clear()
        self._pending = None

    def _learn(self, user: Settings, pass_ms: dict[str, float], frame_ms: float) -> None:
        f = self._factors(user, self.position)
        per_cat = dict.fromkeys(CATEGORIES, 0.0)
        for name, ms in pass_ms.items():
            per_cat[category(name)] += max(0.0, float(ms))
        for c, ms in per_cat.items():
            if f[c] <= 0.0:  # not running at these knobs: nothing to learn of it
                continue
            base = ms / max(f[c], 1e-3)
            old = self.base_ms.get(c)
            self.base_ms[c] = base if old is None else old + EMA * (base - old)
        if self._pending is not None:
            self._pending.after.append(per_cat)
        else:
            for c, ms in per_cat.items():
                old = self.category_ms.get(c)
                self.category_ms[c] = ms if old is None else old + EMA * (ms - old)
        rest = max(0.0, frame_ms - sum(per_cat.values()))
        self.overhead_ms = (
            rest
            if self.overhead_ms is None
            else (self.overhead_ms + EMA * (rest - self.overhead_ms))
        )

    def largest_cost(self, user: Settings) -> str:
        f = self._factors(user, self.position)
        costs = {c: self._base(c) * f[c] for c in CATEGORIES}
        return max(costs, key=lambda c: costs[c]) if costs else "pixels"

    # -- one frame -----------------------------------------------------------------------------
    def observe(
        self,
        user: Settings,
        pass_ms: dict[str, float],
        frame_ms: float,
        display_hz: float | None = None,
        refining: bool = False,
        lod_triangles: dict[float, int] | None = None,
    ) -> dict[str, Any]:
        """Learn from the frame just drawn and choose the next frame's overrides (keys to
        values, applied over a copy of the user's settings); ``lod_triangles``: a new count
        of the triangles in view per allowed error (see :attr:`lod_triangles`)."""
        self.frames += 1
        if lod_triangles:
            self.lod_triangles = dict(lod_triangles)
        self._steps = None  # the user may have changed a setting since the last frame
        self._knobs_all(user)  # the user's knob values, worked out once for this frame
        assert self._steps is not None
        mine = self._steps[2]
        if self._user_values is not None and mine != self._user_values:
            self._forget_steps()  # the user changed a knob: the steps start from other values
        self._user_values = dict(mine)
        fps = target_fps(user, display_hz)
        self.budget_ms = 1000.0 / fps if fps > 0 else 0.0
        self.refining = bool(refining)
        if fps <= 0:  # fixed settings: forget the walking state
            self.position.clear()
            self.overrides = {}
            return self.overrides
        if self.refining:  # standing still: full quality; the walking state stays
            self.overrides = still_overrides(user)
            return self.overrides
        if not math.isfinite(frame_ms) or frame_ms <= 0:
            self.overrides = self._overrides(user)
            return self.overrides
        if self.frames <= WARMUP_FRAMES or self._skip:
            self._skip = False
            self.overrides = self._overrides(user)
            return self.overrides
        if len(self._local) >= 4:  # each frame against the usual one of the last few: a
            # change of knobs moves that, not the spread
            self._recent.append(frame_ms / float(np.median(self._local)))
        self._local.append(frame_ms)
        if self.since_change > 0:  # the first frame with new knobs compiles and allocates
            self._learn(user, pass_ms, frame_ms)
            self.ema_ms = (
                frame_ms if self.ema_ms is None else self.ema_ms + EMA * (frame_ms - self.ema_ms)
            )
        self.since_change += 1
        for k in list(self._backoff):
            self._backoff[k] -= 1
            if self._backoff[k] <= 0:
                del self._backoff[k]
        budget = self.aim_ms()
        if self._restored is not None and self.frames - self._restored[1] > 6 * MIN_FRAMES:
            self._restored = None
        ready = self.since_change >= MIN_FRAMES
        if not ready and self.since_change >= FAST_FRAMES and self.ema_ms is not None:
            measured = list(self._local)[-min(self.since_change - 1, len(self._local)) :]
            ready = bool(measured) and min(measured) > FAR_OVER * budget
        if ready and self._pending is not None:
            self._learn_step(user)
        if ready and self.ema_ms is not None:
            # The usual frame since the last change: one slow frame (the machine's other
            # work) does not lower the knobs; the aim already leaves room for such frames.
            since = list(self._local)[-min(self.since_change, len(self._local)) :]
            usual = float(np.median(since)) if since else self.ema_ms
            if usual > WITHIN * budget and self._restored is not None:
                self._lower(user, budget)  # the last restore overshot: undone first
            elif self._free_restore(user):
                pass
            elif usual > budget:
                self._lower(user, budget)
            elif usual < RESTORE_BELOW * budget:
                self._restore(user, budget)
            elif self.since_change >= SWAP_EVERY and self.since_change % SWAP_EVERY == 0:
                self._swap(user)
        self.overrides = self._overrides(user)
        return self.overrides

    def spread(self) -> float:
        """How much slower than the usual (median) frame one in ten recent frames is, each
        against the median of the 8 before it (1.0 until there are 16 of them; at most
        MAX_SPREAD)."""
        if len(self._recent) < 16:
            return 1.0
        ratios = np.asarray(self._recent)
        median = float(np.median(ratios))
        if median <= 0:
            return 1.0
        return float(np.clip(np.quantile(ratios, SPREAD_QUANTILE) / median, 1.0, MAX_SPREAD))

    def aim_ms(self) -> float:
        """The frame time the governor holds: the budget, or lower where frames vary so much
        that the slow ones would pass it by more than WITHIN."""
        return min(self.budget_ms, WITHIN * self.budget_ms / self.spread())

    def _changed(
        self, user: Settings, action: str, knob: Knob, value: Any, ema: float, instead: str = ""
    ) -> None:
        self.history.append(
            Decision(
                self.frames,
                action,
                knob.name,
                value,
                ema,
                self.budget_ms,
                self.largest_cost(user),
                instead,
            )
        )
        del self.history[:-200]
        self.at_floor = False
        self.since_change = 0
        self.ema_ms = None

    def _lower(self, user: Settings, budget: float) -> None:
        """Greedy: steps with the least error per ms saved until the prediction fits."""
        if self._restored is not None:  # the last restore overshot: undo it, hold it back
            key, _, before = self._restored
            self._overshoots[key] = self._overshoots.get(key, 0) + 1
            self._backoff[key] = 8 * MIN_FRAMES * 2 ** self._overshoots[key]
            self._restored = None
            # Its costs were mispredicted (a category not measured for a while, the view
            # changed): the frames before it were within budget, so go back there at once
            # rather than take new steps on the same model.
            knob = next((k for k in self.knobs if k.key == key), None)
            i = before.get(key, 0)
            if knob is not None and 0 < i <= len(knob.usable_steps(user)):
                ema = float(self.ema_ms or 0.0)
                self._trial(user, before)
                self.position = dict(before)
                self._changed(user, "lower", knob, _value_at(user, knob, i), ema)
                return
        position = dict(self.position)
        predicted = self.predict(user, position)
        # The model's scale can lag behind the measured average: correct it to the measurement.
        correction = (self.ema_ms or predicted) - predicted
        lowered: list[tuple[Knob, Any]] = []
        most = MAX_STEPS_FAR if (self.ema_ms or 0.0) > 1.5 * budget else MAX_STEPS_NEAR
        self.at_floor = False
        while predicted + correction > AIM * budget and len(lowered) < most:
            knobs = [
                (k, s) for k, s in self._knobs_at(user, position) if position.get(k.key, 0) < len(s)
            ]
            normal = [(k, s) for k, s in knobs if not k.fovea]
            fovea = [(k, s) for k, s in knobs if k.fovea]
            # A last resort, then the fovea's knobs, only when nothing else saves time.
            best = self._best_step(user, position, predicted, normal, last_resorts=False)
            best = best or self._best_step(user, position, predicted, normal)
            best = best or self._best_step(user, position, predicted, fovea)
            if best is None:
                self.at_floor = not lowered  # nothing left to take: the panel says so
                break
            _, knob, j, predicted = best
            position[knob.key] = j
            lowered.append((knob, j))
        if lowered:
            ema = float(self.ema_ms or 0.0)
            self._trial(user, position)
            self.position = position
            for knob, i in lowered:
                steps = knob.usable_steps(user)
                self._changed(user, "lower", knob, steps[i - 1][knob.key], ema)

    def _best_step(
        self,
        user: Settings,
        position: dict[str, int],
        predicted: float,
        pool: list,
        last_resorts: bool = True,
    ) -> tuple[float, Knob, int, float] | None:
        """The step of ``pool``'s knobs with the least error per millisecond it saves:
        (score, knob, new position, predicted ms), None where none saves time. A jump of
        several steps is a candidate too: a knob whose first step saves nothing (CPS adds its
        own passes) may pay further on."""
        best: tuple[float, Knob, int, float] | None = None
        for knob, steps in pool:
            i = position.get(knob.key, 0)
            last = len(steps) - (1 if knob.last_resort and not last_resorts else 0)
            for j in range(i + 1, last + 1):
                after = self.predict(user, {**position, knob.key: j})
                saved = predicted - after
                if saved <= 1e-3:  # a step that saves nothing is never a trade
                    continue
                score = sum(knob.error_of(step) for step in steps[i:j]) / saved
                if best is None or score < best[0]:
                    best = (score, knob, j, after)
        return best

    def _free_restore(self, user: Settings) -> bool:
        """Step a knob back where the learnt model says its lower steps cost time (CPS's own
        passes outweighing what it saves, say): better and faster, taken at once. True when
        it did."""
        predicted = self.predict(user, self.position)
        best: tuple[float, Knob, int] | None = None
        for knob, _steps in self._knobs_all(user):
            i = self.position.get(knob.key, 0)
            if knob.key in self._backoff:  # given back before and over budget after it
                continue
            for j in range(i):
                gain = predicted - self.predict(user, {**self.position, knob.key: j})
                if gain >= FREE_RESTORE_MS and (best is None or gain > best[0]):
                    best = (gain, knob, j)
        if best is None:
            return False
        _, knob, j = best
        self._set_back(user, knob, j)
        return True

    def error(self, user: Settings, position: dict[str, int]) -> float:
        """The quality lost at ``position``: the sum of its steps' errors (the error table's
        increments add up to each knob's loss from full quality)."""
        total = 0.0
        for knob, steps in self._knobs_all(user):
            for step in steps[: position.get(knob.key, 0)]:
                total += knob.error_of(step)
        return total

    def _given_back(self, user: Settings, knob: Knob, j: int) -> dict[str, int]:
        """The position with ``knob`` at step ``j``: CPS off again (the user's is off) takes
        its fovea knobs back with it, as they have nothing to do."""
        position = {**self.position, knob.key: j}
        if knob.key == "cps.max_level" and j == 0 and user.cps.mode != "cps":
            for k in self.knobs:
                if k.fovea:
                    position.pop(k.key, None)
        return position

    def _swap(self, user: Settings) -> bool:
        """Greedy steps are taken one at a time, each the best then: coarse lighting taken at
        full resolution saves much, but after the render scale went down it saves little for
        the same loss. Give back one knob (a step, or all of its steps) and lower another by
        up to three, where the model says that loses at least SWAP_GAIN less quality and
        takes no more time (each trade lowers the loss: no cycle while the model stands).
        True when it did."""
        predicted = self.predict(user, self.position)
        now = self.error(user, self.position)
        best: tuple[float, Knob, int, Knob, int, dict[str, int]] | None = None
        for a, _a_steps in self._knobs_all(user):
            i = self.position.get(a.key, 0)
            if i <= 0 or a.key in self._backoff:
                continue
            for back in sorted({i - 1, 0}):
                base = self._given_back(user, a, back)
                for b, b_steps in self._knobs_at(user, base):
                    if b.key == a.key:
                        continue
                    k = base.get(b.key, 0)
                    last = len(b_steps) - (1 if b.last_resort else 0)
                    for j in range(k + 1, min(k + 3, last) + 1):
                        trial = {**base, b.key: j}
                        if self.predict(user, trial) > predicted:
                            continue
                        gain = now - self.error(user, trial)
                        if gain >= SWAP_GAIN and (best is None or gain > best[0]):
                            best = (gain, a, back, b, j, trial)
        if best is None:
            return False
        _, a, back, b, j, position = best
        ema = float(self.ema_ms or 0.0)
        before = dict(self.position)
        self._trial(user, position)
        self.position = position
        self._changed(user, "restore", a, _value_at(user, a, back), ema)
        self._changed(user, "trade", b, _value_at(user, b, j), ema, a.name)
        self._restored = (a.key, self.frames, before)  # over budget after it: undone
        return True

    def _set_back(self, user: Settings, knob: Knob, j: int) -> None:
        before = dict(self.position)
        position = self._given_back(user, knob, j)
        self._trial(user, position)
        self.position = position
        self._restored = (knob.key, self.frames, before)
        self._changed(user, "restore", knob, _value_at(user, knob, j), float(self.ema_ms or 0.0))

    def _trial(self, user: Settings, position: dict[str, int]) -> None:
        """Measure the change to ``position`` where it moves one knob only (several at once
        cannot be told apart)."""
        keys = {*position, *self.position}
        changed = [k for k in keys if position.get(k, 0) != self.position.get(k, 0)]
        self._pending = None
        if len(changed) == 1 and self.category_ms:
            self._pending = _StepTrial(
                changed[0], dict(self.position), dict(position), dict(self.category_ms)
            )
        else:  # the steady costs start again at the new knobs
            self.category_ms = {}

    def _learn_step(self, user: Settings) -> None:
        """The measured change of each category the model says the knob moves, against the
        model's: the higher step's learnt factor takes it, the steps beyond it too, the ones
        between in part."""
        trial = self._pending
        self._pending = None
        if trial is None or len(trial.after) < 2:
            return
        key = trial.key
        hi = max(trial.before_position.get(key, 0), trial.after_position.get(key, 0))
        if hi <= 0:
            return
        f_before = self._factors(user, trial.before_position)
        f_after = self._factors(user, trial.after_position)
        after = {c: float(np.mean([a[c] for a in trial.after])) for c in CATEGORIES}
        lo = min(trial.before_position.get(key, 0), trial.after_position.get(key, 0))
        steps = max((len(k.steps) for k in self.knobs if k.key == key), default=hi)
        lowered = trial.after_position.get(key, 0) > trial.before_position.get(key, 0)
        for c in CATEGORIES:
            before_ms, after_ms = trial.before.get(c, 0.0), after[c]
            if f_before[c] <= 0.0 or f_after[c] <= 0.0 or before_ms < 0.3 or after_ms <= 0.0:
                continue
            model = f_after[c] / f_before[c]
            if abs(model - 1.0) < 0.02:  # a category this knob does not move
                continue
            seen = after_ms / before_ms
            # The higher step's factor moves (a lowering measured it after, a restore before),
            # the steps beyond it with it and the ones between in part: the chain stays whole.
            miss = seen / model if lowered else model / seen
            lo_s, hi_s = STEP_SCALE_RANGE
            for k in range(lo + 1, max(steps, hi) + 1):
                share = 1.0 if k >= hi else (k - lo) / (hi - lo)
                scales = self.step_scale.setdefault((key, k), {})
                scale = scales.get(c, 1.0) * miss**share
                scales[c] = float(min(hi_s, max(lo_s, scale)))
        for c in CATEGORIES:  # the steady costs, now at the new knobs
            self.category_ms[c] = after[c]

    def _knobs_at(self, user: Settings, position: dict[str, int]) -> list:
        saved, self.position = self.position, position
        try:
            return self._knobs(user)
        finally:
            self.position = saved

    def _restore(self, user: Settings, budget: float) -> None:
        """Give back one step: the fovea's first, then the most error per ms it costs."""
        predicted = self.predict(user, self.position)
        correction = (self.ema_ms or predicted) - predicted
        best: tuple[tuple[int, float], Knob] | None = None
        knobs = self._knobs_all(user)
        resorted = [
            (k, s) for k, s in knobs if k.last_resort and self.position.get(k.key, 0) >= len(s)
        ]
        if resorted:  # a last resort taken: it comes back first, after the fovea's knobs
            knobs = resorted + [(k, s) for k, s in knobs if k.fovea]
        for knob, steps in knobs:
            i = self.position.get(knob.key, 0)
            if i <= 0 or knob.key in self._backoff:
                continue
            trial = {**self.position, knob.key: i - 1}
            after = self.predict(user, trial) + correction
            if after > RESTORE_AIM * budget:
                continue
            cost = max(after - predicted - correction, 1e-3)
            rank = (0 if knob.fovea else 1, -knob.error_of(steps[i - 1]) / cost)
            if best is None or rank < best[0]:
                best = (rank, knob)
        if best is None:
            return
        knob = best[1]
        self._set_back(user, knob, self.position[knob.key] - 1)

    # -- words ---------------------------------------------------------------------------------
    def explain(self, user: Settings) -> list[str]:
        """The panel's lines: the budget, the frame time, each knob away from the user's
        value and why."""
        if self.budget_ms <= 0:
            return ["Frame rate not held: every setting is as you set it."]
        lines = [
            f"Budget {self.budget_ms:.0f} ms a frame ({1000.0 / self.budget_ms:.0f} fps); "
            + (f"frames take {self.ema_ms:.0f} ms." if self.ema_ms else "measuring.")
        ]
        aim = self.aim_ms()
        if aim < self.budget_ms - 0.5:
            lines.append(
                f"Frame times vary (one in ten takes {self.spread():.1f}x the usual): "
                f"aiming at {aim:.0f} ms so that they stay within the budget."
            )
        if self.refining:
            lines.append("Standing still: full quality while the picture refines.")
            return lines
        largest = CATEGORY_WORDS.get(self.largest_cost(user), "drawing")
        changed = False
        for knob, steps in self._knobs_all(user):
            i = self.position.get(knob.key, 0)
            if i <= 0:
                continue
            changed = True
            value = steps[min(i, len(steps)) - 1][knob.key]
            why = next((d for d in reversed(self.history) if d.knob == knob.name), None)
            reason = ""
            if why is not None and why.action == "lower":
                reason = (
                    f" — frame {why.frame_ms:.0f} ms over the {why.budget_ms:.0f} ms budget; "
                    f"{CATEGORY_WORDS.get(why.largest, why.largest)} was the largest cost"
                )
            elif why is not None and why.action == "trade":
                reason = f" — in place of less {why.instead}, which lost more for its time"
            lines.append(f"{knob.name} {shown_value(knob.key, value)}{reason}")
        if not changed:
            lines.append(
                f"Full quality: the frame fits the budget ({largest} is the largest cost)."
            )
        elif self.at_floor and (self.ema_ms or 0.0) > WITHIN * self.budget_ms:
            lines.append(
                "Everything it can simplify is simplified, and this room still takes longer "
                "than the budget on this computer: choose a lower frame rate (Settings, "
                "Frame rate to hold) or a smaller window."
            )
        return lines

    def program_variants(self, user: Settings) -> list[dict[str, Any]]:
        """Overrides that between them draw every shader program the knobs can turn to
        (:func:`app.governor_programs.program_variants`)."""
        return program_variants(user, [steps for _knob, steps in self._knobs(user)])

    def summary(self) -> dict[str, Any]:
        """For the benchmark: the changes made and the knobs at the end."""
        return {
            "changes": len(self.history),
            "lowered": sum(d.action == "lower" for d in self.history),
            "traded": sum(d.action == "trade" for d in self.history),
            "restored": sum(d.action == "restore" for d in self.history),
            "final": dict(self.overrides),
            "aim_ms": round(self.aim_ms(), 2),  # the budget, lowered where frames vary
            # What the timers taught of the model (knob step -> category -> factor on it).
            "learnt": {
                f"{key}#{step}": {c: round(v, 3) for c, v in scales.items() if v != 1.0}
                for (key, step), scales in sorted(self.step_scale.items())
                if any(v != 1.0 for v in scales.values())
            },
            "history": [
                {"frame": d.frame, "action": d.action, "knob": d.knob, "value": d.value}
                for d in self.history[-50:]
            ],
        }


def _value_at(user: Settings, knob: Knob, j: int) -> Any:
    """What ``knob`` is set to at its step ``j`` (0: the user's own value; coarse lighting
    given back shows the user's CPS mode, as "none" when CPS was off)."""
    if j > 0:
        return knob.usable_steps(user)[j - 1][knob.key]
    return user.cps.mode if knob.key == "cps.max_level" else user.get(knob.key)


def _exists(settings: Settings, key: str) -> bool:
    try:
        settings.get(key)
    except SettingsError:
        return False
    return True


def apply_overrides(user: Settings, overrides: dict[str, Any]) -> Settings:
    """A copy of the user's settings with the governor's values (the user's stay as set)."""
    if not overrides:
        return user
    out = user.copy()
    for key, value in overrides.items():
        if _exists(out, key):
            out.set(key, value)
    return out
