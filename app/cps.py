"""Coarse pixel shading against VR sickness (CPS paper, SPEC C): the numpy reference model.

Near objects that stream across the edge of the view cause vection, and vection causes sickness;
the paper lowers the detail there. Three parts, each defined here exactly so that the GLSL passes
can mirror them and the tests can hold both to one definition:

1. **Side caps** (:func:`side_caps`): rays from the eye through the left, right and bottom edges
   of the view; the nearer the nearest hit on a side, the coarser that side may become.
2. **Detail map** (:func:`detail_map`): a level s = 0..5 per pixel, meaning an aligned block of
   2^s x 2^s pixels that shares one lighting result. The level grows with the angle from the
   gaze, limited by the side caps, and is chosen so that every aligned block is uniform.
3. **Reconstruction filters** (:func:`hierarchical_filter`, the paper's 3.2.2, and the ordinary
   :func:`bilinear_filter`) that turn the block colours back into a smooth image.

Conventions (shared with the shaders):

- Pixel coordinates (x, y) are OpenGL window coordinates of *one eye's* viewport of W x H
  pixels, origin at the **bottom-left**; arrays are indexed ``[y, x]`` (row 0 = bottom row).
  The centre of pixel (x, y) is (x + 0.5, y + 0.5).
- The normalised viewport point of :meth:`EyeView.ray` has (0, 0) at the **top-left**, so a GL
  point (px, py) maps to u = px / W, v = 1 - py / H (for a pixel centre, px = x + 0.5).
- The block of pixel P at level s has size L = 2^s and origin O = P - (P mod L) per axis
  (``P & ~(L - 1)``); blocks at the right and top border may stick out of the viewport.

Like :mod:`app.tcr`, this is plain numpy with no GL or Qt, and every function documents what it
does with NaN, infinite, empty or out-of-range input instead of raising. Comparisons happen in
float64 here and in float32 on the GPU, so the two may differ where a value lies exactly on a
step (a level boundary, a rounding half-way point); nowhere else.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike

from app.camera import EyeView
from app.raycast import RayCaster
from app.settings import CpsSettings

#: Coarsest level the model knows: blocks of 2^5 = 32 pixels square (paper: 1x1 ... 32x32).
MAX_LEVEL = 5
#: The sides that edge rays probe, in the order their rays are cast.
SIDES = ("left", "right", "bottom")


def _clamped_max_level(settings: CpsSettings) -> int:
    """``settings.max_level`` limited to 0..MAX_LEVEL (a setting made around validation)."""
    try:
        return int(min(MAX_LEVEL, max(0, int(settings.max_level))))
    except (TypeError, ValueError, OverflowError):
        return 0


# ---------------------------------------------------------------------------------------------
# Rays
# ---------------------------------------------------------------------------------------------


def view_rays(eye: EyeView, u: ArrayLike, v: ArrayLike) -> np.ndarray:
    """World-space unit directions through normalised viewport points, vectorised.

    The same mapping as :meth:`EyeView.ray` (and the same fallbacks): u and v are clamped to
    [0, 1], a non-finite coordinate becomes 0.5, (0, 0) is the top-left corner. ``u`` and ``v``
    broadcast against each other; the result has their shape plus a last axis of 3.
    """
    u_arr, v_arr = np.broadcast_arrays(np.asarray(u, np.float64), np.asarray(v, np.float64))
    u_arr = np.clip(np.where(np.isfinite(u_arr), u_arr, 0.5), 0.0, 1.0)
    v_arr = np.clip(np.where(np.isfinite(v_arr), v_arr, 0.5), 0.0, 1.0)
    ndc = np.stack(
        [2 * u_arr - 1, 1 - 2 * v_arr, np.full_like(u_arr, -1.0), np.ones_like(u_arr)], axis=-1
    )
    p = ndc @ np.linalg.inv(eye.projection).T
    d_view = p[..., :3] / p[..., 3:4]
    d = d_view @ np.linalg.inv(eye.view)[:3, :3].T
    return d / np.linalg.norm(d, axis=-1, keepdims=True)


def angle_deg(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Angle in degrees between direction vectors (last axis), as atan2(|a x b|, a . b).

    The atan2 form stays accurate for tiny and for near-180-degree angles, where acos of the dot
    product loses all precision. NaN in a vector gives NaN.
    """
    cross = np.linalg.norm(np.cross(a, b), axis=-1)
    dot = np.sum(a * b, axis=-1)
    return np.degrees(np.arctan2(cross, dot))


def edge_rays(eye: EyeView, n: int) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Origins and unit directions of the edge rays of one eye, ``n`` per side.

    With t_k = (k + 0.5) / n for k = 0 .. n-1: "left" goes through (u = 0, v = t_k), "right"
    through (u = 1, v = t_k) and "bottom" through (u = t_k, v = 1). Every ray starts at the eye
    position. Each value is a pair of (n, 3) float64 arrays; ``n`` below 1 is taken as 1.
    """
    n = max(1, int(n))
    t = (np.arange(n, dtype=np.float64) + 0.5) / n
    zeros, ones = np.zeros(n), np.ones(n)
    origins = np.broadcast_to(np.asarray(eye.position, np.float64), (n, 3))
    return {
        "left": (origins.copy(), view_rays(eye, zeros, t)),
        "right": (origins.copy(), view_rays(eye, ones, t)),
        "bottom": (origins.copy(), view_rays(eye, t, ones)),
    }


# ---------------------------------------------------------------------------------------------
# Side caps
# ---------------------------------------------------------------------------------------------


def cap_from_distance(distance_m: float, settings: CpsSettings) -> int:
    """The coarsest level a side may reach when its nearest edge-ray hit is ``distance_m`` away.

    cap = round(max_level * clamp((far_m - d) / (far_m - near_m), 0, 1)), rounding half up
    (floor(x + 0.5), so the shader needs no roundEven); a hit at or nearer than near_m allows
    max_level, one at or beyond far_m allows nothing. Fallbacks: d infinite or NaN (no hit)
    -> 0; far_m <= near_m -> max_level if d <= near_m else 0; near_m or far_m not finite -> 0
    (a broken setting never removes detail).
    """
    max_level = _clamped_max_level(settings)
    d = float(distance_m)
    near, far = float(settings.near_m), float(settings.far_m)
    if not (math.isfinite(d) and math.isfinite(near) and math.isfinite(far)):
        return 0
    if far <= near:
        return max_level if d <= near else 0
    t = min(1.0, max(0.0, (far - d) / (far - near)))
    return int(math.floor(max_level * t + 0.5))


@dataclass
class SideCaps:
    """What the edge rays of one eye found.

    ``caps``: side -> coarsest level allowed there (0 = no reduction); ``distances``: side ->
    nearest hit distance in metres (inf if none); ``hits``: (N, 3) world-space points of every
    ray that hit, for the visualisation.
    """

    caps: dict[str, int] = field(default_factory=lambda: dict.fromkeys(SIDES, 0))
    distances: dict[str, float] = field(default_factory=lambda: dict.fromkeys(SIDES, math.inf))
    hits: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))


def side_caps(caster: RayCaster | None, eye: EyeView, settings: CpsSettings) -> SideCaps:
    """Cast ``settings.rays_per_side`` edge rays per side (one batch) and derive the caps.

    Each side's cap is :func:`cap_from_distance` of its nearest hit. Without a scene
    (``caster is None``) every cap is 0 and nothing is hit.
    """
    if caster is None:
        return SideCaps()
    n = max(1, int(settings.rays_per_side))
    rays = edge_rays(eye, n)
    origins = np.concatenate([rays[side][0] for side in SIDES])
    dirs = np.concatenate([rays[side][1] for side in SIDES])
    dist, _owner = caster.cast_many(origins, dirs)
    dist = np.where(np.isnan(dist), np.inf, dist)
    caps: dict[str, int] = {}
    distances: dict[str, float] = {}
    for i, side in enumerate(SIDES):
        nearest = float(np.min(dist[i * n : (i + 1) * n]))
        distances[side] = nearest
        caps[side] = cap_from_distance(nearest, settings)
    hit = np.isfinite(dist)
    hits = origins[hit] + dirs[hit] * dist[hit, None]
    return SideCaps(caps=caps, distances=distances, hits=hits)


# ---------------------------------------------------------------------------------------------
# Detail map
# ---------------------------------------------------------------------------------------------


def desired_level(theta_deg: ArrayLike, cap: ArrayLike, settings: CpsSettings) -> np.ndarray:
    """The level a point would like from its angle to the gaze, limited by its side cap.

    e = 0 if theta <= fovea_deg, else floor((theta - fovea_deg) / deg_per_level) + 1; the result
    is min(e, cap, max_level), never below 0. Vectorised: ``theta_deg`` and ``cap`` broadcast;
    the result is an int64 array of their shape (0-d for scalars).

    Fallbacks: theta NaN -> 0; theta +inf -> max_level (before the cap); a fractional cap is
    floored and a NaN cap is 0; fovea_deg NaN -> no reduction anywhere; deg_per_level NaN or
    <= 0 -> anything beyond the fovea goes straight to max_level.
    """
    max_level = _clamped_max_level(settings)
    theta = np.asarray(theta_deg, np.float64)
    cap_arr = np.asarray(cap, np.float64)
    cap_arr = np.floor(np.where(np.isnan(cap_arr), 0.0, cap_arr))
    fovea = float(settings.fovea_deg)
    step = float(settings.deg_per_level)
    if math.isnan(fovea):
        return np.zeros(np.broadcast(theta, cap_arr).shape, np.int64)
    with np.errstate(invalid="ignore", over="ignore", divide="ignore"):
        beyond = theta > fovea  # False for NaN
        if step > 0 and not math.isnan(step):
            e = np.floor((theta - fovea) / step) + 1.0
        else:
            e = np.full(theta.shape, float(max_level))
        e = np.where(beyond, np.clip(np.nan_to_num(e, nan=0.0), 0.0, max_level), 0.0)
    level = np.clip(np.minimum(e, cap_arr), 0.0, max_level)
    return level.astype(np.int64)


def cap_at(u: ArrayLike, v: ArrayLike, caps: Mapping[str, int] | SideCaps) -> np.ndarray:
    """The side cap at normalised viewport points (u, v), (0, 0) top-left; int64 array.

    cap(u, v) = floor(max(mix(capL, capR, clamp((u - 0.25) / 0.5, 0, 1)), capB * wB)) with
    wB = clamp((v - 0.5) / 0.25, 0, 1): the left cap holds on the left quarter of the view, the
    right cap on the right quarter, with a linear blend between them (so the middle gets their
    average rather than no reduction at all), and the bottom cap ramps in over the lower half.
    A missing side counts as 0. The shader's ``side_cap`` (cps_detail.glsl) is the same.
    """
    if isinstance(caps, SideCaps):
        caps = caps.caps
    u_arr, v_arr = np.broadcast_arrays(np.asarray(u, np.float64), np.asarray(v, np.float64))
    t = np.clip((u_arr - 0.25) / 0.5, 0.0, 1.0)
    w_b = np.clip((v_arr - 0.5) / 0.25, 0.0, 1.0)
    c_l, c_r, c_b = (float(caps.get(side, 0)) for side in SIDES)
    best = np.maximum(c_l + (c_r - c_l) * t, c_b * w_b)
    return np.floor(np.nan_to_num(best, nan=0.0)).astype(np.int64)


def block_centres(size: int, level: int) -> np.ndarray:
    """Centre coordinate (GL pixels, one axis) of every aligned 2^level block of a viewport side.

    Block i covers pixels [i * 2^s, (i + 1) * 2^s); its centre i * 2^s + 2^(s-1) is clamped to
    [0.5, size - 0.5], which moves the centre of a block sticking out of the viewport inwards
    (for level 0 the centre is the pixel centre). Returns ceil(size / 2^s) values.
    """
    size = max(1, int(size))
    b = 1 << int(level)
    count = -(-size // b)
    centre = np.arange(count, dtype=np.float64) * b + b / 2.0
    return np.clip(centre, 0.5, size - 0.5)


def detail_map(
    eye: EyeView,
    width: int,
    height: int,
    gaze_uv: tuple[float, float],
    caps: Mapping[str, int] | SideCaps,
    settings: CpsSettings,
) -> np.ndarray:
    """The level s of every pixel of one eye's W x H viewport, as an (H, W) uint8 array.

    theta(u, v) is the angle between the eye's rays through (u, v) and through the gaze point
    ``gaze_uv`` (clamped into the view as :meth:`EyeView.ray` clamps), and the desired level at
    a point is ``desired_level(theta, cap_at(u, v, caps), settings)``.

    Pixel (x, y) gets the largest s in 1..max_level whose aligned 2^s block (origin
    (x & ~(2^s - 1), y & ~(2^s - 1))) has a desired level >= s at its centre (see
    :func:`block_centres`), and 0 if there is none. Every aligned block of level s is then
    uniform: all its pixels test the same block for s, so they all reach at least s; and if
    one of them reached s' > s, the 2^s' block that contains it contains the whole 2^s block
    (aligned blocks nest), so all of them would reach s'. That lets a coarse pass at 1/2^s
    resolution shade exactly one sample per block.

    ``width``/``height`` below 1 are taken as 1.
    """
    w, h = max(1, int(width)), max(1, int(height))
    out = np.zeros((h, w), np.uint8)
    max_level = _clamped_max_level(settings)
    if max_level == 0:
        return out
    gaze = view_rays(eye, gaze_uv[0], gaze_uv[1])
    for s in range(1, max_level + 1):
        b = 1 << s
        cx = block_centres(w, s)[None, :]
        cy = block_centres(h, s)[:, None]
        u, v = cx / w, 1.0 - cy / h
        theta = angle_deg(view_rays(eye, u, v), gaze)
        ok = desired_level(theta, cap_at(u, v, caps), settings) >= s
        # Later (coarser) levels overwrite: the largest qualifying s wins.
        full = np.repeat(np.repeat(ok, b, axis=0), b, axis=1)[:h, :w]
        out[full] = s
    return out


def level_shares(level_map: np.ndarray, max_level: int = MAX_LEVEL) -> list[float]:
    """Fraction of the pixels at each level 0..max_level (an empty map gives zeros).

    Values outside 0..max_level are counted nowhere, so the shares then sum to less than 1.
    """
    levels = np.asarray(level_map).ravel().astype(np.int64)
    n = max(0, int(max_level)) + 1
    if levels.size == 0:
        return [0.0] * n
    inside = levels[(levels >= 0) & (levels < n)]
    counts = np.bincount(inside, minlength=n)[:n]
    return [float(c) / levels.size for c in counts]


def shaded_samples(level_map: np.ndarray) -> int:
    """Lighting evaluations needed for a level map: the number of (level, block) pairs.

    For each level s, every aligned 2^s x 2^s block holding at least one pixel of level s counts
    once. For a block-uniform map (what :func:`detail_map` makes) that is the number of blocks,
    which equals the sum over pixels of 1 / 4^s wherever no block sticks out of the viewport;
    a block cut by the right or top border still costs one evaluation and is counted as one.
    Negative levels count as 0, levels above MAX_LEVEL as MAX_LEVEL.
    """
    levels = np.clip(np.asarray(level_map, np.int64), 0, MAX_LEVEL)
    if levels.size == 0:
        return 0
    h, w = levels.shape
    total = 0
    for s in range(MAX_LEVEL + 1):
        ys, xs = np.nonzero(levels == s)
        if ys.size == 0:
            continue
        grid = np.zeros((((h - 1) >> s) + 1, ((w - 1) >> s) + 1), bool)
        grid[ys >> s, xs >> s] = True
        total += int(grid.sum())
    return total


# ---------------------------------------------------------------------------------------------
# Reconstruction filters
# ---------------------------------------------------------------------------------------------


def _levels_and_grid(
    colours: np.ndarray, levels: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Validated (H, W) block sizes L and full (H, W) x and y pixel index grids."""
    if levels.shape != colours.shape[:2]:
        raise ValueError(f"level map {levels.shape} does not match the image {colours.shape}")
    h, w = levels.shape
    s = np.clip(levels.astype(np.int64), 0, MAX_LEVEL)
    size = np.left_shift(np.int64(1), s)
    y, x = np.indices((h, w), dtype=np.int64)
    return size, x, y


def _per_pixel(weight: np.ndarray, ndim: int) -> np.ndarray:
    """An (H, W) weight shaped to broadcast against an (H, W, ...) image."""
    return weight.reshape(weight.shape + (1,) * (ndim - 2))


def hierarchical_filter(C: ArrayLike, S: ArrayLike) -> np.ndarray:
    """The paper's hierarchical bilinear filter (3.2.2) on a block colour image.

    ``C`` is (H, W) or (H, W, channels), every pixel holding its block's colour; ``S`` is the
    (H, W) level map (values clamped into 0..MAX_LEVEL). Per pixel P (GL coordinates, centre
    c = P + 0.5), with sign(0) counted as +:

    - L = 2^S[P], O = P - (P mod L), l = (c - O) / L - 0.5 per axis (in (-0.5, 0.5)).
    - a0 = the axis where |l| is larger (ties: x), a1 the other; l0 = l[a0], l1 = l[a1].
    - Crossing the block boundary along an axis a in the direction of a sign means the pixel
      index O[a] - 1 if the sign is negative, else O[a] + L; every neighbour is clamped into
      the viewport afterwards.
    - P0 = P crossed along a0 in the direction of l0; t10 = C[P0]. Q = P crossed along a1 in the
      direction of l1; t01 = C[Q]. t00 = C[P].
    - (O', L') = the block of P0 (from S[P0]); R = P0 crossed along a1, in the direction of l1,
      over *that* block's boundary; t11 = C[R]. l2 = (P0[a1] + 0.5 - O'[a1]) / L' - 0.5.
    - output = lerp(lerp(t11, t10, |l2|), lerp(t01, t00, |l1|), |l0|), lerp(A, B, t) =
      t A + (1 - t) B.

    Note that R follows the sign of l1, not of l2: where P0's block is larger than P's, l2 can
    have the opposite sign, and t11 then comes from the far side of P0's block. That is the
    definition as specified (SPEC C); the shader must do the same to match this reference.

    A neighbour clamped at the viewport border lands in P's own block (the block touches the
    border), so the border needs no special case. Level-0 pixels have l = 0 and return C[P]
    (exactly, for finite C). All weights lie in [0, 1] and sum to 1, so the output stays in the
    convex hull of the inputs. Returns float64 of C's shape.
    """
    colours = np.asarray(C, np.float64)
    levels = np.asarray(S)
    if colours.size == 0:
        return colours.copy()
    size, x, y = _levels_and_grid(colours, levels)
    h, w = levels.shape
    ox, oy = x - x % size, y - y % size
    lx = (x + 0.5 - ox) / size - 0.5
    ly = (y + 0.5 - oy) / size - 0.5
    swap = np.abs(ly) > np.abs(lx)  # a0 is y; ties keep x
    # The neighbouring pixel index across P's block boundary, per axis, towards sign(l).
    nx = np.where(lx < 0, ox - 1, ox + size)
    ny = np.where(ly < 0, oy - 1, oy + size)
    p0x = np.clip(np.where(swap, x, nx), 0, w - 1)
    p0y = np.clip(np.where(swap, ny, y), 0, h - 1)
    qx = np.clip(np.where(swap, nx, x), 0, w - 1)
    qy = np.clip(np.where(swap, y, ny), 0, h - 1)
    size0 = size[p0y, p0x]
    o0x, o0y = p0x - p0x % size0, p0y - p0y % size0
    rx = np.clip(np.where(swap, np.where(lx < 0, o0x - 1, o0x + size0), p0x), 0, w - 1)
    ry = np.clip(np.where(swap, p0y, np.where(ly < 0, o0y - 1, o0y + size0)), 0, h - 1)
    l2 = np.where(swap, (p0x + 0.5 - o0x) / size0, (p0y + 0.5 - o0y) / size0) - 0.5
    a0 = _per_pixel(np.abs(np.where(swap, ly, lx)), colours.ndim)
    a1 = _per_pixel(np.abs(np.where(swap, lx, ly)), colours.ndim)
    a2 = _per_pixel(np.abs(l2), colours.ndim)
    t00, t10, t01, t11 = colours, colours[p0y, p0x], colours[qy, qx], colours[ry, rx]
    return a0 * (a2 * t11 + (1 - a2) * t10) + (1 - a0) * (a1 * t01 + (1 - a1) * t00)


def bilinear_filter(C: ArrayLike, S: ArrayLike) -> np.ndarray:
    """Ordinary bilinear reconstruction on each pixel's own block grid, for comparison.

    Per axis, with L = 2^S[P] and c the pixel centre: f = c / L - 0.5, i = floor(f),
    w = f - i. Block i of P's grid is read at pixel i * L + L // 2 (its centre pixel; for L = 1
    the pixel itself), clamped into the viewport, whatever level that pixel really has. The
    output mixes blocks (i, j), (i+1, j), (i, j+1), (i+1, j+1) with weights (1-wx)(1-wy),
    wx(1-wy), (1-wx)wy, wx wy. Where the level is uniform this equals
    :func:`hierarchical_filter`; where sizes meet it ignores them (hence the seams the paper's
    filter avoids). Shapes, clamping of S and the return type as for the hierarchical filter.
    """
    colours = np.asarray(C, np.float64)
    levels = np.asarray(S)
    if colours.size == 0:
        return colours.copy()
    size, x, y = _levels_and_grid(colours, levels)
    h, w = levels.shape
    fx = (x + 0.5) / size - 0.5
    fy = (y + 0.5) / size - 0.5
    ix, iy = np.floor(fx).astype(np.int64), np.floor(fy).astype(np.int64)
    wx = _per_pixel(fx - ix, colours.ndim)
    wy = _per_pixel(fy - iy, colours.ndim)
    half = size // 2
    x0 = np.clip(ix * size + half, 0, w - 1)
    x1 = np.clip((ix + 1) * size + half, 0, w - 1)
    y0 = np.clip(iy * size + half, 0, h - 1)
    y1 = np.clip((iy + 1) * size + half, 0, h - 1)
    bottom = (1 - wx) * colours[y0, x0] + wx * colours[y0, x1]
    top = (1 - wx) * colours[y1, x0] + wx * colours[y1, x1]
    return (1 - wy) * bottom + wy * top


def block_image(image: ArrayLike, S: ArrayLike) -> np.ndarray:
    """The block colour image a coarse pass makes from a full-rate ``image``.

    Every pixel takes the colour of its block's centre pixel O + L // 2 (per axis, clamped into
    the viewport), which is what shading one sample per block produces. Keeps ``image``'s
    dtype and shape; S as for the filters.
    """
    img = np.asarray(image)
    levels = np.asarray(S)
    if img.size == 0:
        return img.copy()
    size, x, y = _levels_and_grid(img, levels)
    h, w = levels.shape
    cx = np.clip(x - x % size + size // 2, 0, w - 1)
    cy = np.clip(y - y % size + size // 2, 0, h - 1)
    return img[cy, cx]
