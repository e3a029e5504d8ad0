"""TCR adaptive texture mapping (Maruyama & Fujishiro 1996): pyramid levels chosen per object.

The paper keeps each texture as a pyramid I_0 .. I_n (each level the 2x2 average of the one
before) and picks, every frame and per object, the level

    j = floor(log2((d + f) / f))      distance term (f = eye-to-screen distance)
        + 1  while the viewpoint moves                      (term v)
        - 1  on the gazed object while the gaze is fixed    (term g)
        + 1  per halving of the scene brightness            (term l)

clamped to [0, n]. Which terms are on is a user choice (a toggle per term, or the paper's two
presets); the 4-state motion model of the paper (viewpoint still/moving x gaze moving/fixed) is
what switches the v and g terms on and off at run time. The brightness l reads is the one
displayed (:func:`app.exposure.displayed_brightness`: how bright the picture shows the room,
exposure and Brightness included, against 18% grey).

Everything here is plain numpy / Python with no GL or Qt, so the renderer, the UI and the
benchmark share one definition of "the level" and the tests can sweep it exhaustively. The level
must stay defined for *any* input (a broken mesh, a NaN eye position, a zero-brightness scene),
so every function below documents the fallback it chooses for 0, negative, infinite and NaN
inputs instead of raising; the integer maths uses :func:`math.frexp` so that even 1e308 / 5e-324
neither overflows nor warns, and so that exact powers of two land on the right side of a step.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from app.color import SRGB8_TO_LINEAR, linear_to_srgb
from app.settings import TcrSettings

# ---------------------------------------------------------------------------------------------
# Which terms are on
# ---------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class TcrTerms:
    """Which of the paper's four level terms (d, v, g, l) take part."""

    d: bool = True
    v: bool = True
    g: bool = True
    l: bool = True


#: The paper's two recommended phases (section 4.2): psychological evaluation keeps the user
#: still and looks closely (gaze helps, motion is irrelevant); ergonomic evaluation walks around
#: (motion coarsens, gaze is ignored).
PRESETS: dict[str, TcrTerms] = {
    "psychology": TcrTerms(d=True, v=False, g=True, l=True),
    "ergonomics": TcrTerms(d=True, v=True, g=False, l=True),
}


def terms_from_settings(s: TcrSettings) -> TcrTerms:
    """The preset's terms, or the ``use_*`` flags for ``preset == "custom"``.

    An unknown preset name (settings set around :meth:`Settings.set`'s validation) is treated as
    "custom" rather than raising: the per-term flags are always there and always meaningful.
    """
    preset = PRESETS.get(s.preset)
    if preset is not None:
        return preset
    return TcrTerms(d=bool(s.use_d), v=bool(s.use_v), g=bool(s.use_g), l=bool(s.use_l))


def phase_name(terms: TcrTerms) -> str:
    """What the evaluation bar shows: the preset whose terms these are, else ``"custom"``.

    Custom flags that happen to equal a preset name that preset, because the bar reports what
    the renderer does, not which button was pressed.
    """
    for name, preset in PRESETS.items():
        if preset == terms:
            return name
    return "custom"


# ---------------------------------------------------------------------------------------------
# Texture pyramid
# ---------------------------------------------------------------------------------------------


def pyramid_sizes(width: int, height: int) -> list[tuple[int, int]]:
    """The (width, height) of every level, as OpenGL's mipmap chain defines them.

    Level 0 is the texture itself; each next level is ``(max(1, w // 2), max(1, h // 2))``
    down to 1x1, so ``n = len(sizes) - 1 = floor(log2(max(w, h)))``. Matching GL exactly lets the
    renderer upload these levels as the texture's mipmaps (``mode == "clamp"``) or sample one of
    them with ``textureLod`` (``mode == "paper"``) with the same level numbers.
    """
    w, h = int(width), int(height)
    if w < 1 or h < 1:
        raise ValueError(f"texture size must be at least 1x1, got {width}x{height}")
    sizes = [(w, h)]
    while w > 1 or h > 1:
        w, h = max(1, w // 2), max(1, h // 2)
        sizes.append((w, h))
    return sizes


def level_bytes(width: int, height: int, bytes_per_texel: int = 4) -> list[int]:
    """Memory of each pyramid level; for 2^n squares the sum is about 4/3 of level 0 (paper 3.1)."""
    return [w * h * int(bytes_per_texel) for w, h in pyramid_sizes(width, height)]


# Averaging sRGB bytes directly darkens every edge; averaging light keeps each level's brightness.
_SRGB_TO_LINEAR = SRGB8_TO_LINEAR.astype(np.float32)


def _decode(rgba: np.ndarray) -> np.ndarray:
    """uint8 sRGB RGBA -> float32 linear RGB + linear alpha in [0, 1]."""
    out = np.empty(rgba.shape, np.float32)
    out[..., :3] = _SRGB_TO_LINEAR[rgba[..., :3]]
    out[..., 3] = rgba[..., 3] * np.float32(1.0 / 255.0)
    return out


def _encode(linear: np.ndarray) -> np.ndarray:
    """float linear RGB + alpha -> uint8 sRGB RGBA (round to nearest)."""
    x = np.clip(linear, 0.0, 1.0)
    rgb = x[..., :3]
    srgb = linear_to_srgb(rgb.astype(np.float32, copy=False))
    out = np.empty(linear.shape, np.uint8)
    out[..., :3] = np.rint(np.clip(srgb, 0.0, 1.0) * 255.0)
    out[..., 3] = np.rint(x[..., 3] * 255.0)
    return out


def _box_taps(n_in: int, n_out: int) -> tuple[np.ndarray, np.ndarray]:
    """Input indices and weights of a box filter from ``n_in`` texels to ``n_out``.

    Output texel i covers the input interval [i * s, (i + 1) * s) with s = n_in / n_out; each
    input texel it overlaps contributes overlap / s. Working in units of 1 / n_out keeps every
    overlap an exact integer. Returns (n_out, K) arrays; unused taps have weight 0.
    """
    i = np.arange(n_out, dtype=np.int64)
    start = i * n_in  # in units of 1 / n_out
    end = start + n_in
    first = start // n_out
    last = (end - 1) // n_out
    k = int((last - first).max()) + 1
    idx = first[:, None] + np.arange(k, dtype=np.int64)[None, :]
    lo = np.maximum(start[:, None], idx * n_out)
    hi = np.minimum(end[:, None], (idx + 1) * n_out)
    weights = np.clip(hi - lo, 0, None).astype(np.float32) / np.float32(n_in)
    return np.minimum(idx, n_in - 1), weights


def _downsample(level: np.ndarray, w_out: int, h_out: int) -> np.ndarray:
    """One pyramid step of a float (H, W, C) image: separable box filter, rows then columns."""
    h_in, w_in = level.shape[:2]
    if h_out != h_in:
        idx, wt = _box_taps(h_in, h_out)
        rows = level[idx[:, 0]] * wt[:, 0, None, None]
        for k in range(1, idx.shape[1]):
            rows += level[idx[:, k]] * wt[:, k, None, None]
        level = rows
    if w_out != w_in:
        idx, wt = _box_taps(w_in, w_out)
        cols = level[:, idx[:, 0]] * wt[None, :, 0, None]
        for k in range(1, idx.shape[1]):
            cols += level[:, idx[:, k]] * wt[None, :, k, None]
        level = cols
    return level


def build_pyramid(rgba: np.ndarray) -> list[np.ndarray]:
    """Every level I_0 .. I_n of an sRGB RGBA8 texture (row 0 at the top), as uint8 arrays.

    * Each level is the 2x2 average of the one before (the paper's pyramid), computed in *linear
      light*: colour is decoded from sRGB, averaged and re-encoded, so a black/white checker
      becomes linear 0.5 (sRGB 188) rather than the too-dark byte average 128. Alpha is
      averaged as stored (it is already linear); colour is not premultiplied, as GL's own
      ``generate_mipmaps`` does not premultiply either.
    * Sizes follow GL's chain (:func:`pyramid_sizes`). For sides that are not powers of two the
      step is a box filter with fractional weights: along an odd side of length 2k + 1 each of
      the k outputs covers (2k + 1) / k input texels, weighting the partly covered ones by the
      covered fraction. Every input texel then contributes equally in total, so each level's
      mean equals level 0's (up to 8-bit rounding) -- the property that keeps a distant wall's
      average colour steady when its level changes. A side already at 1 is left alone, so
      1xN, Nx1 and 1x1 textures work; even sides reduce to the exact 2x2 average.
    * Levels are computed from the previous level's float values, not its rounded bytes, so
      rounding does not accumulate down the chain.
    """
    arr = np.asarray(rgba)
    if arr.ndim != 3 or arr.shape[2] != 4 or arr.dtype != np.uint8:
        raise ValueError(f"expected an (H, W, 4) uint8 RGBA image, got {arr.shape} {arr.dtype}")
    height, width = arr.shape[:2]
    sizes = pyramid_sizes(width, height)
    levels = [np.ascontiguousarray(arr)]
    current = _decode(arr)
    for w, h in sizes[1:]:
        current = _downsample(current, w, h)
        levels.append(_encode(current))
    return levels


# ---------------------------------------------------------------------------------------------
# The level formula
# ---------------------------------------------------------------------------------------------

#: Distance term for an infinitely far object (and brightness term for a black scene): larger
#: than any finite term (those are at most ~2100, the exponent range of a double) and than any
#: real pyramid depth, so clamping turns it into "coarsest level n".
FAR_LEVEL = 1 << 16

#: f used when the given eye-to-screen distance is 0, negative or NaN: the smallest value the
#: settings accept (``TcrSettings.f_m``'s lower bound). Everything farther than 1 um from the eye
#: is then coarse -- a broken f shows up at once as blurry textures rather than being hidden.
F_FALLBACK_M = 1e-6


def _floor_log2_ratio(num: float, den: float) -> int:
    """floor(log2(num / den)) for finite num, den > 0, exactly and without overflow.

    With num = a * 2^p and den = b * 2^q (a, b in [0.5, 1)), num / den = (a / b) * 2^(p - q)
    and a / b lies in (0.5, 2), so the floor is p - q, minus one when a < b. Computing num / den
    first could overflow (1e308 / 1e-6) or round up onto a power of two.
    """
    a, p = math.frexp(num)
    b, q = math.frexp(den)
    return p - q - (1 if a < b else 0)


def distance_term(distance_m: float, f_m: float) -> int:
    """The paper's j = floor(log2((d + f) / f)), never below 0.

    ``distance_m`` is the whole eye-to-object distance, i.e. the paper's d + f, so
    j = floor(log2(distance_m / f_m)). Fallbacks (the result is always a non-negative int):

    * distance NaN -> 0 (finest): when the geometry is broken, show quality rather than mush;
    * distance <= f, including 0, -0.0 and negative distances (eye inside the box) -> 0;
    * distance +inf -> :data:`FAR_LEVEL` (clamped to n by :func:`level_for`: coarsest);
    * f NaN, 0 or negative -> :data:`F_FALLBACK_M`, so anything beyond 1 um is coarse;
    * f +inf -> the largest finite double: every finite distance gets 0 (the limit of
      (d + f) / f as f grows), an infinite one still the coarsest level.
    """
    d = float(distance_m)
    if math.isnan(d) or d <= 0.0:
        return 0
    if math.isinf(d):
        return FAR_LEVEL
    return max(0, _floor_log2_ratio(d, _focal_length(f_m)))


def _focal_length(f_m: float) -> float:
    """f for :func:`distance_term`: NaN, 0 or negative -> F_FALLBACK_M, +inf -> the largest
    finite double."""
    f = float(f_m)
    if math.isnan(f) or f <= 0.0:
        return F_FALLBACK_M
    return 1.7976931348623157e308 if math.isinf(f) else f


def distance_terms(distances_m: np.ndarray, f_m: float) -> np.ndarray:
    """:func:`distance_term` of each distance at once (int64), the same fallbacks and the
    same exact floor (``frexp``): a real room's hundreds of objects a frame."""
    d = np.asarray(distances_m, np.float64).reshape(-1)
    f = _focal_length(f_m)
    out = np.zeros(len(d), np.int64)
    ok = np.isfinite(d) & (d > 0.0)
    a, p = np.frexp(d[ok])
    b, q = math.frexp(f)
    out[ok] = np.maximum(0, p.astype(np.int64) - q - (a < b))
    out[np.isposinf(d)] = FAR_LEVEL
    return out


def brightness_term(brightness: float, reference: float = 1.0) -> int:
    """+1 per halving of the scene brightness below the reference, 0 at or above it.

    j_l = floor(log2(reference / brightness)), never below 0, so exactly half the reference
    gives 1 and every further halving exactly one more (the paper assumes visual acuity is
    proportional to brightness). Fallbacks:

    * brightness 0 or negative, -inf included -> :data:`FAR_LEVEL` (nothing is visible: the
      coarsest level);
    * brightness NaN -> 0 (unknown light: keep quality), +inf -> 0 (brighter than any reference);
    * reference NaN, inf, 0 or negative -> 1.0 (the "as authored" brightness).
    """
    b = float(brightness)
    ref = float(reference)
    if not math.isfinite(ref) or ref <= 0.0:
        ref = 1.0
    if math.isnan(b) or b == math.inf:
        return 0
    if b <= 0.0:  # including -inf
        return FAR_LEVEL
    return max(0, _floor_log2_ratio(ref, b))


@dataclass(frozen=True)
class LevelReason:
    """One object's level and how it came about (for the tint overlay, the log and tests)."""

    distance: int  # distance term (0 when d is off)
    v: int  # +1 while the viewpoint moves (0 when v is off)
    g: int  # -1 on the gazed object while the gaze is fixed, else 0 (0 when g is off)
    l: int  # brightness term (0 when l is off)
    raw: int  # distance + v + g + l
    level: int  # raw clamped to [0, n]
    n: int  # the texture's coarsest level (0 for a 1x1 or untextured object)

    def describe(self, name: str) -> str:
        """``"sofa: level 4 = distance 3 + v 1 - g 0 + l 0, clamped to [0, 9]"``."""
        return (
            f"{name}: level {self.level} = distance {self.distance} + v {self.v} "
            f"- g {-self.g} + l {self.l}, clamped to [0, {self.n}]"
        )

    def plain(self, name: str) -> str:
        """The panel's readout, in words: the level, then each rule's share.

        ``"sofa: texture level 4 of 9 (0 is full detail) from distance +3, motion +1,
        gaze +0, dim light +0"``; a share too large to matter reads "coarsest".
        """

        def share(term: int) -> str:
            return "coarsest" if term >= FAR_LEVEL else f"{term:+d}"

        if self.n == 0:
            return f"{name}: full texture detail (its texture has no coarser levels)"
        text = (
            f"{name}: texture level {self.level} of {self.n} (0 is full detail) from "
            f"distance {share(self.distance)}, motion {share(self.v)}, "
            f"gaze {share(self.g)}, dim light {share(self.l)}"
        )
        if self.raw > self.n:
            text += f"; {self.n} is its coarsest"
        elif self.raw < 0:
            text += "; 0 is its finest"
        return text


def level_for(
    distance_m: float,
    f_m: float,
    n: int,
    *,
    moving: bool,
    gazed_fixed: bool,
    brightness: float,
    terms: TcrTerms,
    reference_brightness: float = 1.0,
    bias: int = 0,
) -> LevelReason:
    """The pyramid level for one object, with each term's share.

    ``moving`` is the viewpoint state, ``gazed_fixed`` whether *this* object is under a fixed
    gaze. The distance and brightness fallbacks are those of :func:`distance_term` and
    :func:`brightness_term`; a negative ``n`` is treated as 0 (a texture with one level), so the
    result is always an int in [0, max(n, 0)]. ``bias`` levels are added before the clamp
    (``tcr.level_bias``: the frame-rate governor's coarser textures).
    """
    top = max(0, int(n))
    dist = distance_term(distance_m, f_m) if terms.d else 0
    v = 1 if terms.v and moving else 0
    g = -1 if terms.g and gazed_fixed else 0
    lum = brightness_term(brightness, reference_brightness) if terms.l else 0
    raw = dist + v + g + lum + int(bias)
    return LevelReason(distance=dist, v=v, g=g, l=lum, raw=raw, level=min(max(raw, 0), top), n=top)


# ---------------------------------------------------------------------------------------------
# The paper's 4-state motion model
# ---------------------------------------------------------------------------------------------


def _finite_or_none(value: object) -> float | None:
    """``value`` as a finite float, or None when it is NaN, infinite or not a number at all."""
    try:
        x = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError, OverflowError):
        return None
    return x if math.isfinite(x) else None


class MotionStateMachine:
    """The paper's 4 states from viewpoint motion and gaze: 0 still/gaze moving, 1 moving/moving,
    2 still/gaze fixed, 3 moving/gaze fixed (state = moving + 2*fixed).

    The viewpoint speed is noisy (head jitter, frame-time spikes), and a level that flickers
    between two pyramid levels is worse than either, so "moving" needs the speed above
    ``move_on`` for ``window_s`` without a break, and "still" needs it below ``move_off`` for
    ``window_s`` (hysteresis plus a time window). The gaze state is the caller's decision (held
    mouse button or dwell, already debounced by :class:`app.gaze.GazeModel`) and applies at once.
    """

    def __init__(
        self, move_on: float = 0.15, move_off: float = 0.05, window_s: float = 0.15
    ) -> None:
        self.move_on, self.move_off, self.window_s = 0.15, 0.05, 0.15
        self.configure(move_on, move_off, window_s)
        self.viewpoint_moving = False
        self.gaze_fixed = False
        self.transitions = 0
        self._pending_s = 0.0  # how long the speed has argued for the other viewpoint state

    @property
    def state(self) -> int:
        return int(self.viewpoint_moving) + 2 * int(self.gaze_fixed)

    def configure(self, move_on: float, move_off: float, window_s: float) -> None:
        """Take new thresholds (the settings panel changed) without losing the current state.

        A NaN, infinite or negative value keeps the default for that parameter. Swapped
        thresholds (move_off > move_on) would make a speed between them toggle the state every
        window, so the larger one is always the "on" threshold.
        """
        on = _finite_or_none(move_on)
        off = _finite_or_none(move_off)
        window = _finite_or_none(window_s)
        on = on if on is not None and on >= 0.0 else 0.15
        off = off if off is not None and off >= 0.0 else 0.05
        self.move_on, self.move_off = max(on, off), min(on, off)
        self.window_s = window if window is not None and window >= 0.0 else 0.15

    def update(self, dt: float, viewpoint_speed: float, gaze_fixed: bool) -> int:
        """Advance by ``dt`` seconds with the speed measured over that interval; returns the state.

        A sample with NaN, infinite or negative ``dt``, or a NaN or infinite speed, carries no
        usable motion information and is ignored (the pending window neither grows nor resets);
        the gaze flag is still applied, since it does not depend on the timing. A negative
        speed is taken as its magnitude.
        """
        before = self.state
        self.gaze_fixed = bool(gaze_fixed)
        step = _finite_or_none(dt)
        speed = _finite_or_none(viewpoint_speed)
        if step is not None and step >= 0.0 and speed is not None:
            speed = abs(speed)
            if self.viewpoint_moving:
                arguing = speed < self.move_off
            else:
                arguing = speed > self.move_on
            if arguing:
                self._pending_s += step
                # The tolerance absorbs the rounding of summed frame times (9 x 1/60 != 0.15).
                if self._pending_s >= self.window_s - 1e-9:
                    self.viewpoint_moving = not self.viewpoint_moving
                    self._pending_s = 0.0
            else:
                self._pending_s = 0.0
        after = self.state
        if after != before:
            self.transitions += 1
        return after


# ---------------------------------------------------------------------------------------------
# Per-frame levels for a scene
# ---------------------------------------------------------------------------------------------


class TcrController:
    """Per-frame level per object. Objects are given once as axis-aligned boxes plus the pyramid
    depth n of the texture each uses (n = 0 for untextured objects).

    The distance of an object is from the eye to the nearest point of its box (0 inside it),
    a cheap, conservative stand-in for the paper's object distance: a long wall next to the
    user counts as near, so it is never shown coarser than its nearest part needs.
    """

    def __init__(
        self, boxes_lo: np.ndarray, boxes_hi: np.ndarray, n_levels: list[int], names: list[str]
    ) -> None:
        lo = np.asarray(boxes_lo, np.float64).reshape(-1, 3)
        hi = np.asarray(boxes_hi, np.float64).reshape(-1, 3)
        count = lo.shape[0]
        if hi.shape[0] != count or len(n_levels) != count or len(names) != count:
            raise ValueError(
                f"boxes_lo ({count}), boxes_hi ({hi.shape[0]}), n_levels "
                f"({len(n_levels)}) and names ({len(names)}) must match"
            )
        # A box given with lo > hi on some axis is the same box; NaN corners stay NaN and give
        # a NaN distance, i.e. the finest level.
        self.lo = np.minimum(lo, hi)
        self.hi = np.maximum(lo, hi)
        self.n_levels = [max(0, int(n)) for n in n_levels]
        self.names = list(names)
        self.levels = np.zeros(count, np.int32)
        self.distances = np.zeros(count, np.float64)
        # This frame's terms (distance per object, v, the gazed object, l, the raw sums): the
        # reasons are made from them when asked (a LevelReason per object a frame cost 2.5 ms
        # in an 850-object room).
        self._terms: tuple[np.ndarray, int, int, int, np.ndarray] | None = None
        self._reasons: list[LevelReason] | None = None

    @property
    def reasons(self) -> list[LevelReason]:
        """Each object's level and how it came about (the log, tests)."""
        if self._reasons is None:
            self._reasons = [self.reason(i) for i in range(len(self.n_levels))]
        return self._reasons

    def reason(self, i: int) -> LevelReason:
        """Object ``i``'s level and how it came about (the TCR panel's gazed object)."""
        if self._reasons is not None:
            return self._reasons[i]
        n = self.n_levels[i]
        if self._terms is None:  # TCR off (or no frame yet): full quality
            return LevelReason(0, 0, 0, 0, 0, 0, n)
        dist, v, target, lum, raw = self._terms
        return LevelReason(
            int(dist[i]), v, -1 if i == target else 0, lum, int(raw[i]), int(self.levels[i]), n
        )

    def box_distances(self, eye: np.ndarray) -> np.ndarray:
        """Eye to the nearest point of each box (0 inside); NaN where eye or box is NaN.

        ``hypot`` instead of a sum of squares so that 1e200-metre boxes do not overflow, and
        floating-point warnings are silenced because inf - inf is an expected NaN here.
        """
        e = np.asarray(eye, np.float64).reshape(3)
        with np.errstate(all="ignore"):
            gap = np.maximum(np.maximum(self.lo - e, e - self.hi), 0.0)
            # np.maximum propagates NaN, so a NaN eye or corner gives a NaN distance.
            return np.hypot(np.hypot(gap[:, 0], gap[:, 1]), gap[:, 2])

    def update(
        self,
        eye: np.ndarray,
        gazed: int | None,
        moving: bool,
        gaze_fixed: bool,
        brightness: float,
        settings: TcrSettings,
    ) -> np.ndarray:
        """This frame's level (int32) per object; :attr:`reasons` says why.

        With ``settings.enabled`` False every level is 0 (full quality) and every reason is
        all zeros. ``gazed`` is the object under the gaze ray (None, or an index out of range,
        means none); it only counts while ``gaze_fixed``.
        """
        count = len(self.names)
        self.distances = self.box_distances(eye) if count else np.zeros(0, np.float64)
        self._reasons = None
        if not settings.enabled:
            self._terms = None
            self.levels = np.zeros(count, np.int32)
            return self.levels.copy()
        # level_for for every object at once (tests/test_tcr.py holds them equal)
        terms = terms_from_settings(settings)
        target = gazed if gaze_fixed and gazed is not None and 0 <= gazed < count else -1
        dist = distance_terms(self.distances, settings.f_m) if terms.d else np.zeros(count, int)
        v = 1 if terms.v and moving else 0
        lum = brightness_term(brightness, 1.0) if terms.l else 0
        raw = dist + (v + lum + int(settings.level_bias))
        if terms.g and target >= 0:
            raw[target] -= 1
        self._terms = (dist, v, target if terms.g else -1, lum, raw)
        top = np.asarray(self.n_levels, np.int64)
        self.levels = np.minimum(np.maximum(raw, 0), top).astype(np.int32)
        return self.levels.copy()


def finest_per_texture(
    levels: list[int] | np.ndarray, texture_of_object: list[int | None], n_textures: int
) -> list[int]:
    """The finest (smallest) level any object uses, per texture; -1 if no object uses it.

    "Unused" is -1 rather than a guessed level because what to do with a texture no object
    needs (keep it, drop its fine levels, evict it) is the caller's policy. Objects without a
    texture (None) or with an index outside [0, n_textures) are skipped, as are objects beyond
    ``levels``; a negative level counts as 0 (finest).
    """
    finest = [-1] * max(0, int(n_textures))
    for level, tex in zip(levels, texture_of_object):
        if tex is None or not 0 <= tex < len(finest):
            continue
        level = max(0, int(level))
        if finest[tex] < 0 or level < finest[tex]:
            finest[tex] = level
    return finest
