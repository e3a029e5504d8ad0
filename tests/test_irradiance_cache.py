"""The irradiance cache (photons.indirect = cache): close to the gather it replaces, darker in
corners than on open floor, rebuilt for new photons, nothing at all from an empty map."""

from __future__ import annotations

import dataclasses

import numpy as np

from app.irradiance_cache import build_cache, cache_for
from app.lab.photon_ref import estimate_radius
from app.photon_map import PhotonMap
from app.photons import trace_photons
from render.offscreen import OffscreenHost
from tests.test_photon_render import box_room, eye_frame, gbuffer_points, photon_settings

W, H = 160, 90


def indirect_of(host: OffscreenHost) -> np.ndarray:
    """The left eye's irradiance E (H, W, 3) of the last frame."""
    with host.ctx:
        return host.renderer.photons.read_indirect(0)[..., :3]


def traced(scene=None, count: int = 1 << 15) -> PhotonMap:
    return trace_photons(scene or box_room(), count, 0)


def test_cache_agrees_with_the_gather_on_the_floor_and_is_darker_in_a_corner():
    photons = traced()
    r = 0.4
    cache = build_cache(photons, r)
    assert cache.points > 0 and np.isfinite(cache.values).all()
    rng = np.random.default_rng(1)
    floor = np.column_stack([rng.uniform(-2.0, 2.0, 64), np.zeros(64), rng.uniform(-2.0, 3.0, 64)])
    up = np.tile([0.0, 1.0, 0.0], (64, 1))
    got = cache.lookup(floor, up)
    want = estimate_radius(photons, floor, up, r)
    assert want.mean() > 0
    rel = np.abs(got - want).mean() / want.mean()
    assert rel < 0.15, rel
    # A floor point in the corner by two walls gets less than the open floor around it.
    corner = cache.lookup(np.array([[-2.95, 0.0, -2.95]]), up[:1])
    assert corner.mean() < 0.8 * got.mean()


def test_empty_and_broken_maps_give_no_indirect_light():
    empty = build_cache(PhotonMap.empty(), 0.3)
    assert empty.points == 0
    assert (empty.lookup(np.zeros((3, 3)), np.tile([0, 1, 0], (3, 1))) == 0).all()
    nan = PhotonMap(np.full((4, 3), np.nan), np.ones((4, 3)), np.zeros(4, np.uint32))
    assert build_cache(nan, 0.3).points == 0
    s = photon_settings(photons__indirect="cache")
    with OffscreenHost(W, H, s) as host:
        host.set_scene(box_room())
        # A trace that stored no photon at all (every light outside the room, say).
        host.photon_cache.ensure = lambda *args, **kw: PhotonMap.empty()  # type: ignore
        img = host.draw(eye_frame(host))
        assert np.isfinite(img).all()
        assert host.renderer.photons.error is None
        ind = indirect_of(host)
        assert (ind[..., :3] == 0).all()


def test_picture_with_the_cache_is_close_to_the_gathers():
    s = photon_settings(photons__indirect="gather")
    with OffscreenHost(W, H, s) as host:
        host.set_scene(box_room())
        fi = eye_frame(host)
        gather = host.draw(fi).astype(np.float64)
        e_gather = indirect_of(host)
        s.photons.indirect = "cache"
        cached = host.draw(fi).astype(np.float64)
        e_cache = indirect_of(host)
        _, _, lit = gbuffer_points(host, 0, fi)
        off = host.renderer.photons
        assert off.cache is not None and off.cache_builds == 1
    lit = np.flipud(lit)
    assert e_gather[lit].mean() > 0
    rel = np.abs(e_cache[lit] - e_gather[lit]).mean() / e_gather[lit].mean()
    assert rel < 0.2, rel
    assert np.abs(cached - gather).mean() < 3.0  # 8-bit levels, both eyes


def test_a_changed_light_rebuilds_the_cache():
    s = photon_settings(photons__indirect="cache")
    room = box_room()
    with OffscreenHost(W, H, s) as host:
        host.set_scene(room)
        fi = eye_frame(host)
        host.draw(fi)
        first = host.renderer.photons.cache
        assert first is not None and host.renderer.photons.cache_builds == 1
        e_first = indirect_of(host).mean()
        light = dataclasses.replace(room.lights[0], intensity=room.lights[0].intensity * 2)
        host.set_scene(dataclasses.replace(room, lights=[light]))
        host.draw(fi)
        p = host.renderer.photons
        assert p.cache is not None and p.cache is not first and p.cache_builds == 2
        assert indirect_of(host).mean() > 1.5 * e_first


def test_the_service_builds_the_cache_with_the_trace():
    s = photon_settings(photons__indirect="cache")
    with OffscreenHost(W, H, s) as host:
        host.set_scene(box_room())
        photons = host.photon_cache.ensure(s.photons, host.scene)
        assert photons is not None
        assert ("irradiance_cache", s.photons.radius_m) in photons.derived
        assert (
            cache_for(photons, s.photons.radius_m)
            is photons.derived[("irradiance_cache", s.photons.radius_m)]
        )


def test_cache_under_coarse_shading_lights_every_block():
    s = photon_settings(photons__indirect="cache", cps__mode="cps")
    with OffscreenHost(W, H, s) as host:
        host.set_scene(box_room())
        fi = eye_frame(host)
        img = host.draw(fi)
        assert not host.renderer.errors, host.renderer.errors
        _, _, lit = gbuffer_points(host, 0, fi)
        e = indirect_of(host)
        s.photons.enabled = "off"
        s.render.ambient_estimate = False  # no bounced light at all (the fixed ambient)
        dark = host.draw(fi)
    assert (e[np.flipud(lit)].sum(axis=-1) > 0).mean() > 0.95  # every surface pixel looked up
    assert img.astype(float).mean() > dark.astype(float).mean() + 1.0  # bounced light added


def _floor_photons(n: int, size: float, power: float, seed: int, y: float = 0.0) -> PhotonMap:
    """``n`` photons spread evenly over a ``size`` x ``size`` m floor at height ``y``, each of
    ``power`` (grey), all arriving from above."""
    rng = np.random.default_rng(seed)
    pos = np.column_stack([rng.uniform(0, size, n), np.full(n, y), rng.uniform(0, size, n)])
    down = np.tile([0.0, -1.0, 0.0], (n, 1))
    from app.photon_map import encode_directions

    return PhotonMap(pos, np.full((n, 3), power), encode_directions(down))


def test_sparse_photons_leave_no_black_holes_in_the_cache():
    """A floor with about 8 photons within the gather radius of any point (a dim hallway): the
    irradiance read anywhere on it is the floor's even light, never 0. Reading only the cells
    that hold photons, about one point in ten read black."""
    size, r = 4.0, 0.3
    n = int(8 / (np.pi * r * r) * size * size)  # 8 photons per disc of radius r
    photons = _floor_photons(n, size, 1.0, seed=3)
    cache = build_cache(photons, r)
    rng = np.random.default_rng(4)
    pts = np.column_stack(
        [rng.uniform(0.5, size - 0.5, 2000), np.zeros(2000), rng.uniform(0.5, size - 0.5, 2000)]
    )
    got = cache.lookup(pts, np.tile([0.0, 1.0, 0.0], (2000, 1)))[:, 1]
    even = n / (size * size)  # E of the floor: its photons' power per m2
    assert (got <= 0.0).mean() < 0.005
    assert abs(got.mean() / even - 1.0) < 0.15
    assert np.percentile(got, 5) > 0.4 * even


def test_a_60_m_hall_gets_the_light_its_cache_holds():
    """A hall 60 m long: 400 cells of 15 cm along it, six grids of which stacked along its
    length overflowed GL's 2048 texels and lost the light (the corridor at a 20 cm radius read
    half its light). They stack along its height: every pixel reads what the cache holds."""
    s = photon_settings(photons__indirect="cache", photons__radius_m=0.3)
    hall = box_room(depth=55.0)
    with OffscreenHost(W, H, s) as host:
        host.set_scene(hall)
        fi = eye_frame(host, pos=(0.0, 1.5, 3.0))
        host.draw(fi)
        assert not host.renderer.errors, host.renderer.errors
        cache = host.renderer.photons.cache.cache
        assert max(cache.dims) * 6 > 2048 and cache.stack_axis == 1
        points, normals, lit = gbuffer_points(host, 0, fi)
        e = np.flipud(indirect_of(host))  # GL row order, as the points
    want = cache.lookup(points[lit], normals[lit])
    got = e[lit]
    assert want.mean() > 0
    assert np.abs(got - want).mean() / want.mean() < 0.02
