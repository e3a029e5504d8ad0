"""All user-adjustable settings as one typed tree of dataclasses, addressed by dotted keys.

The panels, the CLI (``--set key=value``), saved presets and the benchmark all go through
:func:`Settings.set` / :func:`Settings.get`, so a key means the same thing everywhere and every
value is validated in one place. Each setting also carries the words a designer reads: its
label, unit, one plain sentence of help and the paper's name for it (:meth:`Settings.explain`
turns them into a tooltip), so the panels never show a key. How a setting is declared and
shown is in ``app.settings_fields``; the techniques' sections in ``app.settings_techniques``.
"""

from __future__ import annotations

import copy
import dataclasses
import functools
import json
import math
import os
from dataclasses import dataclass, field
from typing import Any

from app.fileio import atomic_write_json
from app.settings_fields import SECTION_TITLES as SECTION_TITLES
from app.settings_fields import SettingsError as SettingsError
from app.settings_fields import (
    _clock_time,
    _iso_date,
    _on_off_auto,
    _opt,
    _target_fps,
    range_text,
    wrap_tooltip,
)
from app.settings_techniques import CpsSettings as CpsSettings
from app.settings_techniques import PhotonSettings as PhotonSettings
from app.settings_techniques import TcrSettings as TcrSettings


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
        "fragment",
        "Where the lighting of the deferred method is computed; the picture is the same, "
        "the speed differs (on a computer without a graphics card the graphics pipeline is "
        "about a tenth faster).",
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
        "when the even light is not worked out from the lamps, and in daylight with bounced "
        "light on (lamp-lit, the even light beside bounced light is worked out).",
        label="Ambient light",
        lo=0.0,
        hi=4.0,
        decimals=2,
        step=0.01,
    )
    ambient_estimate: bool = _opt(
        True,
        "Works the even light out from the lamps, the sun and glowing surfaces (a lamp's "
        "shade, a lit panel): how much of their light the room's surfaces send back, so a "
        "pale lit room gets more of it than a dark one, in the colour of the lamps and of "
        "what it bounced off; it also carries a lamp's light past the distance the lamp is "
        "drawn to, and a glowing surface's light, which the picture draws only as a glow. "
        "Off: the fixed ambient light.",
        label="Even light from the lamps",
        paper="Split-flux estimate of the indirect light (lighting design's enclosure model)",
    )
    ambient_by_place: bool = _opt(
        True,
        "Lets the even light vary across the room as the light bounced off its surfaces "
        "does: brighter beside a sunlit window or a lamp-lit wall, dimmer in a far corner. "
        "Off: one level for the whole room, by the way a surface faces. Needs the even "
        "light from the lamps.",
        label="Even light varies by place",
        paper="Irradiance volume from the estimate's radiosity points",
    )
    normal_maps: bool = _opt(
        True,
        "Shows the fine relief a material gives its surface, such as the joints between "
        "tiles or the grain of boards, in how the light falls on it. Off: every surface is "
        "lit as if it were perfectly flat.",
        label="Surface relief (normal maps)",
        paper="Normal mapping (glTF normal texture)",
    )
    ao: str = _opt(
        "off",
        "Darkens the even ambient light in corners, creases and under furniture, where "
        "light from the room reaches less. Worked out from the picture each frame, or once "
        "for the whole model (a few seconds after it opens, every half metre of a surface "
        "at least). Off while light bouncing from the lamps is on: it darkens those places "
        "itself.",
        label="Shade corners and creases",
        paper="Ambient occlusion: screen-space (SSAO) or baked per vertex",
        choices=("off", "screen", "baked"),
        choice_labels={
            "off": "Off",
            "screen": "From the picture (every frame)",
            "baked": "Once for the model",
        },
    )
    # 0.3 m at 50 %: against Cycles (docs/reference_flip.md, stop 32) closer on five of the six
    # views, where 0.75 m at 100 % was further on four: the even light by place already
    # darkens a room's far corners, the occlusion only needs the contact shadows it cannot see.
    ao_radius_m: float = _opt(
        0.3,
        "How far away a surface still darkens its neighbour, when worked out from the "
        "picture; the shading worked out once for the model uses 0.3 m.",
        label="Corner shading reach",
        unit="m",
        lo=0.1,
        hi=2.0,
        decimals=2,
        step=0.05,
    )
    ao_strength: float = _opt(
        0.5,
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
    reflections: str = _opt(
        "screen",
        "Glossy surfaces, such as a varnished floor or a lacquered piano, mirror what lies "
        "in their reflected direction: the window, the lamps, the sunlit patch. Taken from "
        "the picture on screen: what is out of view is reflected as the room's even light. "
        "Drawn with the deferred rendering method.",
        label="Reflections on glossy surfaces",
        paper="Screen-space reflections (ray march through the depth buffer)",
        choices=("off", "screen"),
        choice_labels={"off": "Off", "screen": "From the picture"},
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
        "auto",
        "Where the shadows are worked out: at every pixel, or at every second or fourth pixel "
        "across and down and filled in between along the surfaces (faster with many lamps; "
        "an edge may soften a little). Automatic: every second pixel, every fourth from four "
        "shadowed lamps on (each lamp's shadow is then a small part of the light, and the "
        "cost grows with the lamps). The forward path and glass always use every pixel.",
        label="Shadow detail",
        paper="Screen-space shadow mask, depth-aware upsampling",
        choices=("auto", "full", "half", "quarter"),
        choice_labels={
            "auto": "Automatic (by the number of lamps)",
            "full": "Every pixel",
            "half": "Every 2nd pixel",
            "quarter": "Every 4th pixel",
        },
    )
    shadow_updates_per_frame: int = _opt(
        2,
        "How many lights may redraw their shadows at a time after something moved or came "
        "into view (a lamp's shadow over three frames, six at one light); the others keep "
        "their last shadows a little longer, so the frame rate holds.",
        label="Shadow redraws per frame",
        unit="lights",
        lo=1,
        hi=64,
        step=1.0,
    )
    lod_bias: float = _opt(
        0.0,
        "Draws far-away objects with fewer triangles: how far, in pixels on screen, a "
        "simplified surface may stray from the full one; a small object that would cover "
        "less than that is left out (glowing ones stay). 0 always draws full detail.",
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
            fields = _fields_of(type(node))  # type: ignore[arg-type]
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


@functools.cache
def _fields_of(cls: type) -> dict[str, dataclasses.Field[Any]]:
    return {f.name: f for f in dataclasses.fields(cls)}  # (a settings read: 7 -> 1 us)


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
