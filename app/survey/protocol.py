"""A study protocol: conditions (settings presets), scene and path, timing, questionnaires.

Written by the experimenter as TOML or JSON (``vrpreview survey template`` prints one) and
checked in full before anything runs: every problem is listed in one :class:`ProtocolError`
that names the file and the field, never a traceback.
"""

from __future__ import annotations

import importlib
import json
import math
import random
import string
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from app.settings import Settings, SettingsError
from app.survey.latin import balanced_latin_square, order_for

# TOML protocols: tomllib on Python 3.11+, tomli on 3.10 if installed; otherwise JSON only.
tomllib: Any = None
for _name in ("tomllib", "tomli"):
    try:
        tomllib = importlib.import_module(_name)
        break
    except ImportError:  # pragma: no cover - Python 3.10 without tomli
        continue

QUESTIONNAIRES = ("ssq", "quality")
ON_STOP = ("end", "continue")
TOP_KEYS = {
    "name",
    "scene",
    "path",
    "exposure_s",
    "rest_s",
    "blind",
    "seed",
    "on_stop",
    "baseline",
    "after_exposure",
    "base_settings",
    "conditions",
}
CONDITION_KEYS = {"name", "settings", "preset"}

TEMPLATE = """\
# A vrpreview study protocol (TOML). Check it with:  vrpreview survey check THIS_FILE
name = "corridor-cps"        # names the study (and its default data folder)
scene = "corridor"           # a built-in scene or a model file
path = "corridor_walk"       # a built-in path or a recorded path file; omit: the scene's own walk
exposure_s = 60              # seconds of each exposure (the path loops if shorter)
rest_s = 120                 # rest between conditions, after the questionnaires
blind = true                 # the experimenter sees conditions only as codes (A, B, ...)
seed = 16                    # fixes which condition gets which code
on_stop = "end"              # after "I feel unwell, stop": questionnaires, then "end" or "continue"
baseline = ["ssq"]           # questionnaires before the first exposure
after_exposure = ["ssq", "quality"]

# Settings every condition shares (any key of: vrpreview --list-settings); defaults otherwise
[base_settings]
"stereo.ipd_mm" = 64

[[conditions]]
name = "none"
settings = { "cps.mode" = "none" }

[[conditions]]
name = "cps"
settings = { "cps.mode" = "cps" }
"""


class ProtocolError(ValueError):
    """A protocol that cannot be used; the message lists every problem found."""


@dataclass(frozen=True)
class Condition:
    name: str
    code: str  # what the experimenter sees when the study is blind
    settings: dict[str, Any] = field(default_factory=dict)  # dotted key -> value


@dataclass(frozen=True)
class Protocol:
    name: str
    scene: str
    path: str | None
    exposure_s: float
    rest_s: float
    blind: bool
    seed: int
    on_stop: str
    baseline: tuple[str, ...]
    after_exposure: tuple[str, ...]
    base_settings: dict[str, Any]
    conditions: tuple[Condition, ...]

    def square(self) -> list[list[int]]:
        return balanced_latin_square(len(self.conditions))

    def order(self, participant_index: int) -> list[Condition]:
        """The conditions in the order the ``participant_index``-th participant meets them."""
        return [self.conditions[i] for i in order_for(participant_index, len(self.conditions))]

    def condition(self, name: str) -> Condition:
        for c in self.conditions:
            if c.name == name:
                return c
        raise KeyError(name)

    def shown_as(self, c: Condition) -> str:
        """How the experimenter's screen names a condition."""
        return f"condition {c.code}" if self.blind else f"condition {c.code} ({c.name})"

    def settings_for(self, c: Condition) -> Settings:
        """Defaults, then the shared settings, then the condition's own."""
        s = Settings()
        for key, value in {**self.base_settings, **c.settings}.items():
            s.set(key, value)
        return s

    def to_dict(self) -> dict[str, Any]:
        return {
            "vrpreview_protocol": 1,
            "name": self.name,
            "scene": self.scene,
            "path": self.path,
            "exposure_s": self.exposure_s,
            "rest_s": self.rest_s,
            "blind": self.blind,
            "seed": self.seed,
            "on_stop": self.on_stop,
            "baseline": list(self.baseline),
            "after_exposure": list(self.after_exposure),
            "base_settings": dict(self.base_settings),
            "conditions": [{"name": c.name, "settings": dict(c.settings)} for c in self.conditions],
        }


def load_protocol(path: str | Path) -> Protocol:
    """Read a ``.toml`` or ``.json`` protocol; ProtocolError if it cannot be used."""
    p = Path(path)
    try:
        raw = p.read_bytes()
    except OSError as exc:
        raise ProtocolError(f"cannot read protocol {p}: {exc.strerror or exc}") from exc
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise ProtocolError(f"{p}: not a text file ({exc})") from exc
    if p.suffix.lower() == ".json" or text.lstrip().startswith("{"):
        try:
            doc = json.loads(text)
        except json.JSONDecodeError as exc:
            raise ProtocolError(f"{p}: not valid JSON: {exc.msg} (line {exc.lineno})") from exc
    elif tomllib is None:
        raise ProtocolError(f"{p}: TOML needs Python 3.11 or tomli; write the protocol as JSON")
    else:
        try:
            doc = tomllib.loads(text)
        except tomllib.TOMLDecodeError as exc:
            raise ProtocolError(f"{p}: not valid TOML: {exc}") from exc
    return protocol_from_dict(doc, str(p), p.parent, default_name=p.stem)


def protocol_from_dict(
    doc: Any, origin: str = "protocol", base_dir: Path | None = None, default_name: str = "study"
) -> Protocol:
    errors: list[str] = []
    if not isinstance(doc, dict):
        raise ProtocolError(f"{origin}: expected a table of settings at the top")
    doc = {k: v for k, v in doc.items() if k != "vrpreview_protocol"}
    unknown = sorted(set(doc) - TOP_KEYS)
    if unknown:
        errors.append(
            f"unknown field(s) {', '.join(unknown)} (known: {', '.join(sorted(TOP_KEYS))})"
        )

    def text(key: str, default: str | None) -> str | None:
        v = doc.get(key, default)
        if v is None:
            return None
        if not isinstance(v, str) or not v.strip():
            errors.append(f"{key}: expected a non-empty text, got {v!r}")
            return default
        return v.strip()

    def number(key: str, default: float, positive: bool) -> float:
        v = doc.get(key, default)
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            errors.append(f"{key}: expected a number of seconds, got {v!r}")
            return default
        if v < 0 or (positive and v == 0):
            errors.append(f"{key}: must be {'above' if positive else 'at least'} 0, got {v}")
            return default
        return float(v)

    def flag(key: str, default: bool) -> bool:
        v = doc.get(key, default)
        if not isinstance(v, bool):
            errors.append(f"{key}: expected true or false, got {v!r}")
            return default
        return v

    def questionnaires(key: str, default: list[str]) -> tuple[str, ...]:
        v = doc.get(key, default)
        if not isinstance(v, list) or not all(isinstance(q, str) for q in v):
            errors.append(f'{key}: expected a list such as ["ssq", "quality"], got {v!r}')
            return tuple(default)
        bad = [q for q in v if q not in QUESTIONNAIRES]
        if bad:
            errors.append(f"{key}: unknown questionnaire {', '.join(bad)} (known: ssq, quality)")
        if len(set(v)) != len(v):
            errors.append(f"{key}: a questionnaire is listed twice")
        return tuple(q for q in v if q in QUESTIONNAIRES)

    name = text("name", default_name) or default_name
    scene = text("scene", "corridor") or "corridor"
    path = text("path", None)
    exposure_s = number("exposure_s", 60.0, positive=True)
    rest_s = number("rest_s", 120.0, positive=False)
    blind = flag("blind", True)
    seed = doc.get("seed", 0)
    if isinstance(seed, bool) or not isinstance(seed, int):
        errors.append(f"seed: expected a whole number, got {seed!r}")
        seed = 0
    on_stop = doc.get("on_stop", "end")
    if on_stop not in ON_STOP:
        errors.append(f'on_stop: expected "end" or "continue", got {on_stop!r}')
        on_stop = "end"
    baseline = questionnaires("baseline", ["ssq"])
    after = questionnaires("after_exposure", ["ssq", "quality"])
    if "ssq" in after and "ssq" not in baseline:
        errors.append('baseline: the SSQ after exposure needs an SSQ at baseline (add "ssq")')

    base_settings = _settings_table(doc.get("base_settings", {}), "base_settings", errors)
    scene = _check_scene(scene, base_dir, errors)
    path = _check_path(path, base_dir, errors)

    conds_doc = doc.get("conditions")
    conditions: list[tuple[str, dict[str, Any]]] = []
    if not isinstance(conds_doc, list) or not conds_doc:
        errors.append("conditions: expected a list of at least one condition ([[conditions]])")
        conds_doc = []
    for i, c in enumerate(conds_doc):
        where = f"conditions[{i + 1}]"
        if not isinstance(c, dict):
            errors.append(f"{where}: expected a table with a name and settings")
            continue
        bad = sorted(set(c) - CONDITION_KEYS)
        if bad:
            errors.append(
                f"{where}: unknown field(s) {', '.join(bad)} (known: name, settings, preset)"
            )
        cname = c.get("name")
        if not isinstance(cname, str) or not cname.strip():
            errors.append(f"{where}: every condition needs a name")
            continue
        cname = cname.strip()
        where = f"conditions[{i + 1}] ({cname})"
        values: dict[str, Any] = {}
        if "preset" in c:
            values.update(_preset(c["preset"], base_dir, where, errors))
        values.update(_settings_table(c.get("settings", {}), f"{where}.settings", errors))
        conditions.append((cname, values))
    names = [n for n, _ in conditions]
    dup = sorted({n for n in names if names.count(n) > 1})
    if dup:
        errors.append(f"conditions: the name(s) {', '.join(dup)} are used twice")
    if len(conditions) > len(string.ascii_uppercase):
        errors.append("conditions: at most 26 conditions")
    if errors:
        raise ProtocolError(
            f"{origin}: " + ("\n  " if len(errors) > 1 else "") + "\n  ".join(errors)
        )
    codes = list(string.ascii_uppercase[: len(conditions)])
    random.Random(seed).shuffle(codes)  # the code does not give away the order in the file
    return Protocol(
        name,
        scene,
        path,
        exposure_s,
        rest_s,
        blind,
        int(seed),
        str(on_stop),
        baseline,
        after,
        base_settings,
        tuple(Condition(n, code, v) for (n, v), code in zip(conditions, codes)),
    )


def _flatten(d: dict[str, Any], prefix: str = "") -> list[tuple[str, Any]]:
    out: list[tuple[str, Any]] = []
    for k, v in d.items():
        if isinstance(v, dict):
            out += _flatten(v, f"{prefix}{k}.")
        else:
            out.append((f"{prefix}{k}", v))
    return out


def _settings_table(table: Any, where: str, errors: list[str]) -> dict[str, Any]:
    """Dotted keys (nested tables allowed), each checked against the settings tree."""
    if not isinstance(table, dict):
        errors.append(f"{where}: expected a table of setting = value")
        return {}
    out: dict[str, Any] = {}
    probe = Settings()
    for key, value in _flatten(table):
        try:
            probe.set(key, value)
        except SettingsError as exc:
            msg = str(exc)
            if msg.startswith("unknown setting"):
                msg = f"unknown setting '{key}' (see: vrpreview --list-settings)"
            errors.append(f"{where}: {msg}")
            continue
        out[key] = probe.get(key)  # coerced: "true" -> True, "2" -> 2
    return out


def _preset(value: Any, base_dir: Path | None, where: str, errors: list[str]) -> dict[str, Any]:
    if not isinstance(value, str):
        errors.append(f"{where}.preset: expected a file name")
        return {}
    p = Path(value).expanduser()
    if not p.is_absolute() and base_dir is not None:
        p = base_dir / p
    try:
        loaded = Settings.load(p)
    except SettingsError as exc:
        errors.append(f"{where}.preset: {exc}")
        return {}
    default = Settings()
    return {k: loaded.get(k) for k in loaded.keys() if loaded.get(k) != default.get(k)}


def _check_scene(scene: str, base_dir: Path | None, errors: list[str]) -> str:
    from app.scenes import BUILTIN

    if scene in BUILTIN:
        return scene
    p = Path(scene).expanduser()
    if not p.is_absolute() and base_dir is not None:
        p = base_dir / p
    if not p.is_file():
        errors.append(
            f"scene: '{scene}' is neither a built-in scene ({', '.join(BUILTIN)}) nor a file"
        )
        return scene
    return str(p.resolve())


def _check_path(path: str | None, base_dir: Path | None, errors: list[str]) -> str | None:
    if path is None:
        return None
    from app.paths import PathError
    from app.scenes import resolve_path

    candidate = path
    p = Path(path).expanduser()
    if p.suffix and not p.is_absolute() and base_dir is not None:
        candidate = str(base_dir / p)
    try:
        resolve_path(candidate)
    except (PathError, OSError) as exc:
        errors.append(f"path: '{path}' is neither a built-in path nor a readable path file ({exc})")
        return path
    return str(Path(candidate).resolve()) if Path(candidate).suffix else candidate
