"""The ambient term estimated from the light the lamps send round the room.

Setting ``render.ambient_estimate``. One constant ambient (``render.ambient``) is the same in a
dim corridor and a sunlit room. A path tracer's indirect light is the lamps' light bounced off
walls and furniture; this finds it with a small radiosity solution on surface points spread
over the scene by area, and takes its mean over what a person standing in the room sees.

1. **The probe** (once per scene, :class:`AmbientProbe`): 2048-4096 surface points, their
   reflectance (the photon tracer's, ``app.photons``: base colour x texture mean x vertex
   colours x (1 - metallic)) and, for each of their two faces, ``GATHER_RAYS`` cosine-weighted
   rays: the point nearest to what each ray hits on the hit's own surface, and the face of it
   the ray sees, never a face with something lying on it (the wall behind a thin panel, the
   floor under a runner: the ray met the panel, which is lit; taking the covered face lost
   10 % of the bounce light per bounce on the corridor against a path tracer). The share
   of rays that hit anything is the face's closure ``c`` (1 inside a room, 0 on a wall's
   outer face). Then the **standing points**: the faces that look up, are enclosed (``c`` at
   least ``STANDING_CLOSURE``) and have headroom (nothing within ``STANDING_HEADROOM_M``
   above), raised to eye height, plus the scene's spawn; from each, ``VIEW_RAYS`` rays in all
   directions find the faces a person there sees.
2. **The estimate** (per set of lights and sky: 0.07-0.09 s on the showroom and a real
   room, 0.36 s on the corridor's hundred lamps): the direct irradiance ``E_0`` of each
   face (the lamps' shadowed light, the sun's, the sky's through the openings), then
   bounce by bounce ``E_(n+1)(x) = mean over x's rays of rho_h E_n(h)`` (a Lambertian
   face's exitance ``rho E`` seen along cosine-weighted rays is its irradiance
   contribution), ``E_ind = E_1 + E_2 + ...``; the ambient radiance scale the shaders take
   (``u_ambient``: ``albedo * u_ambient`` is the radiance a surface sends back) is the
   reflectance-weighted mean of ``E_ind / pi`` over the faces seen from the standing points:
   the mean that the picture's ambient term then has. The sun's first bounce is found
   exactly where the rays hit (its patch on the floor is small and very bright); a hit is
   never given a face that sees nothing (a wall's outer face in the sun and the open sky,
   across a thin wall from the one the ray met). **The lamps' light past their range**
   (what the renderer's range window leaves undrawn, ``app.scene.range_window``) joins the
   even light of each face it reaches: a path tracer has no range (the corridor's lamps leave
   23 % of their light there). The bounce's colour (:meth:`AmbientProbe._chroma`) takes the
   lamps', the sun's and the sky's colour as well as the surfaces' (warm lamps, a warm room).
3. **By the way a surface faces** (``AmbientEstimate.gradient``): the weighted least-squares
   slope of those faces' ``E_ind / pi`` against their normals, so that the shaders give a floor
   that sees the lamp-lit ceiling more than the ceiling that sees the darker floor
   (``max(u_ambient + u_ambient_gradient . n, 0)``, one dot product a pixel).
4. **What a crease's occluders send back** (``AmbientEstimate.occluder_return``): the
   ambient occlusion hides part of a crease's hemisphere behind a nearby surface, which is
   lit itself; the faces in creases (their rays that end within ``CREASE_M``) reflect
   ``rho (E_0 + E_ind)`` against the ``E_ind`` they hide, and shading.glsl
   ``occluded_share`` gives a crease that much of the hidden part back.

Why not the mean over every face (the split-flux enclosure formula this replaced, which gave
the same mean in a closed grey box): a face hidden by something lying on it (the floor under a
rug, the wall behind a picture, the floor under a sofa) counts as a face of the room there and
receives nothing, so on the furnished showroom that mean was half of what Cycles shows on the
walls, floor and ceiling one sees (docs/reference_flip.md). And the bounce takes the lamps'
whole light: the range window (``app.scene.range_window``) is how far the renderer evaluates
a lamp, not where its light ends (a path tracer has none), so the estimate uses the physical
inverse square (``bounce_falloff``).

The direct irradiance is the renderer's otherwise (the spot cone, the sun's cosine, with
shadows: a point sees a lamp only when the ray caster finds nothing in between). Seeded: the
same scene gives the same value.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.spatial import cKDTree

from app.ambient_field import (
    AXES,
    COVERED_M,
    COVERED_SHARE,
    AmbientField,
    FieldLayout,
    build_field,
    cell_size,
    usable,
)
from app.daylight_photons import scene_box
from app.direct_light import (
    cosine_direction,
    direct,
    direct_rgb,
    sky_irradiance,
    sky_irradiance_rgb,
)
from app.photons import _mesh_optics, _scene_geometry, emitting_side
from app.raycast import RayCaster
from app.scene import Light, Scene
from app.sky_light import lets_light_through, occluders, portal_from, through_portal

LUMA = np.array([0.2126, 0.7152, 0.0722])
# Surface points: SAMPLES_PER_M2 of the scene's surface, within SAMPLE_RANGE. At 2048 the estimate
# moved by a few % between seeds and the picture's FLIP against Cycles by up to 0.006 (spawn
# 0.214-0.220, window 0.225-0.232 over four seeds); 4096 gives 0.212-0.217 and 0.223-0.227,
# the living room 0.203 -> 0.189, for 0.2 s more probing and twice the estimate's time
# (docs/reference_flip.md, stop 31). A room (100 m2 of surface and more: the bathroom's 109,
# the showroom's 271) gets all of them; a small object or a test cube (6 m2) half, its points
# a few centimetres apart already, and it opens without a progress dialog (0.3 s).
SAMPLE_RANGE = (2048, 4096)
SAMPLES_PER_M2 = 40.0
GATHER_RAYS = 16  # cosine-weighted rays per face: its closure and what its bounce light sees
SKY_HIT_RAYS = 8  # cosine-weighted rays from each of their hits: the sky seen there
VIEW_RAYS = 32  # rays in all directions from each standing point
STANDING_POINTS = 64  # at most this many standing points (plus the spawn)
STANDING_CLOSURE = 0.25  # a face one stands on sees the scene on at least this share
STANDING_HEADROOM_M = 1.8  # and has nothing this close above it
EYE_HEIGHT_M = 1.6
NEAREST = 24  # points looked at for the one on a ray's hit surface
#: A ray that ends this close met a nearby surface: what a crease is, for the occluders'
#: return and the field by place. Not the occlusion's reach (render.ao_radius_m, 0.3 m): at
#: 0.3 m here six of nine views were further from Cycles (living room 0.228 against 0.188,
#: docs/reference_flip.md, stop 40).
CREASE_M = 0.75
#: A face deeper in a crease than this (the share of its rays ending within CREASE_M: under a
#: sofa, between a cabinet and the wall) stays out of the field by place: no one sees it, and
#: its little light spread over the cells round it darkened the open surfaces beside it
#: (docs/reference_flip.md, stop 31).
FIELD_CREASE_MAX = 0.8
BOUNCES = 48  # bounces summed; the rest as a geometric tail
CHROMA_BOUNCES = 6  # bounces followed in colour (the colour settles after a few)
SEED = 14
#: A bounce keeps at most this share (a white closed box would otherwise diverge).
MAX_KEPT = 0.95
#: In daylight, a face whose rays leave the model other than through the windows more often
#: than this is outside the rooms, and stays out of the field by place
#: (``AmbientProbe.outside_share``, by ``OUTSIDE_RAYS`` rays a face).
OUTSIDE_SHARE_MAX = 0.2
OUTSIDE_RAYS = 16


@dataclass(frozen=True)
class AmbientEstimate:
    """The estimate and what it is made of (luminance, lux and cd/m2)."""

    ambient: float  # u_ambient: the radiance of a white surface from the even indirect light
    direct_mean_lux: float  # mean direct irradiance over the faces that see the scene
    first_bounce_lux: float  # mean irradiance of the first bounce on the faces seen
    mean_albedo: float  # area-weighted mean reflectance (luminance)
    closure: float  # mean share of the scene a face sees (1: every face inside a room)
    # How the even light changes with the way a surface faces: a surface of normal n gets
    # max(ambient + gradient . (n - mean_normal), 0) (the faces looking up see the lamp-lit
    # ceiling, the ceiling sees the darker floor); zero: the same everywhere.
    gradient: tuple[float, float, float] = (0.0, 0.0, 0.0)
    mean_normal: tuple[float, float, float] = (0.0, 0.0, 0.0)
    # What the surfaces hiding part of a crease's hemisphere send back, relative to the even
    # light they hide: the faces in creases, lit by the lamps and the bounce, reflect
    # rho (E_direct + E_indirect) against E_indirect (shading.glsl occluded_share; -1:
    # unknown, the surface's own albedo stands for it).
    occluder_return: float = -1.0
    # The bounce light by place (render.ambient_by_place, app.ambient_field): each probe
    # face's own value on a grid, the level above where the grid has none; None: no field.
    by_place: AmbientField | None = field(default=None, compare=False, repr=False)

    def along(self, normal: Sequence[float]) -> float:
        """The even light of a surface facing ``normal`` (a unit vector)."""
        n = np.asarray(normal, np.float64) - np.asarray(self.mean_normal, np.float64)
        return max(self.ambient + float(np.asarray(self.gradient, np.float64) @ n), 0.0)

    def base_and_gradient(self) -> tuple[float, tuple[float, float, float]]:
        """``(a, g)`` with the even light ``max(a + g . n, 0)`` for a normal n: what the
        shaders take (``u_ambient``, ``u_ambient_gradient``)."""
        g = np.asarray(self.gradient, np.float64)
        a = self.ambient - float(g @ np.asarray(self.mean_normal, np.float64))
        return a, (float(g[0]), float(g[1]), float(g[2]))


NONE = AmbientEstimate(0.0, 0.0, 0.0, 0.0, 0.0)


def estimate_ambient(
    scene: Scene,
    lights: Sequence[Light] | None = None,
    caster: RayCaster | None = None,
    samples: int | None = None,
    seed: int = SEED,
) -> AmbientEstimate:
    """The even indirect light of ``scene`` under ``lights`` (the scene's own by default).

    An empty scene, one without lights, or one whose every surface is black gives 0 (no light
    comes back), never an error."""
    lights = list(scene.lights if lights is None else lights)
    if not lights:
        return NONE
    return AmbientProbe(scene, caster, samples, seed).estimate(lights)


class AmbientProbe:
    """What the estimate needs of a scene alone, found once: surface points spread by area,
    their reflectance, what each of their faces sees (the bounce's paths) and what a person
    standing in the scene sees. ``estimate`` then casts only the lamps' shadow rays, so a
    moving sun costs a few milliseconds."""

    def __init__(
        self,
        scene: Scene,
        caster: RayCaster | None = None,
        samples: int | None = None,
        seed: int = SEED,
    ) -> None:
        self.points = np.zeros((0, 3))
        self._seed = seed
        self._hit_open: np.ndarray | None = None  # made with daylight's first estimate
        self._box: tuple[np.ndarray, np.ndarray] | None = None
        self._spawn: tuple[float, float, float] = (0.0, 0.0, 0.0)
        self.emitted_rgb = np.zeros((0, 3))  # per face, the glowing surfaces' light (lux, RGB)
        self.mean_albedo = 0.0
        self.clear = np.zeros(0, bool)  # per point: on a surface that lets light through
        self._cell: float | None = None
        # where the open faces fall on the field, lamp-lit (False) and in daylight (True: the
        # faces outside the rooms left out, ``outside_share``)
        self._layouts: dict[bool, FieldLayout] = {}
        self._outside: np.ndarray | None = None  # made with daylight's first field
        self._portal: Any = False  # app.sky_light.Portal or None once found (self.portal)
        # Per face and ray, the probe's own (the same for every estimate): whether the ray met
        # a face, the face standing for its hit (0 on a miss) and what a bounce keeps there,
        # in luminance and in colour (set with the paths below).
        self._hit = np.zeros((0, GATHER_RAYS), bool)
        self._face = np.zeros((0, GATHER_RAYS), np.int64)
        self._gain = np.zeros((0, GATHER_RAYS))
        self._gain_rgb = np.zeros((0, GATHER_RAYS, 3))
        self._record: list[tuple[np.ndarray, np.ndarray]] | None = None
        tris, owner, vnormal = _scene_geometry(scene)
        if tris.shape[0] == 0:
            return
        # Rays meet what hides light in the renderer: glowing panes and glass let it through
        # (app.sky_light.occluders); the given caster serves when nothing is left out.
        blocking = occluders(scene)
        if caster is None or blocking.shape[0] != tris.shape[0]:
            cached = getattr(scene, "ray_caster", None)
            whole = blocking.shape[0] == tris.shape[0] and isinstance(cached, RayCaster)
            caster = cached if whole and isinstance(cached, RayCaster) else RayCaster(blocking)
        self.caster: RayCaster = caster
        # Where daylight comes in (the sky's portal, app.sky_light.portal_from), found when
        # daylight first asks (hit_open).
        self._box, self._spawn = scene_box(blocking), scene.spawn.position
        finite = np.isfinite(tris).all(axis=(1, 2))
        tris, owner, vnormal = tris[finite], owner[finite], vnormal[finite]
        cross = np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0])
        length = np.linalg.norm(cross, axis=1)
        area = 0.5 * length
        if tris.shape[0] == 0 or not np.isfinite(area).all() or area.sum() <= 0.0:
            return
        normal = cross / np.maximum(length, 1e-30)[:, None]
        rho_mesh, emit_mesh = _mesh_optics(scene, [])
        rho_rgb = rho_mesh[owner]
        rho = rho_rgb @ LUMA
        self.mean_albedo = float((rho * area).sum() / area.sum())

        if samples is None:  # by the scene's surface (SAMPLES_PER_M2)
            samples = int(np.clip(SAMPLES_PER_M2 * float(area.sum()), *SAMPLE_RANGE))
        rng = np.random.default_rng(seed)
        pick = rng.choice(len(area), size=samples, p=area / area.sum())
        u, v = rng.random(samples), rng.random(samples)
        su = np.sqrt(u)
        b1, b2 = su * (1.0 - v), su * v
        t = tris[pick]
        self.points = (
            t[:, 0] + b1[:, None] * (t[:, 1] - t[:, 0]) + b2[:, None] * (t[:, 2] - t[:, 0])
        )
        self.normal = normal[pick]
        self.rho = rho[pick]
        # A glowing pane or glass (what the rays pass through, app.sky_light.occluders): its
        # points hold the light arriving at the window, from the blinds centimetres away, not
        # a surface's, so the field by place leaves them out (``_by_place``).
        self.clear = lets_light_through(scene)[owner[pick]]
        self.rho_rgb = rho_rgb[pick]  # the colour the bounce takes (app.ambient_field chroma)
        diag = float(np.linalg.norm(tris.reshape(-1, 3).max(0) - tris.reshape(-1, 3).min(0)))
        self.eps = 1e-4 * max(diag, 1e-3)
        self._tree = cKDTree(self.points)
        hit_tris = caster.tri
        hit_cross = np.cross(hit_tris[:, 1] - hit_tris[:, 0], hit_tris[:, 2] - hit_tris[:, 0])
        self._tri_normal = hit_cross / np.maximum(np.linalg.norm(hit_cross, axis=1), 1e-30)[:, None]
        self._plane_tol = max(5.0 * self.eps, 2e-3)  # a rug's thickness is more
        # Every surface is two-sided (as the renderer draws it): face k of point i is
        # 2 i + k (k = 0 along its normal, 1 against it). Each face's rays: the face they
        # meet (-1: a miss), and the share that meet anything (the closure c).
        n = len(self.points)
        self.paths = np.full((2 * n, GATHER_RAYS), -1, np.int64)
        self.crease = np.zeros(2 * n)  # per face, the share of its rays that end nearby
        self.covered = np.zeros(2 * n, bool)  # per face: something lies on it (a rug)
        # Cast first, then find the faces the rays met: a ray from the room that lands on a
        # surface with something lying on it has met that something, so a covered face never
        # stands for a hit (below), and which faces are covered is known from the casts.
        casts = []
        # Glowing surfaces (a lamp's shade, a lit panel, a ceiling's light strip): the renderer
        # draws them but lights nothing with them; a path tracer's rays that meet one take its
        # light, so each face takes what its rays see of them (pi times their mean radiance),
        # and it bounces as the lamps' light does (``emitted_rgb``).
        glow = _glowing(tris, owner, vnormal, emit_mesh)
        self.emitted_rgb = np.zeros((2 * n, 3))
        for k, side in enumerate((1.0, -1.0)):
            origins = self.points + self.normal * side * self.eps
            rays = []
            for _ in range(GATHER_RAYS):
                d = cosine_direction(self.normal * side, rng.random(n), rng.random(n))
                rays.append((d, *caster.cast_triangles(origins, d)))
                if glow is not None:
                    self.emitted_rgb[k::2] += _glow_seen(glow, origins, d, rays[-1][1])
            dist = np.stack([r[1] for r in rays])
            self.crease[k::2] = np.mean(dist < CREASE_M, axis=0)
            self.covered[k::2] = np.mean(dist < COVERED_M, axis=0) >= COVERED_SHARE
            casts.append((origins, rays))
        self.emitted_rgb *= math.pi / GATHER_RAYS
        # Where each face's rays hit (NaN: a miss) and the hit surface's normal turned to the
        # ray: the sun's first bounce is found there exactly (its patch is small and bright).
        self.hit_at = np.empty((2 * n, GATHER_RAYS, 3), np.float32)
        self.hit_normal = np.empty((2 * n, GATHER_RAYS, 3), np.float32)
        for k, (origins, rays) in enumerate(casts):
            self._record = []
            self.paths[k::2] = np.stack(
                [self._faces_met(origins, d, dist, tri) for d, dist, tri in rays], axis=1
            )
            self.hit_at[k::2] = np.stack([a for a, _ in self._record], axis=1)
            self.hit_normal[k::2] = np.stack([f for _, f in self._record], axis=1)
            self._record = None
        c = (self.paths >= 0).mean(axis=1)
        self.closure = [c[0::2], c[1::2]]
        self.paths = _seen_side(self.paths, c)
        self.seen = _seen_side(self._seen_from_standing_points(scene, c, rng), c)
        self._hit, self._face = self.paths >= 0, np.maximum(self.paths, 0)
        self._gain = np.where(self._hit, self.rho[self._face // 2], 0.0)
        self._gain_rgb = np.where(self._hit[..., None], self.rho_rgb[self._face // 2], 0.0)

    def hit_open(self) -> np.ndarray:
        """:meth:`_open_at_hits`, made once, when daylight first asks (a lamp-lit room does
        not wait for it). Its own random numbers: the probe's other draws stay as they were."""
        if self._hit_open is None:
            rng = np.random.default_rng([self._seed, 0x5C7])
            self._hit_open = self._open_at_hits(self.caster, rng)
        return self._hit_open

    def _open_at_hits(self, caster: RayCaster, rng: np.random.Generator) -> np.ndarray:
        """The share of the sky seen at each ray's hit, on the side turned to the ray (2 n,
        GATHER_RAYS; 0 on a miss), by ``SKY_HIT_RAYS`` cosine rays: the sky's first bounce
        is found there exactly, as the sun's is. The face standing for a hit is the nearest
        probe point on that surface or one like it; in a window's frame and sash bars (a
        hand's width, few points) it was an outer face 10-20 cm away that sees 94 % of the
        sky, and the frame's nooks passed 20,000 lux into the room: the living room's
        daylight bounce was 1.8x a path tracer's.

        Only rays that leave through the room's windows (``through_portal``) count: the
        living room's floor stops 4 cm short of its walls, and a hit on the wall's foot saw
        the ground through the void under the floor with half its rays. Its daylight bounce
        was 1.4x Cycles' (the indirect part: our frame less our direct light against Cycles'
        full less its direct), FLIP 0.233; now 0.208 (the bathroom 0.264 -> 0.253)."""
        portal = self.portal()
        at = self.hit_at.reshape(-1, 3).astype(np.float64)
        facing = self.hit_normal.reshape(-1, 3).astype(np.float64)
        met = np.flatnonzero(np.isfinite(at).all(axis=1))
        out = np.zeros(len(at))
        if len(met):
            o = at[met] + facing[met] * self.eps
            seen = np.zeros(len(met))
            for _ in range(SKY_HIT_RAYS):
                d = cosine_direction(facing[met], rng.random(len(met)), rng.random(len(met)))
                _, tri = caster.cast_triangles(o, d)
                out_of = np.flatnonzero(tri < 0)
                seen[out_of] += through_portal(portal, o[out_of], d[out_of])
            out[met] = seen / SKY_HIT_RAYS
        return out.reshape(self.hit_at.shape[:2])

    def _faces_met(
        self,
        origins: np.ndarray,
        dirs: np.ndarray,
        dist: np.ndarray | None = None,
        tri: np.ndarray | None = None,
    ) -> np.ndarray:
        """The face (2 i + k) that stands for where each ray first meets the scene, -1 on a
        miss (``dist``, ``tri``: the rays' casts, made here when not given). Of the
        ``NEAREST`` points nearest to the hit, the nearest one on the hit's own surface (in
        its plane, facing the same way), so that a hit on a rug does not take the floor
        hidden under it; else the nearest facing the same way, else the nearest. A face with
        something lying on it (``covered``: the wall behind a thin panel, the floor under a
        runner, both in the hit's plane to within the tolerance) is never taken while another
        is near: the ray met what lies on it, which is lit, where the covered face gets next
        to nothing (measured on the corridor: such hits were 14 % of the bounce's paths, and
        the bounce beyond the first 10 % short per step against a path tracer)."""
        if dist is None or tri is None:
            dist, tri = self.caster.cast_triangles(origins, dirs)
        out = np.full(len(origins), -1, np.int64)
        hit = np.isfinite(dist) & (tri >= 0)
        if not hit.any():
            if self._record is not None:
                nothing = np.full((len(origins), 3), np.nan, np.float32)
                self._record.append((nothing, np.zeros((len(origins), 3), np.float32)))
            return out
        at = origins[hit] + dirs[hit] * dist[hit, None]
        k = min(NEAREST, len(self.points))
        _, near = self._tree.query(at, k=k)
        near = np.asarray(near, np.int64).reshape(len(at), k)
        n_hit = self._tri_normal[tri[hit]]
        n_near = self.normal[near]  # (H, k, 3)
        same_way = np.abs(np.einsum("hkj,hj->hk", n_near, n_hit)) > 0.9
        offset = np.abs(np.einsum("hkj,hkj->hk", at[:, None, :] - self.points[near], n_near))
        back_k = np.einsum("hkj,hj->hk", n_near, dirs[hit]) > 0.0  # each sees its back
        open_k = ~self.covered[2 * near + back_k]
        on_it = same_way & (offset < self._plane_tol)
        first = np.zeros(len(at), np.int64)  # the nearest, unless one of these is near
        for wanted in (on_it, open_k, same_way & open_k, on_it & open_k):  # the last wins
            first = np.where(wanted.any(axis=1), wanted.argmax(axis=1), first)
        rows = np.arange(len(at))
        i = near[rows, first]
        out[hit] = 2 * i + back_k[rows, first]
        if self._record is not None:  # where the rays hit, the face turned to them
            at_all = np.full((len(origins), 3), np.nan, np.float32)
            n_all = np.zeros((len(origins), 3), np.float32)
            at_all[hit] = at
            turn = np.where(np.einsum("ij,ij->i", n_hit, dirs[hit]) > 0.0, -1.0, 1.0)
            n_all[hit] = n_hit * turn[:, None]
            self._record.append((at_all, n_all))
        return out

    def _seen_from_standing_points(
        self, scene: Scene, closure: np.ndarray, rng: np.random.Generator
    ) -> np.ndarray:
        """The faces met by rays in all directions from eye height above the faces one could
        stand on (looking up, enclosed, with headroom) and from the spawn."""
        up = np.array([0.0, 1.0, 0.0])
        faces = np.arange(2 * len(self.points))
        facing = self.normal[faces // 2] * np.where(faces % 2 == 0, 1.0, -1.0)[:, None]
        floor = faces[(facing @ up > 0.7) & (closure >= STANDING_CLOSURE)]
        if floor.size:
            base = self.points[floor // 2] + up * self.eps
            room, _ = self.caster.cast_many(base, np.broadcast_to(up, base.shape))
            floor = floor[room >= STANDING_HEADROOM_M]
        if floor.size > STANDING_POINTS:
            floor = rng.choice(floor, STANDING_POINTS, replace=False)
        eyes = [self.points[floor // 2] + up * EYE_HEIGHT_M]
        spawn = np.asarray(scene.spawn.position, np.float64).reshape(1, 3)
        if np.isfinite(spawn).all():
            eyes.append(spawn)
        eye = np.concatenate(eyes)
        origins = np.repeat(eye, VIEW_RAYS, axis=0)
        z = rng.uniform(-1.0, 1.0, len(origins))
        phi = rng.uniform(0.0, 2.0 * math.pi, len(origins))
        r = np.sqrt(np.maximum(1.0 - z * z, 0.0))
        dirs = np.stack([r * np.cos(phi), z, r * np.sin(phi)], axis=1)
        met = self._faces_met(origins, dirs)
        return met[met >= 0]

    def estimate(
        self,
        lights: Sequence[Light],
        sky_sh: np.ndarray | None = None,
        beside_photons: bool = False,
    ) -> AmbientEstimate:
        """The estimate under ``lights``: each face takes the lamps' light from its own side,
        the bounces go along the probe's paths, and the indirect light is averaged over the
        faces seen from the standing points, weighted by their reflectance.

        ``sky_sh``: the sky's light (``app.sky.SkyBake.sh``, light leaving a white surface per
        normal, cd/m2) with daylight on; a face then also takes pi SH(n) times the share of
        its rays that leave the scene (1 - c), and that light bounces as the lamps' does.

        ``beside_photons``: the even light beside a photon map, which carries the bounces of
        the drawn lamps', the sun's and the sky's light: only what it leaves out, the lamps'
        light past their range and the glowing surfaces' light, and their bounces."""
        if beside_photons:
            lights = [lt for lt in lights if lt.kind != "directional"]
            sky_sh = None
        # With daylight on, a glowing pane stands for the sky beyond it, whose light through
        # the openings is counted instead (and a lamp's glow is small beside daylight).
        glowing = len(self.points) > 0 and bool(self.emitted_rgb.any()) and sky_sh is None
        if not len(self.points) or (not lights and sky_sh is None and not glowing):
            return AmbientEstimate(0.0, 0.0, 0.0, self.mean_albedo, 0.0)
        n = len(self.points)
        suns = [lt for lt in lights if lt.kind == "directional"]
        lamps = [lt for lt in lights if lt.kind != "directional"]
        e0 = np.zeros(2 * n)
        e0_rgb = np.zeros((2 * n, 3))  # the same light in colour: what the bounce's colour takes
        e0_suns = np.zeros(2 * n)
        # The lamps' light past their range, which the renderer does not draw (its range
        # window, app.scene.range_window): the even light carries it (a path tracer has no
        # range; the corridor's lamps leave 23 % of their light there).
        beyond_rgb = np.zeros((2 * n, 3))
        lamps_only, lamps_only_rgb = np.zeros(2 * n), np.zeros((2 * n, 3))  # e0 but the sky's
        for k, (side, c) in enumerate(zip((1.0, -1.0), self.closure, strict=True)):
            drawn = np.zeros((n, 3))
            rgb = direct_rgb(
                self.points, self.normal * side, lamps, self.caster, self.eps, True, drawn
            )
            beyond_rgb[k::2] = np.maximum(rgb - drawn, 0.0)
            if beside_photons:  # the photon map carries the drawn light's bounces
                rgb = beyond_rgb[k::2].copy()
            e = rgb @ LUMA
            lamps_only[k::2], lamps_only_rgb[k::2] = e, rgb
            if sky_sh is not None:
                open_share = (1.0 - c)[:, None]
                rgb = rgb + sky_irradiance_rgb(self.normal * side, sky_sh) * open_share
                e = e + sky_irradiance(self.normal * side, sky_sh) * (1.0 - c)
            e0[k::2], e0_rgb[k::2] = e, rgb
            if suns:
                e0_suns[k::2] = direct(self.points, self.normal * side, suns, self.caster, self.eps)
        if glowing:  # the glowing surfaces' light: not drawn, so the even light carries it
            e0, e0_rgb = e0 + self.emitted_rgb @ LUMA, e0_rgb + self.emitted_rgb
            beyond_rgb = beyond_rgb + self.emitted_rgb
        c = np.concatenate([self.closure[0][:, None], self.closure[1][:, None]], 1).ravel()
        seen = c.sum()
        if seen <= 0.0:  # nothing sees anything: an open sheet, no light comes back
            return AmbientEstimate(0.0, 0.0, 0.0, self.mean_albedo, 0.0)
        hit, face, gain = self._hit, self._face, self._gain  # what a bounce keeps on each path
        # The first bounce: the lamps' and the sky's light where the rays hit, from the face
        # standing for each hit; the sun's exactly at the hit (a sharp patch on the floor).
        sun_hits: np.ndarray = np.zeros((*gain.shape, 3))
        if suns:
            at, facing = self.hit_at.reshape(-1, 3), self.hit_normal.reshape(-1, 3)
            met = hit.ravel()
            lit = np.zeros((len(at), 3))
            lit[met] = direct_rgb(
                at[met].astype(np.float64),
                facing[met].astype(np.float64),
                suns,
                self.caster,
                self.eps,
            )
            sun_hits = lit.reshape((*gain.shape, 3))
        at_hits_rgb = sun_hits
        if sky_sh is not None:  # the sky's light at the hits themselves (_open_at_hits)
            facing = self.hit_normal.reshape(-1, 3).astype(np.float64)
            sky_rgb = sky_irradiance_rgb(np.nan_to_num(facing), sky_sh)
            at_hits_rgb = at_hits_rgb + (sky_rgb * self.hit_open().reshape(-1, 1)).reshape(
                sun_hits.shape
            )
        # The faces' own light at the hits (the lamps', and the glowing surfaces' without
        # daylight), the sky's and the sun's at the hits themselves.
        own, own_rgb = (e0, e0_rgb) if sky_sh is None else (lamps_only, lamps_only_rgb)
        arriving_rgb = own_rgb[face] + at_hits_rgb
        arriving = own[face] + at_hits_rgb @ LUMA
        first = np.einsum("fr,fr->f", gain, arriving) / GATHER_RAYS
        chroma = self._chroma(arriving_rgb)
        e0 = e0 + e0_suns
        total = first.copy()
        e = first
        kept = float(first.sum()) / float(e0.sum()) if e0.sum() > 0.0 else 0.0
        for _ in range(BOUNCES - 1):
            if kept <= 0.0:
                break
            nxt = np.einsum("fr,fr->f", gain, e[face]) / GATHER_RAYS  # no (2 n, rays) product
            before, e = float(e.sum()), nxt
            total += e
            kept = float(e.sum()) / before if before > 0.0 else 0.0
        if kept > 0.0:  # the bounces left: a geometric tail
            kept = min(kept, MAX_KEPT)
            total += e * kept / (1.0 - kept)
        beyond = beyond_rgb @ LUMA
        if beyond.any():  # the even light's colour: the bounce's and the lamps' beyond
            lit = total + beyond
            mixed = chroma * total[:, None] + beyond_rgb
            chroma = np.where(
                lit[:, None] > 1e-12, mixed / np.maximum(mixed @ LUMA, 1e-12)[:, None], chroma
            )
            total = lit
        view = self.seen if len(self.seen) else np.flatnonzero(c > 0.0)
        rho_v = self.rho[view // 2]
        weight = float(rho_v.sum())
        if weight <= 0.0:  # every face one sees is black: its ambient term is black anyway
            rho_v = np.ones(len(view))
            weight = float(len(view))
        if weight <= 0.0:
            return AmbientEstimate(0.0, float((e0 * c).sum()) / seen, 0.0, self.mean_albedo, 0.0)
        value = total[view] / math.pi
        indirect = float((rho_v * value).sum()) / weight
        bounce1 = float((rho_v * first[view]).sum()) / weight
        facing = self.normal[view // 2] * np.where(view % 2 == 0, 1.0, -1.0)[:, None]
        mean_n = (rho_v[:, None] * facing).sum(axis=0) / weight
        gradient = _gradient(facing - mean_n, value - indirect, rho_v)
        return AmbientEstimate(
            indirect,
            float((e0 * c).sum()) / seen,
            bounce1,
            self.mean_albedo,
            seen / (2.0 * n),
            gradient,
            (float(mean_n[0]), float(mean_n[1]), float(mean_n[2])),
            _occluder_return(self.crease, self.rho[np.arange(2 * n) // 2], e0 - beyond, total, c),
            self._by_place(
                total,
                c,
                indirect + (AXES - mean_n) @ np.asarray(gradient),
                chroma,
                daylight=sky_sh is not None,
            ),
        )

    def _chroma(self, arriving: np.ndarray) -> np.ndarray:
        """Each face's bounce light's colour (2 n, 3), its luminance 1: the first
        ``CHROMA_BOUNCES`` bounces in colour from the light ``arriving`` along each ray
        (2 n, rays, 3: the lamps', the sun's and the sky's own colour), the surfaces'
        reflectance taking theirs (a wooden floor warms the ceiling, warm lamps the room)."""
        gain, face = self._gain_rgb, self._face  # (2 n, rays, 3), (2 n, rays)
        e = np.einsum("frc,frc->fc", gain, arriving) / GATHER_RAYS
        total = e.copy()
        for _ in range(CHROMA_BOUNCES - 1):
            e = np.einsum("frc,frc->fc", gain, e[face]) / GATHER_RAYS
            total += e
        lum = total @ LUMA
        grey = np.ones(3)
        return np.where(lum[:, None] > 1e-12, total / np.maximum(lum, 1e-12)[:, None], grey)

    def _by_place(
        self,
        total: np.ndarray,
        closure: np.ndarray,
        levels: np.ndarray,
        chroma: np.ndarray,
        daylight: bool = False,
    ) -> AmbientField | None:
        """The faces' own bounce light on a grid (app.ambient_field): those that see the
        scene, have nothing lying on them and are not deep in a crease
        (``FIELD_CREASE_MAX``); in daylight, not those outside the rooms
        (``OUTSIDE_SHARE_MAX``)."""
        open_faces = (closure > 0.0) & ~self.covered & (self.crease <= FIELD_CREASE_MAX)
        open_faces &= ~np.repeat(self.clear, 2)
        if daylight:
            open_faces &= self.outside_share() <= OUTSIDE_SHARE_MAX
        faces = np.flatnonzero(open_faces)
        if not len(faces):
            return None
        facing = self.normal[faces // 2] * np.where(faces % 2 == 0, 1.0, -1.0)[:, None]
        at = self.points[faces // 2]
        if self._cell is None:  # the same grid for every set of lights
            self._cell = cell_size(self.points)
        if daylight not in self._layouts:  # the open faces do not change with the lights
            placed = usable(at, facing)
            if placed.any():
                self._layouts[daylight] = FieldLayout.of(at[placed], facing[placed], self._cell)
        level = np.maximum(levels, 0.0)  # AmbientEstimate.along the six axes
        return build_field(
            at,
            facing,
            total[faces] / math.pi,
            level,
            self._cell,
            chroma[faces],
            self._layouts.get(daylight),
        )

    def portal(self):
        """Where daylight comes in (``app.sky_light.portal_from``), found once."""
        if self._portal is False:
            self._portal = portal_from(self.caster, self._box, self._spawn, self._seed)
        return self._portal

    def outside_share(self) -> np.ndarray:
        """Per face (2 n), the share of its cosine rays that leave the model other than
        through the room's windows (``through_portal``), by ``OUTSIDE_RAYS`` rays, made once.

        A face outside the rooms (a floor slab running on past the outer wall, a wall's outer
        side) sees the open sky; by the portal's test an inner face sees it only through the
        windows. The bathroom's slab runs 14 cm past its outer wall: those faces, in the
        sun, bounced 3000-6500 cd/m2, and the field's tent (2 cells of 25 cm) carried it
        through the wall onto the floor inside: the even light by place there was 2x a
        path tracer's (ours), and the daylit bathroom further from Cycles with it than with
        one level (FLIP 0.253 against 0.230)."""
        if self._outside is None:
            rng = np.random.default_rng([self._seed, 0x0D7])
            portal = self.portal()
            n = len(self.points)
            out = np.zeros(2 * n)
            for k, side in enumerate((1.0, -1.0)):
                facing = self.normal * side
                o = self.points + facing * self.eps
                for _ in range(OUTSIDE_RAYS):
                    d = cosine_direction(facing, rng.random(n), rng.random(n))
                    _, tri = self.caster.cast_triangles(o, d)
                    left = np.flatnonzero(tri < 0)
                    out[k + 2 * left] += ~through_portal(portal, o[left], d[left])
            self._outside = out / OUTSIDE_RAYS
        return self._outside


def _seen_side(faces: np.ndarray, closure: np.ndarray) -> np.ndarray:
    """``faces`` with a face that sees nothing (closure 0: a wall's outer face, in the sun
    and the open sky) replaced by the other face of its point: a ray from inside the scene
    cannot have met it (the point standing for the hit lay across a thin wall); -1 where
    neither side sees anything."""
    out = faces.copy()
    met = out >= 0
    blind = np.zeros(out.shape, bool)
    blind[met] = closure[out[met]] <= 0.0
    other = np.where(blind, out ^ 1, out)
    out[blind] = np.where(closure[other[blind]] > 0.0, other[blind], -1)
    return out


def _occluder_return(
    crease: np.ndarray, rho: np.ndarray, direct: np.ndarray, indirect: np.ndarray, c: np.ndarray
) -> float:
    """What the surfaces that hide a crease's light send back against the even light they
    hide: the mean exitance ``rho (E_direct + E_indirect)`` of the faces in creases (each by
    the share of its rays that end within ``CREASE_M``: the faces that hide one another) over
    their mean indirect irradiance; -1 where no face is in a crease."""
    w = crease * (c > 0.0)
    hidden = float((w * indirect).sum())
    if hidden <= 0.0:
        return -1.0
    return float((w * rho * (direct + indirect)).sum()) / hidden


def _gradient(dn: np.ndarray, dv: np.ndarray, w: np.ndarray) -> tuple[float, float, float]:
    """The weighted least-squares slope g of ``dv ~ g . dn`` (both centred), (0, 0, 0) where
    the faces seen do not face enough ways to tell."""
    a = (w[:, None, None] * dn[:, :, None] * dn[:, None, :]).sum(axis=0)
    b = (w[:, None] * dn * dv[:, None]).sum(axis=0)
    if not np.isfinite(a).all() or not np.isfinite(b).all():
        return (0.0, 0.0, 0.0)
    try:
        # a little ridge: a direction the faces hardly vary in gets no slope
        g = np.linalg.solve(a + np.eye(3) * (1e-3 * max(float(np.trace(a)), 1e-12)), b)
    except np.linalg.LinAlgError:
        return (0.0, 0.0, 0.0)
    return (float(g[0]), float(g[1]), float(g[2]))


@dataclass(frozen=True)
class _Glow:
    """The glowing triangles, each one's radiance (linear RGB, cd/m2 per unit colour) and the
    side it glows from: +1 / -1 along its plane's normal, 0 both (the photon tracer's rule,
    ``app.photons``: the side its vertex normals point to, so the ceiling behind a downlight
    set a few millimetres below it is not lit by the light's back)."""

    caster: RayCaster
    radiance: np.ndarray  # (T, 3), aligned with caster.tri
    normal: np.ndarray  # (T, 3) the plane's unit normal
    front: np.ndarray  # (T,) +1, -1 or 0


def _glowing(
    tris: np.ndarray, owner: np.ndarray, vnormal: np.ndarray, emit_mesh: np.ndarray
) -> _Glow | None:
    """The scene's glowing triangles (of meshes whose material emits), None when none does."""
    if not len(tris) or not len(emit_mesh):
        return None
    glows = (emit_mesh[np.clip(owner, 0, len(emit_mesh) - 1)] > 0.0).any(axis=1)
    glows &= np.isfinite(tris).all(axis=(1, 2))
    if not glows.any():
        return None
    tri, mesh = tris[glows], owner[glows]
    cross = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    normal = cross / np.maximum(np.linalg.norm(cross, axis=1), 1e-30)[:, None]
    front = emitting_side(vnormal[glows], normal)
    caster = RayCaster(tri, np.arange(len(tri)))
    if len(caster.tri) == 0:
        return None
    kept = caster.owner  # the input triangles the caster kept, in its order
    return _Glow(caster, emit_mesh[mesh[kept]], normal[kept], front[kept])


def _glow_seen(glow: _Glow, origins: np.ndarray, dirs: np.ndarray, blocked: np.ndarray):
    """The glowing surfaces' radiance along each ray (N, 3): where a ray meets the glowing
    side of one before anything that hides light (``blocked``: the distance to that, inf on
    a miss)."""
    dist, tri = glow.caster.cast_triangles(origins, dirs)
    seen = np.isfinite(dist) & (tri >= 0) & (dist < blocked)
    t = np.maximum(tri, 0)
    facing = np.einsum("ij,ij->i", glow.normal[t], dirs) * glow.front[t]  # < 0: its glow side
    seen &= (glow.front[t] == 0) | (facing < 0.0)
    return np.where(seen[:, None], glow.radiance[t], 0.0)


def probe_for(scene: Scene, caster: RayCaster | None = None) -> AmbientProbe:
    """``scene``'s probe, found once and kept on it (``Scene.ambient_probe``): the window's
    loader finds it on its worker thread (0.5 s for the showroom, 1.8 s for a 380k-triangle
    room), the renderer then only reads it."""
    probe = scene.ambient_probe
    if not isinstance(probe, AmbientProbe):
        probe = AmbientProbe(scene, caster)
        scene.ambient_probe = probe
    return probe
