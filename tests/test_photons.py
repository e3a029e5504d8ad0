"""Photon tracing: determinism, energy bookkeeping, where photons land, bad input.

The energy tests use a closed box whose expected stored flux is known in closed form (up to a
Monte Carlo estimate of the first-hit flux from the box's geometry, independent of the tracer).
"""

from __future__ import annotations

import numpy as np
import pytest

from app import scenes
from app.photon_map import PhotonMap
from app.photons import (
    TracingCancelled,
    _allocate,
    _mesh_optics,
    scene_scale,
    trace_photons,
)
from app.raycast import RayCaster
from app.scene import Material, Mesh, PointLight, Scene, Texture, lamp_falloff

HALF = np.array([2.0, 1.5, 2.5])  # the box is [-HALF, HALF]


def _quad(name: str, corners: np.ndarray, normal: np.ndarray, material: int) -> Mesh:
    """Two triangles over four corners (in order round the quad), wound to face ``normal``."""
    idx = np.array([[0, 1, 2], [0, 2, 3]], np.uint32)
    c = np.asarray(corners, np.float32)
    if np.cross(c[1] - c[0], c[2] - c[0]) @ normal < 0:
        idx = idx[:, ::-1].copy()
    return Mesh(
        name,
        c,
        np.tile(np.asarray(normal, np.float32), (4, 1)),
        np.zeros((4, 2), np.float32),
        idx,
        material,
    )


def _box_walls(material: int = 0) -> list[Mesh]:
    """Six quads of the box, facing inwards."""
    meshes = []
    for axis in range(3):
        u, v = [a for a in range(3) if a != axis]
        for sign in (-1.0, 1.0):
            corners = np.zeros((4, 3))
            corners[:, axis] = sign * HALF[axis]
            for k, (a, b) in enumerate([(-1, -1), (1, -1), (1, 1), (-1, 1)]):
                corners[k, u], corners[k, v] = a * HALF[u], b * HALF[v]
            normal = np.zeros(3)
            normal[axis] = -sign
            meshes.append(_quad(f"wall{axis}{int(sign)}", corners, normal, material))
    return meshes


def _box(
    albedo: float,
    lights: list[PointLight],
    extra: list[Mesh] | None = None,
    materials: list[Material] | None = None,
) -> Scene:
    mats = [Material("wall", (albedo, albedo, albedo, 1.0))] + (materials or [])
    return Scene("box", _box_walls() + (extra or []), mats, lights=lights)


def _centre_light(intensity: float = 5.0) -> PointLight:
    return PointLight((0.0, 0.0, 0.0), (1.0, 0.8, 0.6), intensity, 1e4)


def _first_hit_flux(light: PointLight, n: int = 400_000) -> np.ndarray:
    """Expected first-hit flux from a point light at the box centre (Monte Carlo, no tracer)."""
    rng = np.random.default_rng(12345)
    d = rng.normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    dist = np.min(HALF / np.abs(d), axis=1)  # exit distance from the centre through the slabs
    d2 = dist**2
    factor = lamp_falloff(d2, light.range_m) * d2  # the window and the 10 cm floor
    return 4 * np.pi * light.intensity * np.asarray(light.color) * factor.mean()


def _wall_normals(positions: np.ndarray) -> np.ndarray:
    """Inward normal of the wall each position lies on (the nearest face of the box)."""
    gap = HALF - np.abs(positions)
    axis = np.argmin(gap, axis=1)
    n = np.zeros_like(positions)
    n[np.arange(len(positions)), axis] = -np.sign(positions[np.arange(len(positions)), axis])
    return n


def test_same_seed_same_bytes_other_seed_differs() -> None:
    scene = _box(0.5, [_centre_light()])
    a = trace_photons(scene, 4096, seed=7)
    b = trace_photons(scene, 4096, seed=7)
    c = trace_photons(scene, 4096, seed=8)
    assert len(a) > 0 and a.emitted == 4096 and a.seed == 7
    for field in ("positions", "power", "direction_bits"):
        assert getattr(a, field).tobytes() == getattr(b, field).tobytes()
    assert a.positions.tobytes() != c.positions.tobytes()


def test_black_box_point_light_stores_nothing() -> None:
    # The first hit is the renderer's analytic direct light; black walls reflect nothing more.
    pm = trace_photons(_box(0.0, [_centre_light()]), 4096)
    assert len(pm) == 0


def test_grey_box_energy_and_placement() -> None:
    light = _centre_light()
    bounces = 8
    pm = trace_photons(_box(0.5, [light]), 2**15, seed=3, max_bounces=bounces)
    # rho = 0.5: roulette keeps half the paths at unchanged flux, so bounce k stores F1 0.5^k.
    expected = _first_hit_flux(light) * sum(0.5**k for k in range(1, bounces + 1))
    np.testing.assert_allclose(pm.power.sum(axis=0, dtype=np.float64), expected, rtol=0.04)
    # Every photon lies on a wall, and travelled into it.
    gap = np.min(HALF - np.abs(pm.positions), axis=1)
    assert np.all(np.abs(gap) < 1e-4)
    assert np.all(np.abs(pm.positions) <= HALF + 1e-4)
    cos = np.einsum("ij,ij->i", pm.directions, _wall_normals(pm.positions.astype(np.float64)))
    assert np.all(cos < 0.0)
    assert np.all(pm.power > 0) and np.isfinite(pm.power).all()


def test_range_window_limits_first_hits() -> None:
    # A light whose range ends inside the box lights only walls within that range; no hit
    # beyond it seeds a photon, and the flux shrinks by the renderer's window.
    light = PointLight((0.0, 0.0, 0.0), (1.0, 1.0, 1.0), 5.0, 2.2)
    pm = trace_photons(_box(0.5, [light]), 2**14, seed=1, max_bounces=1)
    expected = _first_hit_flux(light) * 0.5
    np.testing.assert_allclose(pm.power.sum(axis=0, dtype=np.float64), expected, rtol=0.05)


def test_emissive_panel_in_black_box() -> None:
    # A 1 m x 0.5 m panel under the ceiling facing down, in a black box: every photon is stored at
    # its first hit (area-light paths have no analytic direct part) and nothing bounces.
    y = HALF[1] - 0.1
    corners = np.array([[-0.5, y, -0.25], [0.5, y, -0.25], [0.5, y, 0.25], [-0.5, y, 0.25]])
    le = np.array([2.0, 1.5, 1.0])
    panel = _quad("panel", corners, np.array([0.0, -1.0, 0.0]), 1)
    scene = _box(0.0, [], [panel], [Material("panel", (0, 0, 0, 1), emissive=tuple(le))])
    n = 2**14
    pm = trace_photons(scene, n, seed=2)
    assert len(pm) >= n * 0.999  # all but a rare leak through an edge
    np.testing.assert_allclose(pm.power.sum(axis=0, dtype=np.float64), np.pi * le * 0.5, rtol=2e-3)
    # It emits from its front face only (down), so nothing reaches the ceiling above it.
    assert np.all(pm.positions[:, 1] < y)
    cos = np.einsum("ij,ij->i", pm.directions, _wall_normals(pm.positions.astype(np.float64)))
    assert np.all(cos < 0.0)


def test_emitter_without_normals_emits_both_ways() -> None:
    y = 0.0
    corners = np.array([[-0.5, y, -0.25], [0.5, y, -0.25], [0.5, y, 0.25], [-0.5, y, 0.25]])
    panel = _quad("panel", corners, np.array([0.0, -1.0, 0.0]), 1)
    panel.normals = np.tile(np.float32([1.0, 0.0, 0.0]), (4, 1))  # says nothing about the face
    scene = _box(0.0, [], [panel], [Material("panel", (0, 0, 0, 1), emissive=(1.0, 1.0, 1.0))])
    pm = trace_photons(scene, 4096, seed=2)
    up = (pm.positions[:, 1] > 0).mean()
    assert 0.4 < up < 0.6
    np.testing.assert_allclose(pm.power.sum(axis=0, dtype=np.float64), np.pi * 0.5, rtol=5e-3)


def test_photons_shared_by_power() -> None:
    assert list(_allocate(np.array([3.0, 1.0]), 4096)) == [3072, 1024]
    shares = _allocate(np.array([1.0, 1.0, 1.0]), 1000)
    assert shares.sum() == 1000 and shares.max() - shares.min() <= 1
    assert list(_allocate(np.array([1.0, 5.0]), 1)) == [0, 1]
    # Two lights at the centre: each carries its own power whatever its share of photons.
    bright = PointLight((0.0, 0.0, 0.0), (1.0, 0.5, 0.2), 30.0, 1e4)
    dim = PointLight((0.0, 0.0, 0.0), (0.2, 0.5, 1.0), 10.0, 1e4)
    pm = trace_photons(_box(0.5, [bright, dim]), 2**14, seed=5, max_bounces=1)
    expected = 0.5 * (_first_hit_flux(bright) + _first_hit_flux(dim))
    np.testing.assert_allclose(pm.power.sum(axis=0, dtype=np.float64), expected, rtol=0.04)


def test_zero_one_photons_no_lights_no_geometry() -> None:
    scene = _box(0.5, [_centre_light()])
    for count in (0, 1):
        pm = trace_photons(scene, count)
        assert isinstance(pm, PhotonMap) and len(pm) <= count * 9
        assert np.isfinite(pm.positions).all() and np.isfinite(pm.power).all()
    dark = trace_photons(_box(0.5, []), 1000)
    assert len(dark) == 0 and dark.emitted == 0 and dark.notes
    empty = Scene("void", [], [Material("m")], lights=[_centre_light()])
    pm = trace_photons(empty, 1000)
    assert len(pm) == 0 and any("geometry" in n for n in pm.notes)


def test_bad_input_is_tolerated() -> None:
    walls = _box_walls()
    walls[0].positions = walls[0].positions.copy()
    walls[0].positions[0] = np.nan  # one wall loses a triangle
    walls[1].positions = np.zeros((4, 3), np.float32)  # zero-area triangles
    lights = [
        _centre_light(),
        PointLight((np.nan, 0.0, 0.0)),
        PointLight((0.0, 0.0, 0.0), (np.nan, 1.0, 1.0)),
        PointLight((0.0, 0.0, 0.0), (1.0, 1.0, 1.0), np.inf),
        PointLight((0.0, 0.0, 0.0), (1.0, 1.0, 1.0), 5.0, np.inf),
        PointLight((0.0, 0.0, 0.0), (1.0, 1.0, 1.0), 5.0, np.nan),
    ]
    mats = [Material("wall", (0.5, np.nan, 0.5, 1.0), metallic=np.nan, emissive=(np.nan, 0.0, 0.0))]
    scene = Scene("bad", walls, mats, lights=lights)
    pm = trace_photons(scene, 4096, seed=1)
    assert len(pm) > 0
    assert np.isfinite(pm.positions).all() and np.isfinite(pm.power).all()
    assert (pm.power >= 0).all()
    assert any("non-finite" in n for n in pm.notes)


def test_light_outside_and_inside_geometry() -> None:
    # Outside the closed box: the walls are two-sided, photons land on their outer faces.
    outside = trace_photons(_box(0.5, [PointLight((0.0, 0.0, 9.0), range_m=50.0)]), 2048)
    assert np.isfinite(outside.positions).all()
    assert np.all(outside.positions[:, 2] >= HALF[2] - 1e-3)
    # On a wall: no exception, no NaN.
    on_wall = trace_photons(_box(0.5, [PointLight((0.0, 0.0, HALF[2]))]), 2048)
    assert np.isfinite(on_wall.power).all() and np.isfinite(on_wall.positions).all()


def test_reflectance_uses_texture_and_vertex_colours() -> None:
    tex = Texture("grey", np.full((4, 4, 4), 188, np.uint8))  # sRGB 188 = linear 0.5
    walls = _box_walls()
    walls[1].material = 1
    walls[2].colors = np.tile(np.float32([0.5, 1.0, 1.0]), (4, 1))
    mats = [
        Material("plain", (0.8, 0.6, 0.4, 1.0), metallic=0.25),
        Material("textured", (1.0, 1.0, 1.0, 1.0), texture=0),
    ]
    rho, emit = _mesh_optics(Scene("t", walls, mats, [tex]), [])
    np.testing.assert_allclose(rho[0], [0.6, 0.45, 0.3])
    np.testing.assert_allclose(rho[1], 0.5, atol=3e-3)
    np.testing.assert_allclose(rho[2], [0.3, 0.45, 0.3])
    assert not emit.any()


def test_progress_cancel_and_given_caster() -> None:
    scene = _box(0.5, [_centre_light()])
    seen: list[float] = []
    pm = trace_photons(scene, 2048, seed=4, progress=seen.append)
    assert seen and seen[-1] == 1.0 and seen == sorted(seen)
    with pytest.raises(TracingCancelled):
        trace_photons(scene, 2048, cancel=lambda: True)
    caster = RayCaster(scene.triangles(), scene.triangle_owner())
    same = trace_photons(scene, 2048, seed=4, caster=caster)
    assert same.positions.tobytes() == pm.positions.tobytes()
    other = RayCaster(scene.triangles()[:3])
    rebuilt = trace_photons(scene, 2048, seed=4, caster=other)
    assert rebuilt.positions.tobytes() == pm.positions.tobytes()
    assert any("caster" in n for n in rebuilt.notes)


def test_cast_triangles_maps_back_past_dropped_triangles() -> None:
    tris = np.array(
        [
            [[0, 0, 0], [1, 0, 0], [0, 1, 0]],
            [[np.nan, 0, 0], [1, 0, 0], [0, 1, 0]],
            [[0, 0, 2], [1, 0, 2], [0, 1, 2]],
        ],
        float,
    )
    caster = RayCaster(tris)
    dist, tri = caster.cast_triangles(
        [[0.2, 0.2, 1.0], [0.2, 0.2, 1.0], [5, 5, 1]], [[0, 0, 1], [0, 0, -1], [0, 0, 1]]
    )
    np.testing.assert_allclose(dist[:2], [1.0, 1.0], atol=1e-5)
    assert dist[2] == np.inf and tri[2] == -1
    assert list(caster.source_index[tri[:2]]) == [2, 0]


def test_showroom_traces_inside_its_bounds() -> None:
    room = scenes.resolve("showroom")
    pm = trace_photons(room, 2**14, seed=0)
    assert len(pm) > 2**13
    assert np.isfinite(pm.positions).all() and np.isfinite(pm.power).all()
    lo, hi = room.bounds()
    pad = 1e-3 * scene_scale(room)
    assert np.all(pm.positions >= lo - pad) and np.all(pm.positions <= hi + pad)
    assert (pm.power >= 0).all() and pm.power.sum() > 0
