"""All user-adjustable settings as one typed tree of dataclasses, addressed by dotted keys.

The panels, the CLI (``--set key=value``), saved presets and the benchmark all go through
:func:`Settings.set` / :func:`Settings.get`, so a key means the same thing everywhere and every
value is validated in one place. Each setting also carries the words a designer reads: its
label, unit, one plain sentence of help and the paper's name for it (:meth:`Settings.explain`
turns them into a tooltip), so the panels never show a key.
"""

from __future__ import annotations

import copy
import dataclasses
import datetime
import json
import math
import os
import textwrap
from dataclasses import dataclass, field
from typing import Any

from app.fileio import atomic_write_json


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


@dataclass
class StereoSettings:
    ipd_mm: float = _opt(
        64.0,
        "How far apart the two eye cameras are; adults' eyes are about 54 to 74 mm apart.",
        label="Distance between the eyes",
        unit="mm",
        lo=0.0,
        hi=100.0,
        decimals=1,
        step=0.5,
    )
    fov_deg: float = _opt(
        95.0,
        "How much of the room each eye sees, from the top of the view to the bottom.",
        label="Field of view",
        unit="°",
        lo=30.0,
        hi=130.0,
        decimals=0,
        step=1.0,
    )
    near_m: float = _opt(
        0.05,
        "Anything closer to the eyes than this is not drawn.",
        label="Nearest drawn distance",
        unit="m",
        lo=1e-4,
        hi=10.0,
        decimals=3,
        step=0.01,
    )
    far_m: float = _opt(
        200.0,
        "Anything farther from the eyes than this is not drawn.",
        label="Farthest drawn distance",
        unit="m",
        lo=1.0,
        hi=1e5,
        decimals=0,
        step=10.0,
    )
    convergence_m: float = _opt(
        2.0,
        "Objects at this distance look the same in both eyes; nearer ones stand out of the "
        "screen, farther ones sink behind it.",
        label="Screen depth",
        unit="m",
        lo=0.1,
        hi=1e4,
        decimals=2,
        step=0.1,
    )


@dataclass
class RenderSettings:
    path: str = _opt(
        "deferred",
        "Deferred lights the picture after drawing every surface and is needed for the "
        "coarse shading modes; forward lights each object as it is drawn.",
        label="Rendering method",
        choices=("deferred", "forward"),
        choice_labels={"deferred": "Deferred (every effect)", "forward": "Forward (simple)"},
    )
    lighting: str = _opt(
        "compute",
        "Where the lighting of the deferred method is computed; the picture is the same, "
        "the speed differs.",
        label="Lighting runs in",
        paper="CPS paper: lighting in a compute shader",
        panel="cps",  # the CPS tab's mitigation modes set it too: its one control is there
        choices=("compute", "fragment"),
        choice_labels={
            "fragment": "Graphics pipeline (fragment shader)",
            "compute": "Compute shader (the CPS paper's)",
        },
    )
    # Light is in cd/m2; the picture shows it through an exposure (app/exposure.py: L_max =
    # 1.2 * 2^EV100 cd/m2 is white before the tone curve), fixed in EV or metered from the
    # frame. ``brightness`` is the one brightness control: exposure compensation in either
    # mode (TCR's light term reads it times the exposure against the default one).
    # ``exposure`` stays for old command lines and presets: a further factor, hidden.
    exposure_mode: str = _opt(
        "manual",
        "Automatic adjusts the picture to the room's light as the eye does, over the eye "
        "adaptation time; fixed shows every room at the same exposure value.",
        label="Exposure",
        choices=("auto", "manual"),
        choice_labels={
            "auto": "Automatic, adapts like the eye",
            "manual": "Fixed exposure value",
        },
    )
    exposure_ev: float = _opt(
        -1.3,
        "With a fixed exposure: the exposure value of a camera at ISO 100; one more shows "
        "the room half as bright. At 0 a surface of 1.2 cd/m² shows as white, at 10 one "
        "of 1,229 cd/m².",
        label="Fixed exposure value",
        unit="EV",
        lo=-10.0,
        hi=20.0,
        decimals=1,
        step=0.5,
    )
    adaptation_s: float = _opt(
        1.0,
        "With automatic exposure: how quickly the picture follows a change of light, such "
        "as walking from a dim hall into a sunlit room (0: at once).",
        label="Eye adaptation time",
        unit="s",
        lo=0.0,
        hi=30.0,
        decimals=1,
        step=0.5,
    )
    tone_mapping: str = _opt(
        "aces",
        "How light brighter than the screen can show is rolled off into white: a film-like "
        "curve keeps a sunlit floor and a lamp's glow from turning into flat white patches.",
        label="Tone curve",
        choices=("aces", "agx", "clamp"),
        choice_labels={
            "aces": "Filmic, rich colours (ACES)",
            "agx": "Filmic, soft and natural (AgX, as in Blender)",
            "clamp": "None: clipped at white (the papers' tables)",
        },
    )
    exposure: float = _opt(
        1.0,
        "Multiplies the picture's light before it is mapped to the screen, on top of the "
        "exposure and the brightness; for old command lines and presets.",
        label="Exposure factor",
        unit="×",
        lo=0.0,
        hi=64.0,
        decimals=2,
        hidden=True,
    )
    brightness: float = _opt(
        1.0,
        "How bright the picture is shown, on top of the exposure: 100% is as exposed, 50% "
        "one exposure step darker; the lamps stay as the model gives them.",
        label="Brightness",
        unit="%",
        paper="TCR paper: scene brightness, read by the light term l",
        lo=0.0,
        hi=16.0,
        decimals=0,
        step=5.0,
        scale=100.0,
    )
    ambient: float = _opt(
        0.06,
        "Light that reaches every surface evenly, so shadows are never fully black. Used "
        "when the even light is not worked out from the lamps, and with bounced light on.",
        label="Ambient light",
        lo=0.0,
        hi=4.0,
        decimals=2,
        step=0.01,
    )
    ambient_estimate: bool = _opt(
        True,
        "Works the even light out from the lamps and the sun: how much of their light the "
        "room's surfaces send back, so a pale lit room gets more of it than a dark one. "
        "Off: the fixed ambient light.",
        label="Even light from the lamps",
        paper="Split-flux estimate of the indirect light (lighting design's enclosure model)",
    )
    ao: str = _opt(
        "off",
        "Darkens the even ambient light in corners, creases and under furniture, where "
        "light from the room reaches less. Worked out from the picture each frame, or once "
        "for the whole model (a few seconds after it opens; rooms built of large flat pieces "
        "then stay even). Off while light bouncing from the lamps is on: it darkens those "
        "places itself.",
        label="Shade corners and creases",
        paper="Ambient occlusion: screen-space (SSAO) or baked per vertex",
        choices=("off", "screen", "baked"),
        choice_labels={
            "off": "Off",
            "screen": "From the picture (every frame)",
            "baked": "Once for the model",
        },
    )
    ao_radius_m: float = _opt(
        0.75,
        "How far away a surface still darkens its neighbour, when worked out from the "
        "picture; the shading worked out once for the model uses 0.75 m.",
        label="Corner shading reach",
        unit="m",
        lo=0.1,
        hi=2.0,
        decimals=2,
        step=0.05,
    )
    ao_strength: float = _opt(
        1.0,
        "How much the corners darken: 0% leaves the ambient light even, 100% darkens "
        "it fully by what is around.",
        label="Corner shading strength",
        unit="%",
        lo=0.0,
        hi=1.0,
        decimals=0,
        step=0.05,
        scale=100.0,
    )
    overlay: bool = _opt(
        True, "Draws the frames per second in a corner of the view.", label="Show frame rate"
    )
    light_culling: bool = _opt(
        True,
        "In scenes with more than 8 lights, each 16 by 16 pixel tile computes only the "
        "lights that reach it: faster, the same picture.",
        label="Skip lights out of reach",
    )
    shadows: str = _opt(
        "soft",
        "Whether lamps and the sun cast shadows, and whether their edges are crisp or soft.",
        label="Shadows",
        choices=("off", "hard", "soft"),
        choice_labels={"off": "Off", "hard": "Hard edges", "soft": "Soft edges"},
    )
    shadow_detail: str = _opt(
        "half",
        "Where the shadows are worked out: at every pixel, or at every second or fourth pixel "
        "across and down and filled in between along the surfaces (faster with many lamps; "
        "an edge may soften a little). The forward path and glass always use every pixel.",
        label="Shadow detail",
        paper="Screen-space shadow mask, depth-aware upsampling",
        choices=("full", "half", "quarter"),
        choice_labels={
            "full": "Every pixel",
            "half": "Every 2nd pixel",
            "quarter": "Every 4th pixel",
        },
    )
    shadow_updates_per_frame: int = _opt(
        2,
        "How many lights may redraw their shadows in one frame after something moved; the "
        "others keep their last shadows a little longer, so the frame rate holds.",
        label="Shadow redraws per frame",
        unit="lights",
        lo=1,
        hi=64,
        step=1.0,
    )
    lod_bias: float = _opt(
        0.0,
        "Draws far-away objects with fewer triangles: how far, in pixels on screen, a "
        "simplified surface may stray from the full one. 0 always draws full detail.",
        label="Simplify distant geometry",
        unit="px",
        paper="Funkhouser and Séquin: level of detail",
        lo=0.0,
        hi=16.0,
        decimals=1,
        step=0.5,
    )
    # The frame-time governor (app/governor.py). "auto" follows the display in the window;
    # headless hosts (bench, render, tests) have no display and treat it as 0 (fixed).
    target_fps: str = _opt(
        "auto",
        "The frame rate to hold while you walk: the picture gets simpler where you would "
        "notice least when a frame takes too long, and returns to full quality when there "
        "is time. Automatic follows the display; 0 keeps every setting as you set it.",
        label="Frame rate to hold",
        unit="fps",
        paper="Funkhouser and Séquin: target frame time",
        check=_target_fps,
        range_text="Automatic, 0 (off), or 1 to 240 frames per second.",
    )
    scale: float = _opt(
        1.0,
        "Draws each eye with fewer pixels and enlarges the picture with an edge-preserving "
        "filter: faster, a little softer. The frame-rate control lowers it when needed.",
        label="Drawing resolution",
        unit="%",
        lo=0.35,
        hi=1.0,
        decimals=0,
        step=5.0,
        scale=100.0,
    )
    upscaler: str = _opt(
        "edge",
        "How a picture drawn at a lower resolution is enlarged: keeping edges crisp, or a "
        "plain blend of the nearest pixels, which is faster and softer.",
        label="Enlarging",
        paper="AMD FSR 1: edge-adaptive spatial upsampling",
        choices=("edge", "bilinear"),
        choice_labels={"edge": "Edge-preserving (FSR 1 style)", "bilinear": "Plain (bilinear)"},
    )
    # RCAS sharpening after EASU (render/upscale.py, rcas.glsl): 0 off, 1 FSR's strongest
    # (0 stops); 0.9 is FSR's default 0.2 stops (stops = 2 x (1 - value)). Off by default:
    # measured (tests/measure_rcas.py, showroom at 0.67 and 0.5), sharpening moves the frame
    # further from the full-resolution one (FLIP 0.0585 -> 0.0638 at 0.67) for 2-3 ms more.
    sharpen: float = _opt(
        0.0,
        "How much a picture drawn at a lower resolution is sharpened after enlarging it with "
        "the edge-preserving filter, without bright or dark fringes at edges; 0 (the default) "
        "turns it off: sharper, but further from the full-resolution picture. Only acts when "
        "the drawing resolution is below 100%.",
        label="Sharpening",
        unit="%",
        paper="AMD FSR 1: RCAS, sharpness 2 x (1 - value) stops",
        lo=0.0,
        hi=1.0,
        decimals=0,
        step=5.0,
        scale=100.0,
    )
    # Progressive refinement (app/refine.py). "auto" is on in the window (a display refresh
    # rate is known) and off in headless hosts, so renders, benches and tests stay the same.
    refine: str = _opt(
        "auto",
        "While you stand still and your gaze rests, the picture keeps improving frame by "
        "frame until it reaches full quality: smooth edges, the finest textures and full "
        "shading, sharpest where you look first. Any movement starts it again. Automatic "
        "refines in the window only: pictures and measurements made without it stay as drawn.",
        label="Refine the picture while still",
        paper="Progressive refinement (accumulated jittered samples, as in Enscape)",
        choices=("auto", "on", "off"),
        choice_labels={"auto": "Automatic", "on": "On", "off": "Off"},
        check=_on_off_auto,
    )
    refine_samples: int = _opt(
        64,
        "How many slightly shifted pictures are averaged where you look before the picture "
        "counts as refined; the rest of the view takes half as long again. More gives "
        "smoother edges and takes longer.",
        label="Refinement steps",
        unit="pictures",
        lo=2,
        hi=1024,
        step=2.0,
    )
    # Off by default: llvmpipe's anisotropic filter turns magnified texels into round blobs.
    anisotropy: float = _opt(
        1.0,
        "Keeps floors and walls seen at a slant sharp; 1 means off.",
        label="Sharpness at grazing angles",
        unit="×",
        lo=1.0,
        hi=16.0,
        decimals=0,
        step=1.0,
    )


@dataclass
class NavigationSettings:
    walk_speed_mps: float = _opt(
        1.4,
        "How fast the W, A, S, D and arrow keys move you.",
        label="Walking speed",
        unit="m/s",
        lo=0.0,
        hi=50.0,
        decimals=1,
        step=0.1,
    )
    turn_deg_per_px: float = _opt(
        0.15,
        "How far the view turns for each pixel the mouse is dragged.",
        label="Look sensitivity",
        unit="° per pixel",
        lo=0.0,
        hi=5.0,
        decimals=2,
        step=0.01,
    )
    eye_height_m: float = _opt(
        1.6,
        "Height of the eyes above the floor while walking.",
        label="Eye height",
        unit="m",
        lo=0.1,
        hi=3.0,
        decimals=2,
        step=0.05,
    )
    radius_m: float = _opt(
        0.25,
        "How close to a wall you can walk: the radius of your body.",
        label="Body radius",
        unit="m",
        lo=0.0,
        hi=2.0,
        decimals=2,
        step=0.05,
    )
    collision: bool = _opt(
        True, "You cannot walk through walls and furniture.", label="Walls stop you"
    )
    fly: bool = _opt(
        False,
        "Move freely up and down instead of walking on the floor; walls stop you only if "
        "that is on too.",
        label="Fly",
    )


@dataclass
class GazeSettings:
    dwell: bool = _opt(
        False,
        "Holding the mouse still also counts as looking steadily at one point, as holding "
        "a mouse button does.",
        label="A still cursor fixes the gaze",
        paper="TCR paper: gaze fixed",
    )
    dwell_deg: float = _opt(
        1.5,
        "How far the cursor may drift and still count as held still.",
        label="Stillness tolerance",
        unit="°",
        lo=0.0,
        hi=30.0,
        decimals=1,
        step=0.5,
    )
    dwell_s: float = _opt(
        0.4,
        "How long the cursor must stay still before the gaze counts as fixed.",
        label="Stillness time",
        unit="s",
        lo=0.0,
        hi=10.0,
        decimals=2,
        step=0.1,
    )


@dataclass
class TcrSettings:
    """Adaptive texture mapping (TCR paper): which terms choose each object's pyramid level."""

    enabled: bool = _opt(
        False,
        "Lowers texture detail where a viewer would not notice; off shows every texture at "
        "full detail.",
        label="Adaptive textures",
        paper="TCR paper: texture level per object",
    )
    preset: str = _opt(
        "ergonomics",
        "Which rules choose each object's texture detail: the paper's psychology or "
        "ergonomics set, or your own choice below.",
        label="Rules",
        paper="TCR paper: psychology and ergonomics phases",
        choices=("psychology", "ergonomics", "custom"),
        choice_labels={
            "psychology": "Psychology: distance, gaze, light",
            "ergonomics": "Ergonomics: distance, motion, light",
            "custom": "Custom: the rules ticked below",
        },
    )
    use_d: bool = _opt(
        True,
        "Farther objects get coarser textures, one level per doubling of distance.",
        label="Distance",
        paper="TCR paper: distance term d",
    )
    use_v: bool = _opt(
        True,
        "While you move, every texture is one level coarser.",
        label="Motion",
        paper="TCR paper: viewpoint-motion term v",
    )
    use_g: bool = _opt(
        False,
        "The object you look at steadily gets one level finer.",
        label="Gaze",
        paper="TCR paper: gaze term g",
    )
    use_l: bool = _opt(
        True,
        "In dim light textures get one level coarser per halving of the brightness.",
        label="Dim light",
        paper="TCR paper: brightness term l",
    )
    mode: str = _opt(
        "clamp",
        "How the chosen detail level is drawn: exactly that level, or smoothly with the "
        "finer levels left out.",
        label="Texture filtering",
        paper="TCR paper: sampling one pyramid level",
        choices=("paper", "clamp"),
        choice_labels={
            "paper": "Exactly the chosen level (paper)",
            "clamp": "Smooth (mipmaps from that level)",
        },
    )
    f_m: float = _opt(
        1.0,
        "Textures keep full detail up to twice this distance and lose one level at each "
        "doubling beyond it (at 2, 4, 8 times it).",
        label="Eye-to-screen distance",
        unit="m",
        paper="TCR paper: eye-to-screen distance f",
        lo=1e-6,
        hi=100.0,
        decimals=2,
        step=0.1,
    )
    move_on: float = _opt(
        0.15,
        "You count as moving once faster than this (turning 30° a second counts as 1 m/s).",
        label="Moving above",
        unit="m/s",
        paper="TCR paper: viewpoint moving",
        lo=0.0,
        hi=100.0,
        decimals=2,
        step=0.05,
    )
    move_off: float = _opt(
        0.05,
        "You count as still again once slower than this; the gap keeps textures from flickering.",
        label="Still below",
        unit="m/s",
        paper="TCR paper: viewpoint still",
        lo=0.0,
        hi=100.0,
        decimals=2,
        step=0.05,
    )
    window_s: float = _opt(
        0.15,
        "A change between moving and still must last this long before textures follow.",
        label="Change delay",
        unit="s",
        lo=0.0,
        hi=5.0,
        decimals=2,
        step=0.05,
    )
    level_bias: int = _opt(
        0,
        "Makes every texture this many levels coarser than the rules choose; the frame-rate "
        "control raises it when a frame takes too long.",
        label="Coarser textures by",
        unit="levels",
        paper="TCR paper: texture level per object",
        lo=0,
        hi=8,
        step=1.0,
        hidden=True,  # the frame-rate control's knob; command line and presets otherwise
    )
    tint: bool = _opt(
        False,
        "Colours every object by its texture level, as in the legend below.",
        label="Tint objects by level",
    )


@dataclass
class CpsSettings:
    """Coarse pixel shading against VR sickness (CPS paper, SPEC C) and the mitigation modes."""

    mode: str = _opt(
        "none",
        "How the edges of the view are calmed against VR sickness: not at all, darkened, "
        "blurred, or lit more coarsely (deferred method only).",
        label="Mitigation",
        paper="CPS paper: the mitigation modes",
        choices=("none", "black-mask", "blur-mask", "cps"),
        choice_labels={
            "none": "None",
            "black-mask": "Black mask (darkened edges)",
            "blur-mask": "Blur mask (blurred edges)",
            "cps": "Coarse pixel shading",
        },
    )
    max_level: int = _opt(
        4,
        "The largest square of pixels that may share one lighting result (level 0 is one "
        "pixel, level 5 is 32 by 32 pixels).",
        label="Coarsest block",
        paper="CPS paper: detail level s",
        lo=0,
        hi=5,
        range_text="From 1×1 to 32×32 pixels.",
    )
    fovea_deg: float = _opt(
        10.0,
        "Within this angle of where you look, every pixel is lit in full.",
        label="Sharp area around the gaze",
        unit="°",
        paper="CPS paper: angle from the gaze point",
        lo=0.0,
        hi=180.0,
        decimals=1,
        step=1.0,
    )
    deg_per_level: float = _opt(
        6.0,
        "Beyond the sharp area, blocks double in size every this many degrees.",
        label="Detail falloff",
        unit="° per level",
        paper="CPS paper: detail falls with the angle from the gaze",
        lo=0.1,
        hi=180.0,
        decimals=1,
        step=1.0,
    )
    near_m: float = _opt(
        1.0,
        "Where an edge of the view is this close to a surface, that side may use the "
        "coarsest blocks.",
        label="Coarsest when nearer than",
        unit="m",
        paper="CPS paper: peripheral detail from edge rays",
        lo=0.0,
        hi=1000.0,
        decimals=2,
        step=0.25,
    )
    far_m: float = _opt(
        6.0,
        "Where an edge of the view looks this far or into open space, that side keeps full detail.",
        label="Full detail when farther than",
        unit="m",
        paper="CPS paper: peripheral detail from edge rays",
        lo=0.0,
        hi=1000.0,
        decimals=2,
        step=0.25,
    )
    rays_per_side: int = _opt(
        5,
        "Rays cast along the left, right and bottom edge of each eye to measure how near "
        "the surroundings are.",
        label="Edge test rays",
        unit="per side",
        paper="CPS paper: edge rays",
        lo=1,
        hi=64,
        step=1.0,
    )
    dispatch: str = _opt(
        "multi",
        "How the compute shader's work is split: one pass per detail level, or one pass "
        "over 32 by 32 pixel tiles; the picture is the same.",
        label="Compute passes",
        paper="CPS paper: multi-level against single dispatch",
        choices=("multi", "single"),
        choice_labels={"multi": "One pass per level", "single": "One pass, 32×32 tiles"},
    )
    filter: str = _opt(
        "hierarchical",
        "How coarse blocks are blended into the picture: flat blocks, ordinary bilinear, "
        "or the paper's hierarchical bilinear.",
        label="Block smoothing",
        paper="CPS paper: hierarchical bilinear filter, section 3.2.2",
        choices=("none", "bilinear", "hierarchical"),
        choice_labels={
            "none": "None (flat blocks)",
            "bilinear": "Bilinear",
            "hierarchical": "Hierarchical bilinear (paper)",
        },
    )
    temporal: bool = _opt(
        False,
        "Each frame one eye gets strong reduction and the other weak, swapping every frame, "
        "blended with the frame before.",
        label="Alternate the eyes",
        paper="CPS paper: alternating temporal filter, section 3.2.1",
    )
    reproject: bool = _opt(
        True,
        "Moves the frame before to the current viewpoint before blending, and drops what "
        "was hidden from it.",
        label="Follow head motion",
    )
    history_weight: float = _opt(
        0.7,
        "When the two frames are blended, how much the finer one counts.",
        label="Weight of the finer frame",
        paper="CPS paper: the finer image weighs more",
        lo=0.5,
        hi=1.0,
        decimals=2,
        step=0.05,
    )
    visualize: bool = _opt(
        False,
        "Tints pixels by their block size, as in the legend below, and marks where the "
        "edge rays hit.",
        label="Show detail levels",
        paper="CPS paper: detail visualisation, Figure 2",
    )


@dataclass
class PhotonSettings:
    """Photon-mapped indirect light (SPEC D): traced on the CPU, gathered on the GPU."""

    enabled: str = _opt(
        "scene",
        "Light bounced off walls and furniture, from a photon map: on, off, or only where "
        "the scene asks for it.",
        label="Indirect light",
        paper="Photon paper: photon mapping",
        choices=("scene", "on", "off"),
        choice_labels={"scene": "As the scene asks", "on": "On", "off": "Off"},
    )
    indirect: str = _opt(
        "cache",
        "How each pixel gets its bounced light: looked up from light worked out once when "
        "the photons are traced (fast enough to walk), or collected from the photons around "
        "it every frame (the paper's method: slow, for its tables and the reference pictures).",
        label="Indirect light method",
        paper="Christensen 1999: precomputed irradiance; photon paper: per-pixel gather",
        choices=("cache", "gather"),
        choice_labels={"cache": "Precomputed (fast)", "gather": "Collected per pixel (paper)"},
    )
    photons: int = _opt(
        65536,
        "How many light paths are traced from the lights; more is smoother and slower "
        "(the paper uses 16,384 to 262,144).",
        label="Photons",
        unit="photons",
        paper="Photon paper: photon count",
        lo=0,
        hi=1 << 22,
        step=4096.0,
    )
    radius_m: float = _opt(
        0.3,
        "How far around each point photons are collected; larger is smoother but blurs the light.",
        label="Gather radius",
        unit="m",
        paper="Photon paper: gather radius r",
        lo=1e-3,
        hi=100.0,
        decimals=3,
        step=0.05,
    )
    gather: str = _opt(
        "radius",
        "How the photons near a point are found; all give nearly the same light at "
        "different speeds.",
        label="Photon search",
        paper="Photon paper: hash grid, tree and nearest-photon gathers",
        choices=("radius", "radius-half", "heap", "kdtree", "kdtree-heap", "shared"),
        choice_labels={
            "radius": "Grid, cell = radius (paper default)",
            "radius-half": "Grid, cell = half the radius",
            "heap": "Nearest photons only",
            "kdtree": "Tree search",
            "kdtree-heap": "Tree search, nearest photons only",
            "shared": "Cooperative, shared memory (Algorithm 1)",
        },
    )
    k: int = _opt(
        32,
        "For the searches that keep only the nearest photons: how many each point keeps.",
        label="Nearest photons kept",
        unit="photons",
        paper="Photon paper: k nearest photons",
        lo=1,
        hi=64,
        step=1.0,
    )
    fused: bool = _opt(
        False,
        "Collects photons inside the lighting step, in one pass, instead of in a pass of "
        "its own before it.",
        label="Collect while lighting",
        paper="Photon paper: single scheme, not hybrid",
    )
    stereo_reuse: bool = _opt(
        True,
        "Collects photons for the left eye first and reuses them where the right eye sees "
        "the same points.",
        label="Reuse the left eye for the right",
        paper="Photon paper: stereo reuse, section 3.3",
    )
    reuse_tolerance: float = _opt(
        0.01,
        "How far apart the two eyes' points may be, relative to their distance, and still "
        "count as the same point.",
        label="Reuse tolerance",
        unit="% of distance",
        lo=0.0,
        hi=1.0,
        decimals=1,
        step=0.5,
        scale=100.0,
    )
    max_bounces: int = _opt(
        8,
        "How many times a photon may bounce before it stops.",
        label="Bounces per photon",
        unit="bounces",
        lo=1,
        hi=64,
        step=1.0,
    )
    seed: int = _opt(
        0,
        "Changes the random pattern of the photons; the same number gives the same picture.",
        label="Random seed",
        lo=0,
        hi=2**31 - 1,
        step=1.0,
    )
    show_reuse: bool = _opt(
        False,
        "Paints right-eye pixels reused from the left eye green and newly collected ones red.",
        label="Show reused pixels",
    )


def _unit_scale(value: str) -> str:
    """``auto`` or a positive factor from the file's units to metres (0.01 = centimetres)."""
    text = str(value).strip().lower()
    if text == "auto":
        return text
    factor = float(text)
    if not math.isfinite(factor) or factor <= 0.0:
        raise ValueError("a unit scale is 'auto' or a positive number such as 0.01")
    return repr(factor)


@dataclass
class SceneSettings:
    """How a model file becomes a room: its units and the limits that keep a load safe."""

    unit_scale: str = _opt(
        "auto",
        "How many metres one unit of the model file is: as the file says (with a warning "
        "if the room looks implausible), or a number such as 0.01 for centimetres.",
        label="Model units",
        check=_unit_scale,
        choice_labels={
            "auto": "As the file says",
            "1.0": "Metres (1)",
            "0.01": "Centimetres (0.01)",
            "0.001": "Millimetres (0.001)",
            "0.0254": "Inches (0.0254)",
            "0.3048": "Feet (0.3048)",
        },
    )
    max_texture_px: int = _opt(
        8192,
        "Textures bigger than this on their longest side are scaled down when loading.",
        label="Largest texture",
        unit="pixels",
        lo=16,
        hi=65536,
        step=1024.0,
    )
    max_memory_mb: int = _opt(
        8192,
        "A model whose geometry and textures would need more memory than this is refused.",
        label="Memory limit per model",
        unit="MB",
        lo=64,
        hi=1 << 20,
        step=1024.0,
    )


@dataclass
class SkySettings:
    """Daylight: the sun's place from the date, time and site, and the sky seen and lit by."""

    enabled: bool = _opt(
        False,
        "Lights the room with the sun and the sky through its windows.",
        label="Daylight",
    )
    time: str = _opt(
        "10:00",
        "The local solar time of day (hours:minutes) that places the sun.",
        label="Time of day",
        check=_clock_time,
    )
    date: str = _opt(
        "2026-06-21",
        "The date (year-month-day) that places the sun.",
        label="Date",
        check=_iso_date,
    )
    latitude: float = _opt(
        48.85,
        "Where the room stands, north of the equator (negative: south).",
        label="Latitude",
        unit="°",
        lo=-90.0,
        hi=90.0,
        decimals=2,
        step=1.0,
    )
    longitude: float = _opt(
        2.35,
        "Where the room stands, east of Greenwich (negative: west).",
        label="Longitude",
        unit="°",
        lo=-180.0,
        hi=180.0,
        decimals=2,
        step=1.0,
    )
    north_deg: float = _opt(
        0.0,
        "Which way north lies in the model: the angle from the model's own north (the -Z "
        "axis for a model file, which does not say), counter-clockwise seen from above.",
        label="North",
        unit="°",
        lo=-360.0,
        hi=360.0,
        decimals=0,
        step=5.0,
    )
    image: str = _opt(
        "",
        "A panorama photo (equirectangular HDR or JPG) to use as the sky instead of the "
        "computed one; empty: the computed sky.",
        label="Sky photo",
    )


@dataclass
class Settings:
    stereo: StereoSettings = field(default_factory=StereoSettings)
    render: RenderSettings = field(default_factory=RenderSettings)
    navigation: NavigationSettings = field(default_factory=NavigationSettings)
    gaze: GazeSettings = field(default_factory=GazeSettings)
    tcr: TcrSettings = field(default_factory=TcrSettings)
    cps: CpsSettings = field(default_factory=CpsSettings)
    photons: PhotonSettings = field(default_factory=PhotonSettings)
    scene: SceneSettings = field(default_factory=SceneSettings)
    sky: SkySettings = field(default_factory=SkySettings)

    # -- dotted-key access -------------------------------------------------------------------
    def _locate(self, key: str) -> tuple[Any, dataclasses.Field[Any]]:
        parts = key.split(".")
        node: Any = self
        for i, name in enumerate(parts):
            fields = {f.name: f for f in dataclasses.fields(node)}
            if name not in fields:
                raise SettingsError(f"unknown setting '{key}' (known: {', '.join(self.keys())})")
            f = fields[name]
            if i == len(parts) - 1:
                if dataclasses.is_dataclass(getattr(node, name)):
                    raise SettingsError(f"'{key}' is a section, not a setting")
                return node, f
            node = getattr(node, name)
        raise SettingsError(f"unknown setting '{key}'")

    def get(self, key: str) -> Any:
        node, f = self._locate(key)
        return getattr(node, f.name)

    def set(self, key: str, value: Any) -> None:
        node, f = self._locate(key)
        setattr(node, f.name, _coerce(key, f, getattr(node, f.name), value))

    def apply(self, assignments: list[str] | None) -> None:
        """Apply ``key=value`` strings as given on the command line."""
        for text in assignments or []:
            key, sep, value = text.partition("=")
            if not sep:
                raise SettingsError(f"expected key=value, got '{text}'")
            self.set(key.strip(), value.strip())

    def keys(self) -> list[str]:
        return list(_walk(self, ""))

    def describe(self, key: str) -> dict[str, Any]:
        _node, f = self._locate(key)
        return dict(f.metadata)

    def label(self, key: str) -> str:
        """The control's name a panel shows: the metadata's ``label``.

        A setting without one (a new setting, say) falls back to its key's last part in
        words, which tests/test_plain_language.py reports.
        """
        meta = self.describe(key)
        if meta.get("label"):
            return str(meta["label"])
        return key.rsplit(".", 1)[-1].replace("_", " ").capitalize()

    def explain(self, key: str) -> str:
        """The tooltip: the plain sentence, the paper's term and the range, wrapped."""
        meta = self.describe(key)
        paper = str(meta.get("paper", ""))
        return wrap_tooltip(
            [
                str(meta["help"]),
                f"{paper}." if paper else "",
                range_text(meta, self.get(key)),
            ]
        )

    def shown_keys(self, section: str | None = None) -> list[str]:
        """The keys the panels show (all but the hidden ones), of one panel's section or all.

        A key belongs to its own section's panel unless its metadata names another ``panel``.
        """
        out = []
        for k in self.keys():
            meta = self.describe(k)
            home = str(meta.get("panel") or k.split(".", 1)[0])
            if not meta.get("hidden") and (section is None or home == section):
                out.append(k)
        return out

    def to_dict(self) -> dict[str, Any]:
        return dataclasses.asdict(self)

    def copy(self) -> Settings:
        return copy.deepcopy(self)

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> Settings:
        """Build settings from a (possibly partial) nested dict; unknown keys are an error."""
        s = cls()
        for key, value in _flatten(data, ""):
            s.set(key, value)
        return s

    # -- presets on disk ---------------------------------------------------------------------
    def save(self, path: str | os.PathLike[str]) -> None:
        atomic_write_json(path, {"vrpreview_settings": 1, "settings": self.to_dict()})

    @classmethod
    def load(cls, path: str | os.PathLike[str]) -> Settings:
        try:
            with open(path, encoding="utf-8") as fh:
                doc = json.load(fh)
        except (OSError, json.JSONDecodeError) as exc:
            raise SettingsError(f"cannot read settings preset {path}: {exc}") from exc
        if not isinstance(doc, dict) or not isinstance(doc.get("settings"), dict):
            raise SettingsError(f"{path} is not a vrpreview settings preset")
        return cls.from_dict(doc["settings"])


def _walk(node: Any, prefix: str):
    for f in dataclasses.fields(node):
        value = getattr(node, f.name)
        if dataclasses.is_dataclass(value):
            yield from _walk(value, f"{prefix}{f.name}.")
        else:
            yield f"{prefix}{f.name}"


def _flatten(data: dict[str, Any], prefix: str):
    for k, v in data.items():
        if isinstance(v, dict):
            yield from _flatten(v, f"{prefix}{k}.")
        else:
            yield f"{prefix}{k}", v


def _coerce(key: str, f: dataclasses.Field[Any], current: Any, value: Any) -> Any:
    meta = f.metadata
    kind = type(current)
    try:
        if kind is bool:
            if isinstance(value, str):
                low = value.lower()
                if low not in ("1", "0", "true", "false", "on", "off", "yes", "no"):
                    raise ValueError(value)
                out: Any = low in ("1", "true", "on", "yes")
            else:
                out = bool(value)
        elif kind is int:
            out = int(value)
        elif kind is float:
            out = float(value)
            if not math.isfinite(out):
                raise ValueError("not a finite number")
        else:
            out = str(value)
        if meta.get("check") is not None:
            out = meta["check"](out)
    except (TypeError, ValueError) as exc:
        reason = f"cannot use {value!r} ({exc})"
        raise SettingsError(f"{key}: {reason}", key, reason) from exc
    if meta.get("choices") and out not in meta["choices"]:
        reason = f"{out!r} is not one of {', '.join(meta['choices'])}"
        raise SettingsError(f"{key}: {reason}", key, reason)
    lo, hi = meta.get("lo"), meta.get("hi")
    if lo is not None and out < lo or hi is not None and out > hi:
        reason = f"{out} is outside [{lo}, {hi}]"
        raise SettingsError(f"{key}: {reason}", key, reason)
    return out
