"""Deterministic procedural textures for the built-in showroom: no files, no downloads.

Every texture is drawn with vectorised numpy from its own generator seeded by
``np.random.default_rng([SEED, salt])``, so the set is identical on every run and does not depend
on the order in which textures are made. Colours are authored in sRGB (as :class:`Texture`
expects); row 0 is the top of the image. The tiling textures (wallpaper, parquet, ceiling, fabric,
wood) are seamless: their patterns have periods that divide the image size and their noise is
filtered in the Fourier domain, which is periodic by construction.

The paintings and the rug are single pictures (``repeat=False``, uvs 0..1); the paintings are
drawn in their own aspect ratio (:data:`PAINTING_ASPECTS`, width / height) and
stored as 512x512 squares: mapped onto a canvas of that aspect with uvs 0..1 they are undistorted.
"""

from __future__ import annotations

import functools

import numpy as np

from app.scene import Texture

SEED = 20_240_611

#: The five paintings in hanging order, with their canvas aspect (width / height).
PAINTING_ASPECTS: dict[str, float] = {
    "painting_abstract": 0.8,
    "painting_landscape": 1.5,
    "painting_stripes": 0.75,
    "painting_circles": 4.0 / 3.0,
    "painting_colorfield": 0.75,
}

Color = tuple[float, float, float]


def _rng(salt: int) -> np.random.Generator:
    return np.random.default_rng([SEED, salt])


def _coords(size: int, aspect: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """Pixel-centre coordinates as a (1, W) row of x in [0, aspect) and an (H, 1) column of y in
    [0, 1), y growing downwards (image rows); they broadcast to full images where combined."""
    t = (np.arange(size, dtype=np.float32) + 0.5) / size
    return (t * np.float32(aspect))[None, :], t[:, None]


def _noise(
    rng: np.random.Generator, size: int, sigma_x: float, sigma_y: float | None = None
) -> np.ndarray:
    """Seamless Gaussian-filtered noise with zero mean and unit deviation (sigmas in pixels).

    Smooth noise is synthesised on a coarser periodic grid and upsampled (wrapping), which keeps
    the whole texture set fast; fine noise is made at full size.
    """
    sy = sigma_x if sigma_y is None else sigma_y
    step = 1
    while step < 8 and min(sigma_x, sy) / (step * 2) >= 2.0 and size % (step * 2) == 0:
        step *= 2
    n = size // step
    white = rng.standard_normal((n, n), dtype=np.float32)
    fy = np.fft.fftfreq(n).astype(np.float32)[:, None]
    fx = np.fft.rfftfreq(n).astype(np.float32)[None, :]
    sxs, sys = np.float32(sigma_x / step), np.float32(sy / step)
    filt = np.exp(np.float32(-2.0 * np.pi**2) * ((fx * sxs) ** 2 + (fy * sys) ** 2))
    out = np.fft.irfft2(np.fft.rfft2(white) * filt, s=(n, n)).astype(np.float32)
    if step > 1:
        out = _upsample_wrap(out, step)
    out -= out.mean()
    return out / max(float(out.std()), 1e-8)


def _upsample_wrap(a: np.ndarray, step: int) -> np.ndarray:
    """Periodic bilinear upsampling by an integer factor."""
    n = a.shape[0]
    t = (np.arange(n * step, dtype=np.float32) + 0.5) / step - 0.5
    i0 = np.floor(t).astype(np.int64)
    f = (t - i0).astype(np.float32)
    i0 %= n
    i1 = (i0 + 1) % n
    rows = a[i0] * (1 - f)[:, None] + a[i1] * f[:, None]
    return rows[:, i0] * (1 - f)[None, :] + rows[:, i1] * f[None, :]


def _fbm(rng: np.random.Generator, size: int, sigma: float, octaves: int = 4) -> np.ndarray:
    total = np.zeros((size, size), np.float32)
    amp = 1.0
    for _ in range(octaves):
        total += amp * _noise(rng, size, sigma)
        sigma *= 0.5
        amp *= 0.5
    return total / max(float(total.std()), 1e-8)


def _rgb(c: tuple[int, int, int]) -> np.ndarray:
    return np.asarray(c, np.float32) / 255.0


def _solid(size: int, c: tuple[int, int, int]) -> np.ndarray:
    return np.broadcast_to(_rgb(c), (size, size, 3)).copy()


def _paint(
    img: np.ndarray, alpha: np.ndarray | float, c: tuple[int, int, int] | np.ndarray
) -> None:
    """Composite colour ``c`` over ``img`` in place with coverage ``alpha`` (0..1, or a mask)."""
    col = _rgb(c) if isinstance(c, tuple) else np.asarray(c, np.float32)
    a = np.asarray(alpha)
    if a.ndim == 2 and a.shape != img.shape[:2]:
        a = np.broadcast_to(a, img.shape[:2])
    if a.dtype == bool:
        img[a] = col if col.ndim == 1 else col[a]
        return
    a = np.clip(a.astype(np.float32, copy=False), 0.0, 1.0)
    if a.ndim == 2:
        a = a[..., None]
    img += a * (col - img)


def _smoothstep(e0: float, e1: float, x: np.ndarray) -> np.ndarray:
    t = np.clip((x - e0) / (e1 - e0), 0.0, 1.0)
    return t * t * (3.0 - 2.0 * t)


def _texture(name: str, rgb: np.ndarray, repeat: bool = True) -> Texture:
    h, w = rgb.shape[:2]
    out = np.empty((h, w, 4), np.uint8)
    out[..., :3] = np.clip(rgb * 255.0 + 0.5, 0.0, 255.0).astype(np.uint8)
    out[..., 3] = 255
    return Texture(name, out, repeat)


@functools.lru_cache(maxsize=4)
def _canvas_grain(size: int) -> np.ndarray:
    """Linen weave and brush noise, shared by the paintings (read-only)."""
    wave = np.sin(np.arange(size, dtype=np.float32) * np.float32(2 * np.pi / 3.0))
    grain = 0.02 * wave[:, None] * wave[None, :] + 0.02 * _noise(_rng(10), size, 6.0, 1.5)
    grain.flags.writeable = False
    return grain


def _canvas(img: np.ndarray, strength: float = 1.0) -> np.ndarray:
    """The painting ``img`` on linen canvas with visible brush work."""
    shade = 1.0 + strength * _canvas_grain(img.shape[0])
    return np.clip(img * shade[..., None], 0.0, 1.0)


# -- tiling surfaces --------------------------------------------------------------------------


def wallpaper(size: int = 512) -> Texture:
    """Warm greige wallpaper: faint damask lattice, pinstripes and paper grain."""
    rng = _rng(1)
    y, x = np.mgrid[0:size, 0:size].astype(np.float32)
    k = 2 * np.pi / size
    cells = 4.0  # motif repeats per tile
    u, v = x * k * cells, y * k * cells
    lattice = np.cos(u) * np.cos(v)  # a diamond grid
    ogee = np.cos(u + v) * np.cos(u - v) + 0.6 * np.cos(2 * u) * np.cos(2 * v)
    motif = _smoothstep(0.35, 0.75, np.abs(lattice)) * 0.5 + _smoothstep(0.5, 1.1, ogee) * 0.5
    stripes = _smoothstep(0.92, 1.0, np.cos(x * k * 32.0))
    grain = _fbm(rng, size, 2.0, 3)
    blotch = _noise(rng, size, 40.0)
    shade = 1.0 + 0.045 * motif - 0.03 * stripes + 0.012 * grain + 0.015 * blotch
    img = _solid(size, (214, 204, 186)) * shade[..., None]
    return _texture("wallpaper", np.clip(img, 0, 1))


def _planks(size: int, rng: np.random.Generator):
    """The parquet's layout (8 rows of 2 staggered planks per tile): rows, columns, the row
    of each texel, the row height, the staggered x, the plank length and each texel's plank.
    The first draw of ``rng`` (the rows' offsets), so the colour and the relief agree."""
    rows, plank_len = 8, size // 2
    row_h = size // rows
    y, x = np.mgrid[0:size, 0:size]
    row = y // row_h
    offsets = rng.integers(0, plank_len, rows)
    xs = x + offsets[row]
    plank = row * 2 + (xs // plank_len) % 2  # 16 planks per tile, seamless horizontally
    return rows, y, row_h, xs, plank_len, plank


def parquet(size: int = 512) -> Texture:
    """Oak plank floor: 8 rows of 2 planks per tile, staggered, with grain and dark joints."""
    rng = _rng(2)
    rows, y, row_h, xs, plank_len, plank = _planks(size, rng)
    tone = rng.normal(0.0, 1.0, (rows * 2, 3)).astype(np.float32)
    base = _rgb((168, 116, 70)) * (1.0 + 0.10 * tone[:, :1] + 0.03 * tone)
    grain_warp = _noise(rng, size, 48.0, 3.0)  # streaks run along x (the plank length)
    fine = _noise(rng, size, 24.0, 0.8)
    phase = rng.uniform(0, 2 * np.pi, rows * 2).astype(np.float32)
    g = np.sin((y.astype(np.float32) * 0.9 + 9.0 * grain_warp) + phase[plank])
    rings = 0.5 + 0.5 * g
    shade = 0.86 + 0.10 * rings**3 + 0.05 * fine
    img = base[plank] * shade[..., None]
    joint_y = (y % row_h == 0) | (y % row_h == row_h - 1)
    joint_x = (xs % plank_len == 0) | (xs % plank_len == 1)
    img[joint_y | joint_x] *= 0.45
    return _texture("parquet", np.clip(img, 0, 1))


def parquet_relief(size: int = 512) -> Texture:
    """The parquet's tangent-space normal map (glTF: linear, x right, y up, z out of the
    surface): the planks' bevelled edges dip into the joints of :func:`parquet` (the same
    layout), each plank lies a little out of level, and the grain is faintly raised. Seen
    under a grazing light, the joints and the planks' edges catch and lose it."""
    rng = _rng(2)
    _rows, y, row_h, xs, plank_len, plank = _planks(size, rng)
    relief = _rng(12)  # its own draws after the shared layout
    # Height in texels (one texel is about 4 mm on the floor, 2 m per tile): 1 on a plank,
    # a bevel of 2 texels down to the joint, 0 in it.
    to_row_edge = np.minimum(y % row_h, row_h - 1 - y % row_h).astype(np.float32)
    along = xs % plank_len
    to_end = np.minimum(along, plank_len - 1 - along).astype(np.float32)
    edge = np.minimum(to_row_edge, to_end)
    height = 0.6 * _smoothstep(0.0, 2.5, edge)
    # each plank out of level by a fraction of a degree, the grain raised a little
    tilt = relief.normal(0.0, 0.004, (plank.max() + 1, 2)).astype(np.float32)
    grain = 0.08 * _noise(relief, size, 24.0, 0.8)
    height = height + grain
    # Gradients with wrap-around (the tile repeats); image rows run down, glTF's y up.
    dx = 0.5 * (np.roll(height, -1, axis=1) - np.roll(height, 1, axis=1)) + tilt[plank, 0]
    dy_down = 0.5 * (np.roll(height, -1, axis=0) - np.roll(height, 1, axis=0)) + tilt[plank, 1]
    n = np.stack([-dx, dy_down, np.ones_like(dx)], axis=-1)
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    return _texture("parquet_relief", n * 0.5 + 0.5)


def ceiling(size: int = 64) -> Texture:
    """Off-white stucco, 64x64 as in the TCR paper's room."""
    rng = _rng(3)
    shade = 1.0 + 0.02 * _fbm(rng, size, 1.5, 3)
    img = _solid(size, (236, 233, 226)) * shade[..., None]
    return _texture("ceiling", np.clip(img, 0, 1))


def fabric(size: int = 128) -> Texture:
    """Teal-grey upholstery: a twill weave with slub noise."""
    rng = _rng(4)
    y, x = np.mgrid[0:size, 0:size].astype(np.float32)
    twill = np.sin((x + y) * (2 * np.pi / 8.0))
    warp = np.sin(x * (2 * np.pi / 2.0)) * 0.5 + np.sin(y * (2 * np.pi / 2.0)) * 0.5
    slub = _noise(rng, size, 6.0, 0.7)
    shade = 1.0 + 0.06 * twill + 0.05 * warp + 0.05 * slub
    img = _solid(size, (78, 104, 112)) * shade[..., None]
    return _texture("fabric", np.clip(img, 0, 1))


def wood(size: int = 256) -> Texture:
    """Walnut for the chair, tables and sideboard: grain along u."""
    rng = _rng(5)
    y = np.mgrid[0:size, 0:size][0].astype(np.float32)
    warp = _noise(rng, size, 40.0, 4.0)
    fine = _noise(rng, size, 16.0, 0.7)
    g = 0.5 + 0.5 * np.sin(y * 0.55 + 7.0 * warp)
    shade = 0.8 + 0.22 * g**4 + 0.06 * fine
    img = _solid(size, (118, 78, 50)) * shade[..., None]
    return _texture("wood", np.clip(img, 0, 1))


def rug(size: int = 256) -> Texture:
    """A Persian-style rug: madder field, navy medallion, cream and navy borders."""
    rng = _rng(6)
    x, y = _coords(size)
    cx, cy = np.abs(x - 0.5), np.abs(y - 0.5)
    edge = np.minimum(0.5 - cx, 0.5 - cy)  # distance to the rug's edge
    img = _solid(size, (138, 34, 38))
    diamond = cx + cy
    _paint(img, _smoothstep(0.012, 0.0, diamond - 0.30), (28, 40, 82))
    _paint(img, _smoothstep(0.012, 0.0, diamond - 0.20), (228, 206, 160))
    _paint(img, _smoothstep(0.012, 0.0, diamond - 0.11), (138, 34, 38))
    petals = np.cos(np.arctan2(y - 0.5, x - 0.5) * 8.0) * 0.03 + 0.06
    _paint(img, _smoothstep(0.008, 0.0, np.hypot(cx, cy) - petals), (28, 40, 82))
    lattice = np.cos(x * 2 * np.pi * 10) * np.cos(y * 2 * np.pi * 10)
    _paint(img, 0.35 * _smoothstep(0.7, 0.9, lattice) * (diamond > 0.31), (90, 24, 30))
    _paint(img, (edge < 0.10) & (edge > 0.035), (28, 40, 82))
    _paint(img, (edge < 0.075) & (edge > 0.06), (228, 206, 160))
    border_motif = np.cos((x + y) * 2 * np.pi * 24) * ((edge < 0.10) & (edge > 0.035))
    _paint(img, 0.6 * _smoothstep(0.6, 0.9, border_motif), (190, 150, 70))
    _paint(img, edge < 0.035, (210, 190, 150))
    wool = 1.0 + 0.05 * _noise(rng, size, 1.0) + 0.04 * _noise(rng, size, 12.0)
    return _texture("rug", np.clip(img * wool[..., None], 0, 1), repeat=False)


# -- paintings ----------------------------------------------------------------------------------


def painting_abstract(size: int = 512) -> Texture:
    """A neo-plastic composition: black grid, primary colour fields on off-white."""
    aspect = PAINTING_ASPECTS["painting_abstract"]
    x, y = _coords(size, aspect)
    img = _solid(size, (238, 233, 220))
    xs = np.array([0.0, 0.17, 0.56, 0.70, 1.0]) * aspect
    ys = np.array([0.0, 0.24, 0.63, 0.84, 1.0])
    ci = np.searchsorted(xs, x) - 1
    cj = np.searchsorted(ys, y) - 1
    colours = {
        (1, 0): (196, 32, 36),
        (2, 0): (196, 32, 36),
        (0, 2): (24, 52, 148),
        (0, 3): (24, 52, 148),
        (3, 3): (238, 196, 34),
        (3, 1): (20, 20, 22),
        (2, 2): (230, 226, 214),
    }
    for (i, j), c in colours.items():
        _paint(img, (ci == i) & (cj == j), c)
    lw = 0.012
    for gx in xs[1:-1]:
        _paint(img, np.abs(x - gx) < lw, (18, 18, 20))
    for k, gy in enumerate(ys[1:-1]):
        span = (x > xs[1] - lw) if k == 2 else np.ones_like(x, bool)  # one line stops short
        _paint(img, (np.abs(y - gy) < lw) & span, (18, 18, 20))
    return _texture("painting_abstract", _canvas(img, 0.8), repeat=False)


def painting_landscape(size: int = 512) -> Texture:
    """Rolling hills at sunset under a warm sky, with a lake and cypresses."""
    rng = _rng(12)
    aspect = PAINTING_ASPECTS["painting_landscape"]
    x, y = _coords(size, aspect)
    sky_top, sky_low = _rgb((52, 92, 168)), _rgb((246, 190, 128))
    t = _smoothstep(0.0, 0.62, y)[..., None]
    img = np.broadcast_to(sky_top * (1 - t) + sky_low * t, (size, size, 3)).copy()
    sun = np.hypot(x - 1.08, y - 0.36)
    _paint(img, 0.55 * np.exp(-((sun / 0.16) ** 2)), (255, 224, 160))
    _paint(img, _smoothstep(0.062, 0.055, sun), (255, 240, 200))
    clouds = _fbm(rng, size, 18.0, 3)
    _paint(img, 0.55 * _smoothstep(0.8, 1.8, clouds) * _smoothstep(0.55, 0.1, y), (250, 232, 226))
    layers = [
        (0.50, 0.05, (112, 104, 150)),
        (0.60, 0.06, (74, 110, 92)),
        (0.72, 0.05, (58, 96, 52)),
        (0.86, 0.06, (34, 62, 30)),
    ]
    for k, (base, amp, colour) in enumerate(layers):
        ph = [float(p) for p in rng.uniform(0, 2 * np.pi, 3)]
        ridge = base - amp * (
            np.sin(x * 3.1 + ph[0])
            + 0.5 * np.sin(x * 7.3 + ph[1])
            + 0.25 * np.sin(x * 17.0 + ph[2])
        )
        below = _smoothstep(-0.004, 0.004, y - ridge)
        depth = np.clip((y - ridge) * 3.0, 0, 1)[..., None]
        col = _rgb(colour) * (1.0 - 0.25 * depth)
        _paint(img, below, col)
        if k == 1:  # a lake lying in front of the far hills
            lake = (np.abs(x - 0.45) / 0.42) ** 2 + (np.abs(y - 0.70) / 0.05) ** 2
            refl = sky_low * 0.8 + 0.1 * np.sin(y * 400.0)[..., None] * 0.3
            _paint(img, _smoothstep(1.0, 0.9, lake), refl)
    for cx, cy, h in [(0.22, 0.80, 0.22), (0.27, 0.82, 0.17), (1.32, 0.84, 0.25)]:
        shape = ((x - cx) / 0.022) ** 2 + ((y - (cy - h / 2)) / (h / 2)) ** 2
        _paint(img, _smoothstep(1.0, 0.85, shape), (22, 40, 22))
    return _texture("painting_landscape", _canvas(img, 1.2), repeat=False)


def painting_stripes(size: int = 512) -> Texture:
    """Slanted bands of saturated colour in varying widths (op-art stripes)."""
    rng = _rng(13)
    aspect = PAINTING_ASPECTS["painting_stripes"]
    x, y = _coords(size, aspect)
    palette = (
        np.array(
            [
                (232, 72, 56),
                (248, 178, 40),
                (40, 140, 120),
                (36, 64, 140),
                (240, 234, 220),
                (200, 60, 120),
                (24, 24, 30),
                (120, 190, 220),
            ],
            np.float32,
        )
        / 255.0
    )
    s = x + 0.28 * y + 0.02 * np.sin(y * 9.0)  # bands lean and waver slightly
    widths = rng.uniform(0.018, 0.07, 64).astype(np.float32)
    edges = np.cumsum(widths) - 0.1
    band = np.clip(np.searchsorted(edges, s), 0, len(widths) - 1)
    order = rng.permutation(np.resize(np.arange(len(palette)), len(widths)))
    for i in range(1, len(order)):  # no two neighbours alike
        if order[i] == order[i - 1]:
            order[i] = (order[i] + 3) % len(palette)
    img = palette[order[band]].copy()
    return _texture("painting_stripes", _canvas(img, 0.9), repeat=False)


def painting_circles(size: int = 512) -> Texture:
    """A 4x3 grid of squares, each holding wobbly concentric rings of colour."""
    rng = _rng(14)
    aspect = PAINTING_ASPECTS["painting_circles"]
    x, y = _coords(size, aspect)
    ncx, ncy = 4, 3
    cell = 1.0 / ncy
    cx = np.minimum((x / cell).astype(int), ncx - 1)
    cy = np.minimum((y / cell).astype(int), ncy - 1)
    lx = x / cell - cx - 0.5
    ly = y / cell - cy - 0.5
    wobble = 0.006 * _noise(rng, size, 8.0)
    r = np.hypot(lx, ly) + wobble
    palette = (
        np.array(
            [
                (210, 48, 40),
                (246, 196, 46),
                (30, 70, 160),
                (40, 140, 90),
                (236, 120, 40),
                (120, 40, 110),
                (240, 232, 214),
                (20, 24, 40),
                (110, 190, 210),
                (200, 110, 160),
            ],
            np.float32,
        )
        / 255.0
    )
    ncell = ncx * ncy
    rings = 5
    bounds = np.sort(rng.uniform(0.06, 0.42, (ncell, rings - 1)), axis=1).astype(np.float32)
    colours = rng.integers(0, len(palette), (ncell, rings))
    for i in range(1, rings):  # neighbouring rings differ
        same = colours[:, i] == colours[:, i - 1]
        colours[same, i] = (colours[same, i] + 4) % len(palette)
    cid = cy * ncx + cx
    ring = (r[..., None] > bounds[cid]).sum(axis=-1)
    img = palette[colours[cid, ring]]
    return _texture("painting_circles", _canvas(img, 1.0), repeat=False)


def painting_colorfield(size: int = 512) -> Texture:
    """Two soft-edged glowing rectangles floating on maroon (colour-field painting)."""
    rng = _rng(15)
    aspect = PAINTING_ASPECTS["painting_colorfield"]
    x, y = _coords(size, aspect)
    img = _solid(size, (104, 28, 32)) * (1.0 + 0.05 * _fbm(rng, size, 20.0, 3))[..., None]
    ragged = 0.006 * _fbm(rng, size, 8.0, 2)

    def soft_rect(x0: float, x1: float, y0: float, y1: float) -> np.ndarray:
        d = np.maximum(np.maximum(x0 - x, x - x1), np.maximum(y0 - y, y - y1)) + ragged
        return _smoothstep(0.02, -0.02, d)

    top = soft_rect(0.07, aspect - 0.07, 0.06, 0.50)
    bottom = soft_rect(0.07, aspect - 0.07, 0.58, 0.94)
    glow = 1.0 + 0.08 * _fbm(rng, size, 30.0, 3)
    _paint(img, top, np.clip(_rgb((236, 124, 42)) * glow[..., None], 0, 1))
    _paint(img, bottom, np.clip(_rgb((70, 22, 44)) * glow[..., None], 0, 1))
    return _texture("painting_colorfield", _canvas(img, 1.2), repeat=False)


# -- the set ------------------------------------------------------------------------------------


def checker_quadrants() -> Texture:
    """4x4 test image: top-left red, top-right green, bottom-left blue, bottom-right white."""
    img = np.zeros((4, 4, 4), np.uint8)
    img[:2, :2] = (255, 0, 0, 255)
    img[:2, 2:] = (0, 255, 0, 255)
    img[2:, :2] = (0, 0, 255, 255)
    img[2:, 2:] = (255, 255, 255, 255)
    return Texture("checker_quadrants", img, repeat=False)


def make_textures() -> dict[str, Texture]:
    """Every showroom texture by name (the piano's black lacquer is colour-only)."""
    makers = [
        wallpaper,
        parquet,
        ceiling,
        fabric,
        wood,
        rug,
        painting_abstract,
        painting_landscape,
        painting_stripes,
        painting_circles,
        painting_colorfield,
    ]
    textures = [make() for make in makers]
    textures.append(parquet_relief())  # the floor's normal map (linear data, not a colour)
    return {t.name: t for t in textures}
