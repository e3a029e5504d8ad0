"""Exposure in photographic units, the eye's adaptation and the tone curves, without GL.

The renderer's linear values are luminance in cd/m2 (see ``app.scene``). Exposure follows the
photographic convention (Lagarde and de Rousiers, "Moving Frostbite to PBR", 2014, section
5.1): at an exposure value EV100 (ISO 100) the luminance

    L_max = 1.2 * 2^EV100  cd/m2

maps to white before the tone curve, so the picture is ``L / L_max`` and one EV more halves
it. Manual exposure sets EV100 (``render.exposure_ev``); automatic exposure meters the frame:
the geometric mean L_avg of the luminance of the model's surfaces (the void around it, where
nothing is drawn, is not metered) with the darkest and brightest few per cent left out is
placed at 18% grey,

    EV100 = log2(L_avg / (1.2 * 0.18)),

(a reflected-light meter with calibration K = 100 * 1.2 * 0.18 = 21.6) clamped to
[EV_MIN, EV_MAX], and the eye adapts to it over ``render.adaptation_s`` (a time constant:
two-thirds of a change in that time, 95% in three times that).

``render.brightness`` is the one brightness control a designer sees: it multiplies what the
screen shows in either mode (exposure compensation; 50% is one EV darker). The lamps stay
as the model gives them. TCR's light term l reads the displayed brightness (see
:func:`displayed_brightness`): how bright the picture shows the room against 18% grey, so
it reads the Brightness alone once automatic exposure has adapted (a dark room brightened
by the exposure does not coarsen the textures, a sunlit one neither), and reads less while
the eye adapts or where a fixed exposure shows the room dark.

The default EV (:data:`EV_DEFAULT`, -1.3) shows the built-in scenes as before exposure had
units: Stephen Hill's ACES fit at EV -1.3 is within 1 of 255 levels of Narkowicz's fit at the
old exposure 1 (Narkowicz fitted ACES to an input pre-scaled by 0.6, Hill fits it unscaled).
The numpy curves below are the GLSL ones of ``render/shaders/exposure_tonemap.glsl`` (the
tests compare them); the renderer uses the GLSL.
"""

from __future__ import annotations

import math

import numpy as np

EV_DEFAULT = -1.3  # the built-in scenes look as they did at the old exposure 1 (see above)
EV_MIN, EV_MAX = -10.0, 20.0  # automatic exposure stays inside (starlight .. sunlit snow)
METER_GREY = 0.18  # automatic exposure puts the frame's average here before the tone curve
TRIM_DARK, TRIM_BRIGHT = 0.05, 0.05  # the fractions of the meter's samples left out
ADAPTED_EV = 1e-3  # the eye counts as adapted this close to the metering (TCR's l is exact)
NO_SURFACE = -1000.0  # a meter cell where nothing is drawn (the shader writes it)
UNSEEN_EV = 0.1  # TCR's l takes the room as shown at the exposure when this close (7%)
LOG2_FLOOR = -24.0  # log2 of the luminance the meter takes for black (the shader's floor)


def white_luminance(ev100: float) -> float:
    """L_max = 1.2 * 2^EV100: the luminance (cd/m2) shown as white before the tone curve."""
    return 1.2 * 2.0 ** float(ev100)


def exposure_scale(ev100: float) -> float:
    """The factor on the linear picture at EV100 (1 / L_max)."""
    return 1.0 / white_luminance(ev100)


def compensation_ev(brightness: float) -> float:
    """``render.brightness`` as exposure compensation in EV (100% is 0, 50% is -1)."""
    b = float(brightness)
    if not math.isfinite(b) or b <= 0.0:
        return -math.inf
    return math.log2(b)


def metered_ev(log2_luminance: np.ndarray) -> float | None:
    """EV100 that puts the trimmed geometric mean of the samples at :data:`METER_GREY`.

    ``log2_luminance`` are the meter's samples (log2 cd/m2); the darkest :data:`TRIM_DARK`
    and brightest :data:`TRIM_BRIGHT` of them are left out (a lamp's hot spot, a black
    corner). Non-finite samples and cells with no surface (:data:`NO_SURFACE`: the void
    around a model) are dropped; none left: None (nothing to meter). The result is clamped
    to [EV_MIN, EV_MAX].
    """
    x = np.asarray(log2_luminance, np.float64).ravel()
    x = np.sort(x[np.isfinite(x) & (x > NO_SURFACE)])
    if x.size == 0:
        return None
    lo = int(math.floor(x.size * TRIM_DARK))
    hi = max(lo + 1, x.size - int(math.floor(x.size * TRIM_BRIGHT)))
    mean_log2 = float(np.mean(x[lo:hi]))
    ev = mean_log2 - math.log2(1.2 * METER_GREY)
    return min(max(ev, EV_MIN), EV_MAX)


def unfit_opening_exposure(
    mode: str, ev100: float, daylight: bool, lamps_from_file: bool
) -> str | None:
    """Why the fixed exposure a room opens with (``mode`` manual at :data:`EV_DEFAULT`, made
    for the built-in scenes' lamps and the default lights) does not fit the light: "daylight"
    (a sunlit room is some eight stops brighter: a white screen) or "lamps" (a model file's
    own lamps, as bright as the file says: a 60 W bulb's 64 cd shows a bathroom five stops
    over). None where it fits, or where the user chose another exposure."""
    if mode != "manual" or ev100 != EV_DEFAULT:
        return None
    if daylight:
        return "daylight"
    if lamps_from_file:
        return "lamps"
    return None


class EyeAdaptation:
    """The automatic exposure's state: the EV the eye has adapted to, stepped once a frame.

    The first metering after a reset is taken at once (a camera meters before its first
    picture); later ones are approached exponentially with the time constant
    ``adaptation_s`` (0: at once). Deterministic: the host passes the frame's time step.
    """

    def __init__(self) -> None:
        self.ev: float | None = None  # None: not metered yet
        self.target: float | None = None

    def reset(self) -> None:
        self.ev = self.target = None

    def update(self, metered: float | None, dt: float, adaptation_s: float) -> float | None:
        """Step towards ``metered`` (None: no new metering, keep the state) by ``dt`` s."""
        if metered is None or not math.isfinite(metered):
            return self.ev
        self.target = min(max(float(metered), EV_MIN), EV_MAX)
        step = float(dt) if math.isfinite(dt) and dt > 0.0 else 0.0
        tau = float(adaptation_s) if math.isfinite(adaptation_s) else 0.0
        if self.ev is None or tau <= 0.0:
            self.ev = self.target
        else:
            self.ev = self.target + (self.ev - self.target) * math.exp(-step / tau)
            if abs(self.ev - self.target) < ADAPTED_EV:  # adapted: exactly, not asymptotically
                self.ev = self.target
        return self.ev


def effective_ev(base_ev: float, brightness: float) -> float:
    """The EV the picture is shown at: the metered or fixed EV less the compensation."""
    return float(base_ev) - compensation_ev(brightness)


def displayed_brightness(
    brightness: float, shown_ev: float, scene_ev: float | None = None
) -> float:
    """What TCR's light term l reads: how bright the picture shows the room, 1 when its
    average is at 18% grey, ``brightness * 2^(scene_ev - shown_ev)``.

    ``scene_ev`` is the EV the meter found for the room in the last frame, ``shown_ev`` the
    one the picture is shown at: the same once automatic exposure has adapted, so l then
    reads the Brightness alone; while the eye adapts to a darker room, or where a fixed
    exposure shows the room dark, it reads less. Without a metering (None) the room is
    taken as the built-in scenes are at the default EV. Differences under
    :data:`UNSEEN_EV` count as none (a frame's textures change the metering a little). A NaN
    or infinite EV gives NaN (l's fallback: keep quality).
    """
    b = float(brightness)
    seen = EV_DEFAULT if scene_ev is None else float(scene_ev)
    ev = float(shown_ev)
    if not (math.isfinite(ev) and math.isfinite(seen)) or math.isnan(b):
        return math.nan
    if abs(seen - ev) < UNSEEN_EV:  # the meter's noise: the level must not flicker with it
        seen = ev
    if b <= 0.0:
        return 0.0
    if math.isinf(b):
        return b
    return b * 2.0 ** max(-1000.0, min(1000.0, seen - ev))


def readout(ev: float, mode: str) -> str:
    """``"Exposure EV 7.2 (auto)"`` for the evaluation bar."""
    if not math.isfinite(ev):
        return "Exposure: black"
    return f"Exposure EV {ev:.1f} ({'auto' if mode == 'auto' else 'fixed'})"


# ---------------------------------------------------------------------------------------------
# Tone curves (the GLSL's twins, for tests and tools)
# ---------------------------------------------------------------------------------------------

# Stephen Hill's ACES fit (github.com/TheRealMJP/BakingLab, ACES.hlsl, 2016): sRGB -> AP1 with
# the RRT's saturation, the fitted RRT + ODT (sRGB, 100 nits), AP1 -> sRGB with the ODT's
# desaturation. Rows act on the column vector (mul(M, c)).
ACES_INPUT = np.array(
    [[0.59719, 0.35458, 0.04823], [0.07600, 0.90834, 0.01566], [0.02840, 0.13383, 0.83777]]
)
ACES_OUTPUT = np.array(
    [[1.60475, -0.53108, -0.07367], [-0.10208, 1.10813, -0.00605], [-0.00327, -0.07276, 1.07602]]
)

# AgX base contrast (Troy Sobotka's AgX, as in Blender 4), in Benjamin Wrensch's published
# fit (iolite engine, "Minimal AgX implementation", 2024: iolite-engine.com/blog_posts/
# minimal_agx_implementation): inset matrix, log2 encoding over [AGX_MIN_EV, AGX_MAX_EV]
# around 18% grey, a 6th-order polynomial of Blender's base contrast curve, then the outset
# matrix and the 2.2 power back to linear. Rows act on the column vector.
AGX_INSET = np.array(
    [
        [0.842479062253094, 0.0784335999999992, 0.0792237451477643],
        [0.0423282422610123, 0.878468636469772, 0.0791661274605434],
        [0.0423756549057051, 0.0784336, 0.879142973793104],
    ]
)
AGX_OUTSET = np.array(
    [
        [1.19687900512017, -0.0980208811401368, -0.0990297440797205],
        [-0.0528968517574562, 1.15190312990417, -0.0989611768448433],
        [-0.0529716355144438, -0.0980434501171241, 1.15107367264116],
    ]
)
AGX_MIN_EV, AGX_MAX_EV = -12.47393, 4.026069

TONE_CURVES = ("aces", "agx", "clamp")


def _agx_contrast(x: np.ndarray) -> np.ndarray:
    x2 = x * x
    x4 = x2 * x2
    return (
        15.5 * x4 * x2
        - 40.14 * x4 * x
        + 31.96 * x4
        - 6.868 * x2 * x
        + 0.4298 * x2
        + 0.1191 * x
        - 0.00232
    )


def tone_map(rgb: np.ndarray, curve: str) -> np.ndarray:
    """Exposed linear sRGB (..., 3) to display-linear [0, 1] with the named curve."""
    c = np.maximum(np.asarray(rgb, np.float64), 0.0)
    if curve == "clamp":
        return np.clip(c, 0.0, 1.0)
    if curve == "aces":
        v = c @ ACES_INPUT.T
        a = v * (v + 0.0245786) - 0.000090537
        b = v * (0.983729 * v + 0.4329510) + 0.238081
        return np.clip((a / b) @ ACES_OUTPUT.T, 0.0, 1.0)
    if curve == "agx":
        v = c @ AGX_INSET.T
        v = np.clip(np.log2(np.maximum(v, 1e-10)), AGX_MIN_EV, AGX_MAX_EV)
        v = _agx_contrast((v - AGX_MIN_EV) / (AGX_MAX_EV - AGX_MIN_EV))
        v = np.maximum(v @ AGX_OUTSET.T, 0.0)
        return np.clip(v**2.2, 0.0, 1.0)
    raise ValueError(f"unknown tone curve {curve!r} (one of {', '.join(TONE_CURVES)})")
