"""Frustum culling of mesh chunks and levels of detail (app.lod, render.culling): the picture
is the same, fewer triangles are drawn when the view turns away, a chunked big mesh keeps its
identity, levels coarsen with distance and lod_bias, are cached, and broken input falls back."""

from __future__ import annotations

import numpy as np
import pytest

from app.lod import CHUNK_TRIANGLES, LOD_FRACTIONS, build_lod, cached_lod, chunk_mesh
from app.scene import Light, Material, Mesh, Scene, Viewpoint
from app.session import Session
from app.settings import Settings
from assets.showroom import MeshBuilder
from render.culling import frustum_planes, visible_mask
from render.offscreen import OffscreenHost

W, H = 320, 90  # both eyes: 160 x 90 each
N = 200  # the floor grid: N x N quads, 2 N^2 triangles (8 chunks)


def grid_floor(n: int = N, half: float = 10.0) -> Mesh:
    xs = np.linspace(-half, half, n + 1)
    gx, gz = np.meshgrid(xs, xs)
    pos = np.c_[gx.ravel(), np.zeros(gx.size), gz.ravel()].astype(np.float32)
    uv = np.c_[gx.ravel() / (2 * half) + 0.5, gz.ravel() / (2 * half) + 0.5].astype(np.float32)
    normals = np.tile(np.float32([0, 1, 0]), (len(pos), 1))
    i = np.arange(n)
    a = (i[:, None] * (n + 1) + i[None, :]).ravel()
    b, c, d = a + 1, a + n + 1, a + n + 2
    tris = np.r_[np.c_[a, c, b], np.c_[b, c, d]].astype(np.uint32)
    return Mesh("floor", pos, normals, uv, tris, 0)


def scene(pitch: float = -20.0) -> Scene:
    cube = MeshBuilder()
    cube.box((0.0, 0.5, -3.0), (1.0, 1.0, 1.0))
    return Scene(
        "grid",
        [grid_floor(), cube.mesh("box", 1)],
        [
            Material("grey", (0.8, 0.8, 0.8, 1.0), None, roughness=1.0),
            Material("red", (0.8, 0.1, 0.1, 1.0), None, roughness=0.6),
        ],
        [],
        [Light((0.0, 3.0, 0.0), intensity=20.0, range_m=30.0)],
        Viewpoint((0.0, 1.6, 0.0), pitch_deg=pitch),
        floor_y=0.0,
    ).sanitized()


@pytest.fixture(scope="module")
def host():
    s = Settings()
    s.render.overlay = False
    h = OffscreenHost(W, H, s)
    yield h
    assert not h.renderer.errors
    h.close()


def frame(host: OffscreenHost, sc: Scene):
    session = Session(host.settings.copy())
    session.set_scene(sc)
    return session.frame_input(*host.eye_size)


def test_a_big_mesh_is_split_into_coherent_chunks_and_a_small_one_is_not():
    floor = grid_floor()
    tris, chunks = chunk_mesh(floor.positions, floor.indices)
    assert chunks is not None and chunks.first.shape[1] == 8
    assert chunks.count.max() <= 3 * CHUNK_TRIANGLES
    # Every triangle once, and each chunk much smaller than the whole floor.
    assert sorted(map(tuple, np.sort(tris, axis=1))) == sorted(
        map(tuple, np.sort(floor.indices.astype(np.int64), axis=1))
    )
    area = (chunks.hi - chunks.lo)[:, [0, 2]].prod(axis=1)
    assert area.max() <= 0.25 * 20.0 * 20.0 + 1e-6
    small_tris, small = chunk_mesh(floor.positions, floor.indices[:100])
    assert small is not None and small.first.shape[1] == 1
    assert np.array_equal(small_tris, floor.indices[:100])  # its own order: same picture


def test_boxes_behind_the_eye_are_culled_and_in_front_kept():
    from app.camera import frustum

    vp = frustum(-0.1, 0.1, -0.1, 0.1, 0.1, 100.0)  # 90 degrees, down -z from the origin
    chunks = chunk_mesh(np.zeros((1, 3)), np.zeros((1, 3), np.uint32))[1]
    assert chunks is not None
    chunks.lo = np.array([[-1.0, -1.0, -6.0], [-1.0, -1.0, 4.0], [50.0, -1.0, -6.0]])
    chunks.hi = np.array([[1.0, 1.0, -4.0], [1.0, 1.0, 6.0], [52.0, 1.0, -4.0]])
    assert visible_mask(chunks, frustum_planes(vp)).tolist() == [True, False, False]


def test_culling_keeps_the_picture_and_draws_less_when_looking_away(host):
    sc = scene()
    host.set_scene(sc)
    fi = frame(host, sc)
    gpu = host.renderer.gpu_scene
    assert gpu is not None
    gpu.cull = False
    full = host.draw(fi).copy()
    all_tris = host.renderer.triangles_drawn()
    gpu.cull = True
    culled = host.draw(fi).copy()
    drawn = host.renderer.triangles_drawn()
    assert np.abs(full.astype(int) - culled.astype(int)).max() <= 1
    assert full[..., :3].std() > 5  # something was drawn
    assert all(d < a for d, a in zip(drawn, all_tris))
    # Looking up, away from the floor: fewer still.
    away = scene(pitch=70.0)
    host.set_scene(away)
    host.draw(frame(host, away))
    back = host.renderer.triangles_drawn()
    assert all(b < d for b, d in zip(back, drawn))


def test_a_chunked_mesh_keeps_its_object_id(host):
    sc = scene()
    host.set_scene(sc)
    fi = frame(host, sc)
    ids = host.object_ids(fi)
    floor_px = (ids[0] == 0).sum()
    box_px = (ids[0] == 1).sum()
    assert floor_px > 0.3 * ids[0].size and box_px > 20
    assert set(np.unique(ids[0]).tolist()) <= {-1, 0, 1}


def test_broken_positions_do_not_break_the_chunks():
    floor = grid_floor()
    pos = floor.positions.copy()
    pos[::7] = np.nan
    tris, chunks = chunk_mesh(pos, floor.indices)
    assert chunks is not None and len(tris) == len(floor.indices)
    assert np.isfinite(chunks.lo).all() and np.isfinite(chunks.hi).all()
    none_tris, none = chunk_mesh(pos, np.zeros((0, 3), np.uint32))
    assert none is None and len(none_tris) == 0


def bumpy_floor(n: int = 60) -> Mesh:
    """A gently waved grid: simplifiable, but not flat (so levels have a real error)."""
    m = grid_floor(n, half=2.0)
    pos = m.positions.copy()
    pos[:, 1] = 0.05 * np.sin(pos[:, 0] * 3.0) * np.cos(pos[:, 2] * 2.0)
    return Mesh("bumpy", pos, m.normals, m.uvs, m.indices, 0)


def test_levels_are_coarser_far_away_and_with_a_higher_bias():
    from render.culling import lod_levels

    m = bumpy_floor()
    tris, chunks = build_lod(m.positions, m.indices, m.normals)
    assert chunks is not None and chunks.levels == 1 + len(LOD_FRACTIONS)
    counts = chunks.count[:, 0]
    assert counts[0] == m.indices.size and counts[1] < counts[0] and counts[3] < counts[1]
    assert (chunks.error[1:] > 0).all()
    # Simplified levels use the mesh's own vertices (attributes stay valid) and stay inside.
    assert tris.max() < len(m.positions)
    near = lod_levels(chunks, np.array([0.0, 1.0, 2.5]), 360.0, 1.0)
    far = lod_levels(chunks, np.array([0.0, 1.0, 60.0]), 360.0, 1.0)
    farther_bias = lod_levels(chunks, np.array([0.0, 1.0, 2.5]), 360.0, 8.0)
    assert near[0] < far[0] and near[0] < farther_bias[0]
    assert lod_levels(chunks, np.array([0.0, 1.0, 60.0]), 360.0, 0.0)[0] == 0


def test_the_cache_answers_the_second_load_and_broken_input_falls_back(tmp_path):
    m = bumpy_floor()
    lod, hit = cached_lod(m.positions, m.indices)
    assert lod is not None and not hit
    again, hit = cached_lod(m.positions, m.indices)
    assert hit and again is not None and np.array_equal(again.triangles, lod.triangles)
    broken = m.positions.copy()
    broken[5] = np.nan
    lod_nan, _ = cached_lod(broken, m.indices)  # the chunk with a NaN keeps its full level only
    assert lod_nan is not None and lod_nan.chunks.count[3, 0] == m.indices.size


@pytest.mark.parametrize("flat", [False, True], ids=["smooth", "flat-shaded"])
def test_a_simplified_mesh_far_away_looks_like_the_full_one(host, flat):
    m = flat_shaded(bumpy_floor()) if flat else bumpy_floor()
    m.positions[:, 2] -= 14.0  # 12-16 m away
    m.lod, _ = cached_lod(m.positions, m.indices, m.normals)
    sc = Scene(
        "bumpy",
        [m],
        [Material("grey", (0.8, 0.8, 0.8, 1.0), None, roughness=0.5)],
        [],
        [Light((0.0, 3.0, -12.0), intensity=40.0, range_m=30.0)],
        Viewpoint((0.0, 1.6, 0.0), pitch_deg=-8.0),
        floor_y=0.0,
    )
    host.set_scene(sc)
    fi = frame(host, sc)
    host.settings.render.lod_bias = 0.0
    full = host.draw(fi).astype(int)
    tris_full = host.renderer.triangles_drawn()
    host.settings.render.lod_bias = 4.0
    coarse = host.draw(fi).astype(int)
    tris_coarse = host.renderer.triangles_drawn()
    host.settings.render.lod_bias = 0.0
    assert all(2 * c < f for c, f in zip(tris_coarse, tris_full)), (tris_coarse, tris_full)
    assert full[..., :3].std() > 3  # the floor is in view
    assert np.abs(full - coarse).mean() < 2.0


def flat_shaded(m: Mesh) -> Mesh:
    """The mesh as a flat-shaded export writes it: every triangle its own three vertices,
    with its facet's normal (no two triangles share a vertex)."""
    tris = m.indices.reshape(-1, 3)
    pos = m.positions[tris].reshape(-1, 3)
    p = pos.reshape(-1, 3, 3)
    face = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    face /= np.linalg.norm(face, axis=1, keepdims=True)
    normals = np.repeat(face, 3, axis=0).astype(np.float32)
    uvs = m.uvs[tris].reshape(-1, 2)
    indices = np.arange(len(pos), dtype=np.uint32).reshape(-1, 3)
    return Mesh(m.name + "-flat", pos.astype(np.float32), normals, uvs, indices, m.material)


def tiled_cube(n: int = 12) -> Mesh:
    """A 1 m cube, each face an n x n grid of quads (a mesh to simplify with sharp edges)."""
    t = np.linspace(-0.5, 0.5, n + 1)
    gu, gv = (a.ravel() for a in np.meshgrid(t, t))
    positions, indices = [], []
    for axis in range(3):
        for side in (-0.5, 0.5):
            p = np.zeros((len(gu), 3))
            p[:, axis] = side
            p[:, (axis + 1) % 3], p[:, (axis + 2) % 3] = gu, gv
            i = np.arange(n)
            a = (i[:, None] * (n + 1) + i[None, :]).ravel()
            quads = np.r_[np.c_[a, a + 1, a + n + 1], np.c_[a + 1, a + n + 2, a + n + 1]]
            if side < 0:
                quads = quads[:, ::-1]
            indices.append(quads + sum(len(q) for q in positions))
            positions.append(p)
    pos = np.concatenate(positions).astype(np.float32)
    normals = np.zeros_like(pos)  # replaced by flat_shaded's facet normals
    uvs = np.zeros((len(pos), 2), np.float32)
    return Mesh("cube", pos, normals, uvs, np.concatenate(indices).astype(np.uint32), 0)


@pytest.mark.parametrize("shape", [bumpy_floor, tiled_cube])
def test_a_flat_shaded_mesh_is_simplified_and_keeps_its_facets_normals(shape):
    m = flat_shaded(shape())
    tris, chunks = build_lod(m.positions, m.indices, m.normals)
    assert chunks is not None
    full = chunks.count[0, 0] // 3
    coarsest = chunks.count[-1, 0] // 3
    assert coarsest <= 2 * LOD_FRACTIONS[-1] * full, (coarsest, full)
    assert 0.0 <= chunks.error[-1, 0] < 0.05  # within the bumps
    level = tris[chunks.first[-1, 0] // 3 :][:coarsest]
    p = m.positions[level].astype(np.float64)
    face = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    face /= np.linalg.norm(face, axis=1, keepdims=True)
    # Each corner's vertex is one of that position's, the one facing as the new facet does.
    alignment = np.einsum("kj,kcj->kc", face, m.normals[level].astype(np.float64))
    assert np.median(alignment) > 0.99 and alignment.min() > 0.9


def screws_scene(glow: bool = False) -> Scene:
    """The grid floor and a row of 5 cm boxes (knobs, handles) 1 to 8 m ahead at eye level,
    black against a lit white wall behind them (glowing when ``glow``)."""
    wall = MeshBuilder()
    wall.box((0.0, 1.5, -10.0), (20.0, 3.0, 0.2))
    screws = []
    for z in (-1.0, -2.0, -4.0, -8.0):
        screw = MeshBuilder()
        screw.box((0.0, 1.6, z), (0.05, 0.05, 0.05))
        screws.append(screw.mesh(f"screw{-z:g}", 2))
    materials = [
        Material("grey", (0.8, 0.8, 0.8, 1.0), None, roughness=1.0),
        Material("white", (1.0, 1.0, 1.0, 1.0), None, roughness=1.0, emissive=(2.0, 2.0, 2.0)),
        Material("black", (0.0, 0.0, 0.0, 1.0), None, emissive=(9.0, 0, 0) if glow else (0, 0, 0)),
    ]
    return Scene(
        "screws",
        [grid_floor(), wall.mesh("wall", 1), *screws],
        materials,
        [],
        [Light((0.0, 3.0, 0.0), intensity=20.0, range_m=30.0)],
        Viewpoint((0.0, 1.6, 0.0)),
        floor_y=0.0,
    ).sanitized()


def test_a_tiny_whole_object_is_left_out_within_the_error_and_a_glowing_one_stays():
    from render.culling import LEFT_OUT, lod_levels

    screw = MeshBuilder()
    screw.box((0.0, 1.6, -4.0), (0.02, 0.02, 0.02))
    _, chunks = chunk_mesh(screw.mesh("screw", 0).positions, screw.mesh("screw", 0).indices)
    assert chunks is not None
    eye = np.array([0.0, 1.6, 0.0])
    # 3.5 cm of diagonal at 4 m, 400 px a radian: 3.5 px on screen.
    assert lod_levels(chunks, eye, 400.0, 0.0)[0] == 0  # no bias: always drawn
    assert lod_levels(chunks, eye, 400.0, 2.0)[0] == 0  # bigger than the error allowed
    assert lod_levels(chunks, eye, 400.0, 4.0)[0] == LEFT_OUT
    assert lod_levels(chunks, eye, 400.0, 4.0, keep=np.array([True]))[0] == 0
    # A chunk of a big mesh is never left out: it would cut a hole in its surface.
    floor = grid_floor()
    _, big = chunk_mesh(floor.positions, floor.indices)
    assert big is not None
    assert (lod_levels(big, np.array([0.0, 500.0, 0.0]), 400.0, 16.0) != LEFT_OUT).all()


def test_tiny_objects_go_with_the_bias_and_glowing_ones_stay_on_screen(host):
    def draw(sc: Scene, bias: float):
        host.settings.set("render.lod_bias", bias)
        host.set_scene(sc)
        fi = frame(host, sc)
        img = host.draw(fi).astype(float)
        return img, host.renderer.triangles_drawn()[0]

    try:
        full, full_tris = draw(screws_scene(), 0.0)
        simple, simple_tris = draw(screws_scene(), 8.0)
        lit_full, _ = draw(screws_scene(glow=True), 0.0)
        lit_simple, _ = draw(screws_scene(glow=True), 8.0)
    finally:
        host.settings.set("render.lod_bias", 0.0)
    assert simple_tris <= full_tris - 4 * 12  # the four boxes' 12 triangles each are gone
    # The nearest box (5 cm at 1 m: about 4 px across at this size) was a dark dot on the
    # white wall; simplified, the wall shows there. Glowing, it stays.
    dark = (full.sum(axis=2) < 200) & (simple.sum(axis=2) > 400)
    assert dark.sum() >= 1
    assert np.array_equal(lit_full, lit_simple)
