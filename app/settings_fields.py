"""The words and checks each setting carries (label, unit, help, the paper's term, range) and
how a panel or tooltip shows them: :func:`_opt` declares a setting, the formatters turn its
value into text. Used by the setting sections (``app.settings``, ``app.settings_techniques``).
"""

from __future__ import annotations

import datetime
import math
import textwrap
from dataclasses import field
from typing import Any


class SettingsError(ValueError):
    """A key that does not exist, or a value that does not fit its key.

    ``key`` is the setting concerned (None for a malformed assignment) and ``reason`` the
    message without the key, for a panel that names the setting by its label instead.
    """

    def __init__(self, message: str, key: str | None = None, reason: str | None = None) -> None:
        super().__init__(message)
        self.key = key
        self.reason = reason if reason is not None else message


#: The words a panel shows for each section of settings.
SECTION_TITLES = {
    "stereo": "Stereo view",
    "render": "Picture",
    "navigation": "Walking",
    "gaze": "Gaze",
    "tcr": "Adaptive textures (TCR)",
    "cps": "Coarse pixel shading (CPS)",
    "photons": "Indirect light (photon mapping)",
    "scene": "Model files",
    "sky": "Sun and sky",
}

#: Tooltip lines are wrapped to this many characters, so none runs off the screen.
TOOLTIP_WIDTH = 60


def _opt(
    default: Any,
    help: str,
    *,
    label: str | None = None,
    unit: str = "",
    paper: str | None = None,
    lo: float | None = None,
    hi: float | None = None,
    decimals: int | None = None,
    step: float | None = None,
    scale: float | None = None,
    choices: tuple[str, ...] | None = None,
    choice_labels: dict[str, str] | None = None,
    check: Any = None,
    range_text: str | None = None,
    panel: str | None = None,
    hidden: bool = False,
) -> Any:
    """A setting's default and what the panels, the CLI and validation know about it.

    ``help`` is one plain sentence (the CLI's comment, the tooltip's first line); ``label``
    names the control in words (every setting has one: a test checks), ``unit`` is shown
    after its value and ``paper`` is the paper's term for it ("TCR paper: distance term d").
    ``lo``/``hi`` bound a number and ``choices`` a string (both enforced by
    :meth:`Settings.set`); ``choice_labels`` names a choice's entry. A float is shown with
    ``decimals`` and stepped by ``step``; ``scale`` multiplies the value for display (100: a
    fraction shown in per cent). ``check`` normalises a value or raises ``ValueError`` with
    the reason; ``range_text`` replaces the tooltip's range line (for a number shown as named
    entries); ``panel`` names the section whose panel shows the control when it is not the
    key's own (one control per setting); ``hidden`` keeps a setting out of the panels
    (command line and presets only).
    """
    meta: dict[str, object] = {
        "help": help,
        "unit": unit,
        "lo": lo,
        "hi": hi,
        "choices": choices,
    }
    optional = {
        "paper": paper,
        "decimals": decimals,
        "step": step,
        "scale": scale,
        "check": check,
        "label": label,
        "range_text": range_text,
        "panel": panel,
        "choice_labels": dict(choice_labels) if choice_labels is not None else None,
    }
    meta.update({k: v for k, v in optional.items() if v is not None})
    if hidden:
        meta["hidden"] = True
    return field(default=default, metadata=meta)


def with_unit(number: str, unit: str) -> str:
    """``"64 mm"``, ``"95°"``, ``"100%"``, ``"2×"``: a value and its unit as shown."""
    if not unit:
        return number
    return f"{number}{unit}" if unit[0] in "°%×" else f"{number} {unit}"


def format_number(value: float, decimals: int) -> str:
    """``value`` with at most ``decimals`` decimals and thousands separators, no trailing 0s."""
    text = f"{value:,.{max(0, decimals)}f}"
    if "." in text:
        text = text.rstrip("0").rstrip(".")
    return text


def shown_range(meta: dict[str, Any], integer: bool) -> tuple[float | None, float | None]:
    """The range a control offers: the model's bounds times ``scale``, rounded to what it shows.

    The lower end is rounded up and the upper end down, so every value the control offers is
    one the model accepts.
    """
    scale = float(meta.get("scale") or 1.0)
    digits = 0 if integer else int(meta.get("decimals", 2))
    step = 10.0**digits
    lo, hi = meta.get("lo"), meta.get("hi")
    return (
        math.ceil(lo * scale * step - 1e-9) / step if lo is not None else None,
        math.floor(hi * scale * step + 1e-9) / step if hi is not None else None,
    )


def shows_integer(meta: dict[str, Any], value: Any) -> bool:
    """Whether a number's control shows whole numbers: an int, or a float with 0 decimals."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return False
    return isinstance(value, int) or meta.get("decimals") == 0


def range_text(meta: dict[str, Any], value: Any) -> str:
    """``"Range: 0 to 100 mm."`` for a number (as its control shows it), else ``""``."""
    if meta.get("range_text"):
        return str(meta["range_text"])
    if isinstance(value, bool) or not isinstance(value, (int, float)) or meta.get("choices"):
        return ""
    integer = shows_integer(meta, value)
    lo, hi = shown_range(meta, integer)
    digits = 0 if integer else int(meta.get("decimals", 2))
    unit = str(meta.get("unit", ""))
    if lo is None and hi is None:
        return ""
    if hi is None:
        return f"At least {with_unit(format_number(lo or 0.0, digits), unit)}."
    if lo is None:
        return f"At most {with_unit(format_number(hi, digits), unit)}."
    low = format_number(lo, digits)
    return f"Range: {low} to {with_unit(format_number(hi, digits), unit)}."


def wrap_tooltip(paragraphs: list[str], width: int = TOOLTIP_WIDTH) -> str:
    """Plain-text lines of at most ``width`` characters, one paragraph after another."""
    return "\n".join(textwrap.fill(p, width) for p in paragraphs if p)


def _clock_time(value: Any) -> str:
    """``HH:MM`` on a 24-hour clock."""
    text = str(value).strip()
    try:
        hours, minutes = (int(part) for part in text.split(":"))
    except ValueError:
        raise ValueError(f"{text!r} is not a time of day such as 10:30") from None
    if not (0 <= hours <= 23 and 0 <= minutes <= 59):
        raise ValueError(f"{text!r} is not a time of day such as 10:30")
    return f"{hours:02d}:{minutes:02d}"


def _on_off_auto(value: Any) -> str:
    """``"auto"``, ``"on"`` or ``"off"``; a yes/no value (``true``, ``1``, ``no``) reads as on
    or off, so a file that wrote the setting as a switch still loads."""
    text = str(value).strip().lower()
    if text in ("1", "true", "yes"):
        return "on"
    if text in ("0", "false", "no"):
        return "off"
    return text


def _target_fps(value: Any) -> str:
    """``"auto"``, or a frame rate in [0, 240] written without trailing zeros (``"30"``)."""
    text = str(value).strip().lower()
    if text in ("auto", "automatic", "display"):
        return "auto"
    try:
        fps = float(text)
    except ValueError:
        raise ValueError(f"{value!r} is not 'auto' or a frame rate such as 30") from None
    if not math.isfinite(fps) or not 0.0 <= fps <= 240.0:
        raise ValueError(f"{value!r} is not 'auto' or a frame rate from 0 to 240")
    return format_number(fps, 2).replace(",", "")


def _iso_date(value: Any) -> str:
    """``YYYY-MM-DD``."""
    text = str(value).strip()
    try:
        return datetime.date.fromisoformat(text).isoformat()
    except ValueError:
        raise ValueError(f"{text!r} is not a date such as 2026-06-21") from None
