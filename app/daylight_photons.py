"""Daylight photons: the sun and the sky shining into a room through its openings.

The photon tracer (``app.photons``) starts these paths beside the lamps' when ``sky.enabled``:

* **The sun** is a parallel beam. Its rays start on the scene's bounding box (a little outside
  the geometry) and travel along ``-sun_direction``; the box's faces turned to the sun are the
  beam's cross-section, each counted by its projected area ``A cos``. A photon's flux is the
  beam's power over its photons, ``E_sun * sum(A cos) / n`` (lux times square metres: lumen, the
  lamps' photons' unit too: a lamp of ``I`` candela emits ``4 pi I`` lumen). Directional lights
  of the scene (``Light.kind == "directional"``, intensity in lux) are beams the same way.
* **The sky** (and the ground outside, below the horizon) lights the box's faces from outside:
  a photon starts at a uniform point of a face and goes in, cosine-weighted about the face's
  inward normal, with flux ``pi A L / n`` for the luminance ``L`` (cd/m2) it came from. The
  box is convex and holds every triangle, so the light reaching it from outside is exactly the
  sky's: nothing is left out.

**Portals.** Most of a room's bounding box is wall and roof, and a photon that starts in front
of a wall is wasted on its outside. So the faces are cut into cells (about 64 along the box's
longest edge) and only the cells that light can cross into the room emit:

* the sky's portal: rays cast from points inside the room (the spawn point and points it sees)
  that escape the geometry mark the cells where they leave the box; more rays aimed from those
  points at the openings found fill them in; the marked cells' neighbours are added;
* a beam's portal: rays from points on the room's surfaces (where the probe rays landed) cast
  towards the sun; those that escape mark where the beam comes in.

A cell is picked in proportion to its area (projected, for a beam), its light and the number
of probe rays that crossed it plus ``CROSSING_FLOOR`` times their mean (``crossing_weight``),
and its photons' flux is divided by the same weight, so the power through the portal stays
exact while the middle of a window gets more photons than its grown border. The windows of a
room are then the portals, found without being named. A sky photon's direction is drawn from
the baked sky in proportion to the light it sends through the cell's face (``SkyTables``).

Until stop 36 the floor was 1 crossing: a border cell that no probe ray crossed sent few
photons, each with up to 1600x the flux of a busy cell's, and the few that found the window
made the photon map's blotches. The effective number of photons (``(sum w)^2 / sum w^2`` over
the stored photons' power, 262k paths) went 3k -> 155k in the white living room, 1.9k -> 157k
in the bathroom, 56k -> 127k in the showroom and 59k -> 207k in the staircase, though fewer
photons go in (on the synthetic room of the tests 28% of the sky's, against 88% before and
one in twenty over the whole box). A closed room has no portal (no daylight photons, said in
the photon map's notes); a scene seen from outside (the spawn outside the box) has every cell.

**First hits.** The renderer draws the sun's direct light itself (a directional light, as the
lamps'), so a sun photon's first hit is not stored, as a lamp's is not. The sky's light through
the windows has no analytic term that knows where the openings are, so a sky photon's first
hit is stored (``STORE_SKY_FIRST_HIT``): the gather then shows the sky's direct light on the
floor by the window and its bounces alike.

**How much light.** The renderer's own sun and sky (``app.sky``: the sun's illuminance and
colour of ``sun_light``, the baked Preetham sky and its ground of ``bake_sky``, or the user's
sky photo), which the Cycles reference gets too: a sky photon carries the radiance of the
baked sky in the direction it came from, so a window turned to the sunny side lets in more
than one turned away. (Until stop 35 the photons had their own figures, the IES clear sky: a
sun 18 % brighter than the one drawn and a uniform sky.)
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

from app.raycast import RayCaster
from app.settings import SkySettings

#: Rec. 709 luminance weights (as app.photons): a colour's luma is its lux / cd/m2 figure.
LUMA = np.array([0.2126, 0.7152, 0.0722])
#: A sky this dim (cd/m2) sends no photons: the baked sky's night floor (app.sky_model
#: NIGHT_LUMINANCE, 0.002 cd/m2 at its bluest 0.003) lights nothing a lamp does not drown.
NIGHT_CD = 0.01
#: Neither sky nor sun photons' first hits are stored: the renderer draws both direct terms.
STORE_SKY_FIRST_HIT = False
#: Portal cells along the bounding box's longest edge.
PORTAL_CELLS = 64
#: Points inside the room that probe for openings, and rays cast from each.
PROBE_POINTS, PROBE_RAYS = 1024, 64
#: Rays aimed from the probe points at the openings the first rays found.
REFINE_RAYS = 1 << 18
#: Surface points (for the beams' portals) sit this fraction of the box diagonal off the surface.
SURFACE_OFFSET = 1e-3
#: A portal cell is picked in proportion to its area, light and (probe crossings + this times
#: their mean): busy cells (the middle of a window) get more photons, the grown border and
#: grazing exits fewer, and each photon's flux is divided by the same weight, so the power
#: stays exact; no photon carries more than (1 + max / (4 mean)) times another's.
CROSSING_FLOOR = 4.0
#: The box around the geometry is this fraction of its diagonal larger on every side.
BOX_MARGIN = 0.01


@dataclass(frozen=True)
class Beam:
    """Parallel light: ``towards`` the source (unit), ``lux`` its RGB normal illuminance."""

    towards: tuple[float, float, float]
    lux: tuple[float, float, float]


@dataclass(frozen=True)
class Daylight:
    """What the daylight photons depend on (hashable: it is part of the photon map's key)."""

    beams: tuple[Beam, ...] = ()  # the sun (and directional lights are added at tracing)
    sky: tuple[float, float, float] = (0.0, 0.0, 0.0)  # sky luminance, cd/m2, linear RGB
    ground: tuple[float, float, float] = (0.0, 0.0, 0.0)  # ground luminance below the horizon
    #: The ``sky.*`` settings whose baked sky (``app.sky.bake_sky``: the renderer's and the
    #: reference's) gives each sky photon the radiance of the direction it came from; None: a
    #: uniform ``sky`` above the horizon and ``ground`` below (``sky`` and ``ground`` are then
    #: also the baked sky's means, for choosing cells).
    sky_key: tuple | None = None

    @property
    def dark(self) -> bool:
        """No sun and a sky no brighter than a moonless night's (``NIGHT_CD``): nothing for
        photons to carry."""
        return not self.beams and max(*self.sky, *self.ground) <= NIGHT_CD


def daylight_for(sky: SkySettings | None) -> Daylight | None:
    """The sun and sky of these settings, None when daylight is off (``sky.enabled``)."""
    if sky is None or not sky.enabled:
        return None
    from app.sky import sky_key  # astral, loaded only with daylight

    return _daylight(sky_key(sky))


@functools.lru_cache(maxsize=64)  # the window asks on every timer tick
def _daylight(key: tuple) -> Daylight:
    """The renderer's sun (``app.sky.sun_light``) and sky (``app.sky.bake_sky``) for the
    settings of ``key`` (``app.sky.sky_key``), which Cycles gets too. The IES clear-sky
    figures used before gave the sun 18 % more light than the renderer's at 10:00 on the
    default date, and a sky as bright to the north as to the south."""
    from app.sky import sky_of_key, sun_light

    beams: tuple[Beam, ...] = ()
    sun = sun_light(sky_of_key(key))
    if sun is not None and sun.intensity > 0.0:
        towards = -np.asarray(sun.direction, np.float64)
        towards = towards / np.linalg.norm(towards)
        beams = (Beam(xyz(towards), xyz(np.asarray(sun.color) * sun.intensity)),)
    image_rgb, dirs, solid = _baked_sky(key)
    up = dirs[..., 1] > 0.0
    cos_up = solid * np.maximum(dirs[..., 1], 0.0)
    sky_l = (image_rgb * cos_up[..., None]).sum(axis=(0, 1)) / math.pi  # E_h / pi
    ground_w = solid * ~up
    ground_l = (image_rgb * ground_w[..., None]).sum(axis=(0, 1)) / max(ground_w.sum(), 1e-12)
    return Daylight(beams, xyz(sky_l), xyz(ground_l), key)


@functools.lru_cache(maxsize=8)
def _baked_sky(key: tuple) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The baked sky of ``Daylight.sky_key``: radiance (H, W, 3), each texel's direction
    (H, W, 3) and solid angle (H, W)."""
    from app.sky import bake_sky, north_east, sky_of_key
    from app.sky_model import equirect_directions

    where = sky_of_key(key)
    image = np.asarray(bake_sky(where).image, np.float64)
    north, east = north_east(where.north_deg)
    dirs, solid = equirect_directions(image.shape[1], image.shape[0], north, east)
    return image, dirs, np.asarray(solid)


def xyz(v) -> tuple[float, float, float]:
    a = np.asarray(v, np.float64).reshape(3)
    return (float(a[0]), float(a[1]), float(a[2]))


# -- portals -----------------------------------------------------------------------------------


@dataclass
class Portal:
    """The bounding box cut into cells, and which of them let daylight in.

    The arrays hold every cell of the box's six faces; ``open`` marks the sky's portal (the
    cells that rays from inside leave through) and :meth:`beam_cells` the cells a parallel beam
    enters the room through. ``surface`` are points on the room's surfaces seen from inside.
    """

    lo: np.ndarray  # (3,) the box
    hi: np.ndarray
    centre: np.ndarray  # (C, 3) cell centre on the box
    half_u: np.ndarray  # (C, 3) half the cell's first edge
    half_v: np.ndarray  # (C, 3) half the cell's second edge
    normal: np.ndarray  # (C, 3) outward unit normal of the cell's face
    area: np.ndarray  # (C,) m2
    open: np.ndarray  # (C,) bool: the sky's portal
    crossings: np.ndarray  # (C,) probe rays that left through each cell (sampling weight)
    surface: np.ndarray  # (S, 3) points just off the room's surfaces, inside
    escaped: float  # fraction of the probe rays that left the geometry
    inside: bool  # the probe point was inside the box (else every cell is open)

    @property
    def cells(self) -> int:
        return int(len(self.area))

    @property
    def total_area(self) -> float:
        return float(self.area[self.open].sum())

    def sample_open(self, rng: np.random.Generator, n: int) -> np.ndarray:
        """``n`` points uniform over the open cells' area, (n, 3); none when none is open."""
        cells = np.flatnonzero(self.open)
        if len(cells) == 0:
            return np.zeros((0, 3))
        cdf = np.cumsum(self.area[cells])
        at = np.searchsorted(cdf, rng.random(n) * cdf[-1], "right")
        pick = cells[np.minimum(at, len(cells) - 1)]
        u, v = (rng.random((n, 1)) * 2.0 - 1.0 for _ in range(2))
        return self.centre[pick] + u * self.half_u[pick] + v * self.half_v[pick]

    def open_density(self, o: np.ndarray, d: np.ndarray) -> np.ndarray:
        """The solid-angle density, at each origin ``o`` (inside the box) and unit direction
        ``d``, of aiming at a point uniform over the open cells (:meth:`sample_open`): where the
        ray leaves the box through an open cell, ``t^2 / (area cos)``; else 0. (N,)"""
        if len(o) == 0:
            return np.zeros(0)
        t, face = _box_exit(o, d, self.lo, self.hi)
        cell = _cell_index(self.lo, self.hi, o + d * t[:, None], face)
        cos = np.abs(d[np.arange(len(d)), face // 2])
        area = self.total_area
        with np.errstate(divide="ignore", invalid="ignore"):
            pdf = t * t / (area * cos)
        return np.where(self.open[cell] & (cos > 1e-9) & np.isfinite(pdf), pdf, 0.0)

    def beam_cells(self, caster: RayCaster, towards: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The cells a beam from ``towards`` enters the room through and how many rays from the
        room's surfaces towards the source left through each (their neighbours: 0)."""
        facing = self.normal @ towards > 1e-6
        if not self.inside:
            cells = np.flatnonzero(facing)
            return cells, np.zeros(len(cells))
        if len(self.surface) == 0:
            return np.zeros(0, np.int64), np.zeros(0)
        d = np.ascontiguousarray(np.broadcast_to(towards, self.surface.shape))
        _, tri = caster.cast_triangles(self.surface, d)
        out = tri < 0
        t, face = _box_exit(self.surface[out], d[out], self.lo, self.hi)
        count = _crossings(self.lo, self.hi, self.surface[out] + d[out] * t[:, None], face)
        cells = np.flatnonzero(_dilate_all(self.lo, self.hi, count) & facing)
        return cells, count[cells]


def scene_box(tri: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """The box around the triangles (T, 3, 3), grown by ``BOX_MARGIN``; None if there are none."""
    pts = np.asarray(tri, np.float64).reshape(-1, 3)
    pts = pts[np.isfinite(pts).all(axis=1)]
    if len(pts) == 0:
        return None
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    margin = BOX_MARGIN * max(float(np.linalg.norm(hi - lo)), 1e-3)
    return lo - margin, hi + margin


def _face_grids(lo: np.ndarray, hi: np.ndarray) -> list[tuple[int, int, int, int, int, int]]:
    """(axis, side, u axis, v axis, cells along u, cells along v) for the six faces."""
    ext = hi - lo
    step = float(ext.max()) / PORTAL_CELLS
    faces = []
    for k in range(3):
        a, b = (k + 1) % 3, (k + 2) % 3
        na = max(1, math.ceil(ext[a] / step - 1e-9))
        nb = max(1, math.ceil(ext[b] / step - 1e-9))
        for side in (-1, 1):
            faces.append((k, side, a, b, na, nb))
    return faces


def _cell_index(lo: np.ndarray, hi: np.ndarray, p: np.ndarray, face: np.ndarray) -> np.ndarray:
    """The cell of each point ``p`` on the box (on faces ``face``, as ``_box_exit`` gives
    them), (N,) int into the cells of every face in ``_face_grids`` order."""
    out = np.zeros(len(p), np.int64)
    at = 0
    for k, side, a, b, na, nb in _face_grids(lo, hi):
        on = face == 2 * k + (side > 0)
        if on.any():
            ia = ((p[on, a] - lo[a]) / (hi[a] - lo[a]) * na).astype(np.int64)
            ib = ((p[on, b] - lo[b]) / (hi[b] - lo[b]) * nb).astype(np.int64)
            out[on] = at + np.clip(ia, 0, na - 1) * nb + np.clip(ib, 0, nb - 1)
        at += na * nb
    return out


def _crossings(lo: np.ndarray, hi: np.ndarray, p: np.ndarray, face: np.ndarray) -> np.ndarray:
    """How many of the points ``p`` (on the box, on faces ``face``) lie in each cell, (C,)."""
    cells = sum(na * nb for *_, na, nb in _face_grids(lo, hi))
    return np.bincount(_cell_index(lo, hi, p, face), minlength=cells).astype(np.float64)


def _dilate_all(lo: np.ndarray, hi: np.ndarray, count: np.ndarray) -> np.ndarray:
    """The cells with a count and their neighbours on the same face, (C,) bool."""
    out, at = [], 0
    for *_, na, nb in _face_grids(lo, hi):
        out.append(_dilate(count[at : at + na * nb].reshape(na, nb) > 0).reshape(-1))
        at += na * nb
    return np.concatenate(out)


def find_portal(
    caster: RayCaster, box: tuple[np.ndarray, np.ndarray], inside: np.ndarray, seed: int
) -> Portal:
    """The box's cells and the sky's portal among them (see the module docstring).

    ``inside`` is a point in the room (the spawn). Deterministic for a seed.
    """
    lo, hi = (np.asarray(b, np.float64) for b in box)
    start = np.asarray(inside, np.float64).reshape(3)
    inside_box = bool(np.isfinite(start).all() and (start > lo).all() and (start < hi).all())
    escaped = 1.0
    surface = np.zeros((0, 3))
    exits, exit_face = np.zeros((0, 3)), np.zeros(0, np.int64)
    if inside_box:
        rng = np.random.default_rng([int(seed) & 0xFFFFFFFF, 0xDA7])
        d0 = _sphere(rng, PROBE_POINTS - 1)
        t0, tri0 = caster.cast_triangles(np.broadcast_to(start, d0.shape), d0)
        frac = rng.uniform(0.5, 0.98, len(d0))  # most near the surfaces, where light lands
        seen = tri0 >= 0  # not out of a window: a point there may be outside
        points = np.concatenate([start[None], start + d0[seen] * (t0 * frac)[seen, None]])
        o = np.repeat(points, PROBE_RAYS, axis=0)
        d = _sphere(rng, len(o))
        t, tri = caster.cast_triangles(o, d)
        hit = tri >= 0
        pull = np.minimum(SURFACE_OFFSET * float(np.linalg.norm(hi - lo)), 0.5 * t[hit])
        surface = o[hit] + d[hit] * (t[hit] - pull)[:, None]
        escaped = float((~hit).mean())
        te, exit_face = _box_exit(o[~hit], d[~hit], lo, hi)
        exits = o[~hit] + d[~hit] * te[:, None]
        if len(exits):
            # Then aim at the openings found: from every probe point towards the exit points
            # (jittered by two cells), so a window's cells are found from every angle.
            o = points[rng.integers(0, len(points), REFINE_RAYS)]
            step = (hi - lo).max() / PORTAL_CELLS
            aim = exits[rng.integers(0, len(exits), REFINE_RAYS)]
            aim = aim + rng.uniform(-2.0, 2.0, (REFINE_RAYS, 3)) * step
            d = aim - o
            d /= np.maximum(np.linalg.norm(d, axis=1, keepdims=True), 1e-12)
            _, tri = caster.cast_triangles(o, d)
            out = tri < 0
            te, face = _box_exit(o[out], d[out], lo, hi)
            exits = np.concatenate([exits, o[out] + d[out] * te[:, None]])
            exit_face = np.concatenate([exit_face, face])
        crossings = _crossings(lo, hi, exits, exit_face)
        is_open = _dilate_all(lo, hi, crossings)
    else:  # seen from outside: the whole box lets light in
        crossings = np.zeros(sum(f[4] * f[5] for f in _face_grids(lo, hi)))
        is_open = np.ones(len(crossings), bool)
    centre, hu, hv, normal, area = [], [], [], [], []
    for k, side, a, b, na, nb in _face_grids(lo, hi):
        ia, ib = (g.reshape(-1) for g in np.meshgrid(np.arange(na), np.arange(nb), indexing="ij"))
        du, dv = (hi[a] - lo[a]) / na, (hi[b] - lo[b]) / nb
        c = np.zeros((len(ia), 3))
        c[:, k] = hi[k] if side > 0 else lo[k]
        c[:, a] = lo[a] + (ia + 0.5) * du
        c[:, b] = lo[b] + (ib + 0.5) * dv
        centre.append(c)
        u = np.zeros((len(ia), 3))
        u[:, a] = 0.5 * du
        hu.append(u)
        v = np.zeros((len(ia), 3))
        v[:, b] = 0.5 * dv
        hv.append(v)
        n = np.zeros((len(ia), 3))
        n[:, k] = side
        normal.append(n)
        area.append(np.full(len(ia), du * dv))
    return Portal(
        lo,
        hi,
        np.concatenate(centre),
        np.concatenate(hu),
        np.concatenate(hv),
        np.concatenate(normal),
        np.concatenate(area),
        is_open,
        crossings,
        surface,
        escaped,
        inside_box,
    )


def _sphere(rng: np.random.Generator, n: int) -> np.ndarray:
    """``n`` uniform unit directions."""
    u = rng.random((n, 2))
    z = 1.0 - 2.0 * u[:, 0]
    r = np.sqrt(np.clip(1.0 - z * z, 0.0, None))
    phi = 2.0 * np.pi * u[:, 1]
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1)


def _box_exit(
    o: np.ndarray, d: np.ndarray, lo: np.ndarray, hi: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Distance to where rays from inside the box leave it, and the face: 2 * axis + (side > 0)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.where(d > 0, (hi - o) / d, np.where(d < 0, (lo - o) / d, np.inf))
    axis = np.argmin(t, axis=1)
    rows = np.arange(len(o))
    side = d[rows, axis] > 0
    return np.maximum(t[rows, axis], 0.0), 2 * axis + side


def _dilate(m: np.ndarray) -> np.ndarray:
    """The marked cells and their eight neighbours."""
    p = np.pad(m, 1)
    out = np.zeros_like(m)
    for i in range(3):
        for j in range(3):
            out |= p[i : i + m.shape[0], j : j + m.shape[1]]
    return out


# -- emission ----------------------------------------------------------------------------------


def crossing_weight(crossings: np.ndarray) -> np.ndarray:
    """A portal cell's sampling weight from the probe rays that crossed it: the crossings plus
    ``CROSSING_FLOOR`` times their mean over the cells (at least 1), so that the heaviest cell
    weighs at most ``1 + max / (CROSSING_FLOOR * mean)`` times the lightest, and a photon
    carries at most that many times another's flux."""
    c = np.asarray(crossings, np.float64)
    mean = float(c.mean()) if c.size else 0.0
    return c + max(CROSSING_FLOOR * mean, 1.0)


#: The box's six face normals, outward, in the order ``face_of`` numbers them.
FACES = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], np.float64)


def face_of(normal: np.ndarray) -> np.ndarray:
    """Index into ``FACES`` of axis-aligned outward normals (M, 3)."""
    n = np.asarray(normal, np.float64).reshape(-1, 3)
    axis = np.argmax(np.abs(n), axis=1)
    return 2 * axis + (n[np.arange(len(n)), axis] < 0.0)


@dataclass
class SkyTables:
    """The baked sky's texels as a distribution per box face: a sky photon entering through a
    face with outward normal n comes from texel t with probability ``luma(L_t) cos_t
    Omega_t / total[f]`` (cos_t = max(0, n . omega_t)), so that each carries the same luma.
    The computed sky spans only about 4.5x over a window's half of the sky, but a user's sky
    photo with the sun in it spans thousands: drawn cosine-weighted, a few photons from near the
    sun would carry most of the light (the tests' sky photo with a band 50x the rest: 4.2x the
    mean flux at the 99.9th percentile, under 3x drawn this way)."""

    cdf: np.ndarray  # (6, T) cumulative luma(L) cos Omega over the texels, per face
    centre_cos: np.ndarray  # (6, T) cos between each face's normal and each texel's centre
    total: np.ndarray  # (6,) lumen per m2 through each face: the last of cdf
    radiance: np.ndarray  # (T, 3)
    shape: tuple[int, int]  # (H, W) of the equirectangular bake
    north: np.ndarray
    east: np.ndarray

    @staticmethod
    @functools.lru_cache(maxsize=4)
    def of(key: tuple) -> SkyTables:
        from app.sky import north_east, sky_of_key

        image, dirs, solid = _baked_sky(key)
        h, w = image.shape[:2]
        radiance = image.reshape(-1, 3)
        cos = np.clip(dirs.reshape(-1, 3) @ FACES.T, 0.0, None).T  # (6, T)
        cdf = np.cumsum(cos * (radiance @ LUMA) * solid.reshape(-1), axis=1)
        north, east = north_east(sky_of_key(key).north_deg)
        return SkyTables(cdf, cos, cdf[:, -1].copy(), radiance, (h, w), north, east)

    def sample(
        self, face: np.ndarray, a: np.ndarray, b: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """Travel directions (M, 3), into the box through faces ``face``, and the RGB each
        carries per lumen / m2 of its face's ``total`` (luma 1 but for the cosine's change
        across a texel), from uniform numbers ``a`` (the texel) and ``b`` (where in it)."""
        h, w = self.shape
        m = len(face)
        texel = np.zeros(m, np.int64)
        for f in np.unique(face):
            sel = face == f
            cdf = self.cdf[f]
            texel[sel] = np.minimum(
                np.searchsorted(cdf, a[sel] * cdf[-1], side="right"), len(cdf) - 1
            )
        row, col = np.divmod(texel, w)
        # Where in the texel, uniformly by solid angle (cos theta uniform between its rows):
        # two numbers from b, its high and low bits.
        jr, whole = np.modf(b * 4096.0)
        jc = whole / 4096.0
        top, bottom = np.cos(row / h * math.pi), np.cos((row + 1) / h * math.pi)
        ct = top + (bottom - top) * jc
        st = np.sqrt(np.clip(1.0 - ct * ct, 0.0, None))
        phi = ((col + jr) / w - 0.5) * 2.0 * math.pi
        omega = st[:, None] * (np.cos(phi)[:, None] * self.north + np.sin(phi)[:, None] * self.east)
        omega[:, 1] += ct
        n = FACES[face]
        # The texel was drawn for its centre's cos; the photon's own corrects it (at most 2x
        # in the texels the face's plane cuts, which are drawn the least).
        here = np.clip(np.einsum("ij,ij->i", omega, n), 0.0, None)
        centre = self.centre_cos[face, texel]
        ratio = np.where(centre > 0.0, here / np.where(centre > 0.0, centre, 1.0), 0.0)
        luma = np.maximum(self.radiance[texel] @ LUMA, 1e-300)
        rgb = self.radiance[texel] / luma[:, None] * ratio[:, None]
        return -omega, rgb


@dataclass
class DaylightSources:
    """The beams and the sky, as photon sources over a portal: one source each, sky last."""

    portal: Portal
    beam_towards: np.ndarray  # (B, 3)
    beam_cdf: list[np.ndarray]  # per beam: cumulative projected area over its portal cells
    beam_cells: list[np.ndarray]  # per beam: the cells it enters through
    beam_q: list[np.ndarray]  # per beam: their sampling weight (crossings + floor)
    beam_lux: np.ndarray  # (B, 3) normal illuminance
    beam_power: np.ndarray  # (B, 3) lumen through the portal
    sky_cells: np.ndarray  # (K,) the sky's portal cells
    sky_q: np.ndarray  # (K,) their sampling weight (crossings + floor)
    sky_cdf: np.ndarray  # (K,) cumulative area * face_w * weight over them
    sky_face_w: np.ndarray  # (K,) luma of the light per m2 entering a cell's face (lumen / m2)
    sky: np.ndarray  # (3,)
    ground: np.ndarray  # (3,)
    power_luma: np.ndarray  # (B + 1,) per source, lumen
    sky_key: tuple | None = None  # Daylight.sky_key
    tables: SkyTables | None = None  # the baked sky's directions, sampled by their light

    @staticmethod
    def build(daylight: Daylight, portal: Portal, caster: RayCaster) -> DaylightSources:
        towards, cdfs, cells, qs, power = [], [], [], [], []
        for beam in daylight.beams:
            s = np.asarray(beam.towards, np.float64)
            s = s / max(float(np.linalg.norm(s)), 1e-300)
            facing, count = portal.beam_cells(caster, s)
            w = portal.area[facing] * (portal.normal[facing] @ s)
            towards.append(s)
            cells.append(facing)
            qs.append(crossing_weight(count))
            cdfs.append(np.cumsum(w * qs[-1]))
            power.append(np.asarray(beam.lux, np.float64) * float(w.sum()))
        sky = np.asarray(daylight.sky, np.float64)
        ground = np.asarray(daylight.ground, np.float64)
        sky_cells = np.flatnonzero(portal.open)
        up = portal.normal[sky_cells, 1]  # +1 top face (photons come from the sky), -1 bottom
        face_l = np.where(
            (up > 0.5)[:, None], sky, np.where((up < -0.5)[:, None], ground, 0.5 * (sky + ground))
        )
        tables = None if daylight.sky_key is None else SkyTables.of(daylight.sky_key)
        if tables is None:
            face_w = np.pi * (face_l @ LUMA)  # a uniform sky and ground: pi L per m2
        else:
            face_w = tables.total[face_of(portal.normal[sky_cells])]
        sky_w = portal.area[sky_cells] * face_w
        sky_q = crossing_weight(portal.crossings[sky_cells])
        sky_cdf = np.cumsum(sky_w * sky_q)
        luma = [float(p @ LUMA) for p in power] + [float(sky_w.sum())]
        return DaylightSources(
            portal,
            np.reshape(towards, (-1, 3)),
            cdfs,
            cells,
            qs,
            np.reshape([beam.lux for beam in daylight.beams], (-1, 3)),
            np.reshape(power, (-1, 3)),
            sky_cells,
            sky_q,
            sky_cdf,
            face_w,
            sky,
            ground,
            np.asarray(luma),
            daylight.sky_key,
            tables,
        )

    @property
    def n_beams(self) -> int:
        return len(self.beam_cells)

    def emit(
        self, src: np.ndarray, per_source: np.ndarray, rng: np.random.Generator
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Origins, directions and flux of new paths; ``src`` indexes this object's sources
        (beams, then the sky), ``per_source`` their photon counts."""
        m = len(src)
        u = rng.random((m, 5))  # cell, point on the cell (2), direction (2)
        o = np.zeros((m, 3))
        d = np.zeros((m, 3))
        flux = np.zeros((m, 3))
        p = self.portal
        for b in range(self.n_beams):
            sel = src == b
            if not sel.any():
                continue
            cdf = self.beam_cdf[b]
            if len(cdf) == 0:
                continue  # the beam finds no way in (its photons: none, see power_luma)
            k = np.searchsorted(cdf, u[sel, 0] * cdf[-1], side="right")
            j = np.minimum(k, len(cdf) - 1)
            cell = self.beam_cells[b][j]
            o[sel] = self._point(cell, u[sel, 1], u[sel, 2])
            d[sel] = -self.beam_towards[b]
            # A cell is picked with pdf A cos q / W, a point on it uniformly: E W / q per photon.
            flux[sel] = self.beam_lux[b] * (cdf[-1] / self.beam_q[b][j])[:, None] / per_source[b]
        sel = src == self.n_beams
        if sel.any():
            from app.photons import _cosine_directions

            k = np.searchsorted(self.sky_cdf, u[sel, 0] * self.sky_cdf[-1], side="right")
            j = np.minimum(k, len(self.sky_cdf) - 1)
            cell = self.sky_cells[j]
            o[sel] = self._point(cell, u[sel, 1], u[sel, 2])
            if self.tables is not None:
                # The baked sky, its directions drawn in proportion to their light on the face:
                # every photon of a cell carries the same luma (no bright few by the sun).
                # pdf of a cell is A_c face_w q_c / total, its light A_c face_w: flux per photon
                # total / q_c, in the texel's colour.
                d[sel], rgb = self.tables.sample(face_of(p.normal[cell]), u[sel, 3], u[sel, 4])
                scale = self.sky_cdf[-1] / self.sky_q[j] / per_source[self.n_beams]
                flux[sel] = rgb * scale[:, None]
            else:  # a uniform sky above the horizon and ground below, cosine-weighted
                d[sel] = _cosine_directions(-p.normal[cell], u[sel, 3], u[sel, 4])
                came_from_sky = d[sel, 1] < 0.0  # going down: it came from above the horizon
                radiance = np.where(came_from_sky[:, None], self.sky, self.ground)
                face = np.maximum(self.sky_face_w[j], 1e-300) * self.sky_q[j]
                # pdf of a cell is A_c face_w q_c / total, of a direction cos / pi: flux per
                # photon pi L total / (face_w q_c).
                flux[sel] = (
                    np.pi * radiance * (self.sky_cdf[-1] / face)[:, None] / per_source[self.n_beams]
                )
        return o, d, flux

    def _point(self, cell: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        p = self.portal
        return (
            p.centre[cell]
            + (2.0 * a - 1.0)[:, None] * p.half_u[cell]
            + (2.0 * b - 1.0)[:, None] * p.half_v[cell]
        )
