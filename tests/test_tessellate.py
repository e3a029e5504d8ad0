"""Long edges split at load (app.tessellate): the mesh's surface, attributes and seams kept,
no T-junction, the budget kept, and the sky's light per vertex then finds the window's pool on
a floor exported as one quad."""

from __future__ import annotations

import numpy as np

from app.scene import Material, Mesh, Scene, Viewpoint
from app.sky_light import sky_visibility
from app.tessellate import MAX_EDGE_M, refine_scene, split_long_edges
from tests.test_sky import grid


def quad(name, origin, du, dv, normal) -> Mesh:
    """A rectangle as one quad (two triangles), as a modelling tool exports a floor."""
    return grid(name, origin, du, dv, 1, normal)


def edges(mesh: Mesh) -> dict[tuple, int]:
    """How many triangles have each edge, by its two end positions (rounded)."""
    out: dict[tuple, int] = {}
    p = np.round(mesh.positions.astype(np.float64), 5)
    for t in mesh.indices.reshape(-1, 3):
        for a, b in ((t[0], t[1]), (t[1], t[2]), (t[2], t[0])):
            key = tuple(sorted((tuple(p[a]), tuple(p[b]))))
            out[key] = out.get(key, 0) + 1
    return out


def lengths(mesh: Mesh) -> np.ndarray:
    t = mesh.indices.reshape(-1, 3).astype(np.int64)
    p = mesh.positions.astype(np.float64)
    return np.linalg.norm(p[t] - p[np.roll(t, -1, axis=1)], axis=2)


def area(mesh: Mesh) -> float:
    t = mesh.indices.reshape(-1, 3).astype(np.int64)
    p = mesh.positions.astype(np.float64)
    return float(
        0.5
        * np.linalg.norm(np.cross(p[t[:, 1]] - p[t[:, 0]], p[t[:, 2]] - p[t[:, 0]]), axis=1).sum()
    )


def test_a_floor_quad_gets_short_edges_and_keeps_its_surface_winding_and_uvs():
    floor = quad("floor", (-4, 0, -3), (8, 0, 0), (0, 0, 6), (0, 1, 0))
    out = split_long_edges(floor)
    assert out.triangle_count > 500
    # Halved until each triangle is at most half a MAX_EDGE_M square: its legs that long.
    assert lengths(out).max() <= MAX_EDGE_M * 2**0.5 + 1e-6
    assert abs(area(out) - 48.0) < 1e-3
    t = out.indices.reshape(-1, 3).astype(np.int64)
    p = out.positions.astype(np.float64)
    facing = np.cross(p[t[:, 1]] - p[t[:, 0]], p[t[:, 2]] - p[t[:, 0]])
    assert (facing[:, 1] > 0).all()  # every triangle still faces up
    # The UVs are the plane's linear map at every new vertex; the normals stay unit and up.
    assert np.allclose(out.uvs[:, 0], (p[:, 0] + 4) / 8, atol=1e-5)
    assert np.allclose(out.uvs[:, 1], (p[:, 2] + 3) / 6, atol=1e-5)
    assert np.allclose(out.normals, [0, 1, 0])
    # No T-junction: every edge inside the floor belongs to two triangles, and the edges of
    # one triangle only add up to the floor's outline.
    count = edges(out)
    outline = sum(float(np.linalg.norm(np.subtract(a, b))) for (a, b), n in count.items() if n == 1)
    assert set(count.values()) == {1, 2}
    assert abs(outline - 28.0) < 1e-3


def test_a_seam_of_copied_vertices_splits_alike_on_both_sides():
    # Two quads meeting along x = 0, each with its own vertices there (a UV or normal seam).
    left = quad("left", (-2, 0, 0), (2, 0, 0), (0, 0, 2), (0, 1, 0))
    right = quad("right", (0, 0, 0), (2, 0, 0), (0, 0, 2), (0, 1, 0))
    n = len(left.positions)
    both = Mesh(
        "both",
        np.concatenate([left.positions, right.positions]),
        np.concatenate([left.normals, right.normals]),
        np.concatenate([left.uvs, right.uvs]),
        np.concatenate([left.indices, right.indices + n]),
    )
    out = split_long_edges(both)
    count = edges(out)
    seam = [k for k in count if k[0][0] == 0.0 and k[1][0] == 0.0]
    assert seam and all(count[k] == 2 for k in seam)  # each piece of the seam has both sides


def test_the_budget_stops_whole_rounds_and_short_meshes_stay_as_they_are():
    floor = quad("floor", (-4, 0, -3), (8, 0, 0), (0, 0, 6), (0, 1, 0))
    out = split_long_edges(floor, max_triangles=100)
    assert 2 < out.triangle_count <= 100
    assert set(edges(out).values()) == {1, 2}  # still no T-junction
    small = grid("tiles", (0, 0, 0), (1, 0, 0), (0, 0, 1), 4, (0, 1, 0))
    assert split_long_edges(small) is small
    scene = Scene("s", [small], [Material("m")], [], [], Viewpoint((0, 1, 0)))
    assert refine_scene(scene) is scene


def test_the_sky_per_vertex_finds_the_window_on_a_floor_of_one_quad():
    """A 4 x 4 m room whose floor is one quad, a window in its south wall: with the long edges
    split, the floor beside the window sees the sky and its far end does not; as one quad,
    the floor's four corners miss the pool between them."""
    south = (0, 0, -1)
    meshes = [
        quad("floor", (-2, 0, -2), (4, 0, 0), (0, 0, 4), (0, 1, 0)),
        quad("ceiling", (-2, 3, -2), (4, 0, 0), (0, 0, 4), (0, -1, 0)),
        quad("north wall", (-2, 0, -2), (4, 0, 0), (0, 3, 0), (0, 0, 1)),
        quad("west wall", (-2, 0, -2), (0, 0, 4), (0, 3, 0), (1, 0, 0)),
        quad("east wall", (2, 0, -2), (0, 0, 4), (0, 3, 0), (-1, 0, 0)),
        quad("under the window", (-2, 0, 2), (4, 0, 0), (0, 1, 0), south),
        quad("over the window", (-2, 2.5, 2), (4, 0, 0), (0, 0.5, 0), south),
        quad("left of the window", (-2, 1, 2), (1, 0, 0), (0, 1.5, 0), south),
        quad("right of the window", (1, 1, 2), (1, 0, 0), (0, 1.5, 0), south),
    ]
    scene = Scene(
        "room", meshes, [Material("white", (0.7, 0.7, 0.7, 1.0))], [], [], Viewpoint((0, 1.6, 0))
    ).sanitized()

    def floor_sky(s: Scene) -> tuple[float, float]:
        vis = sky_visibility(s, rays=64, seed=1)
        assert vis is not None
        p, up = s.meshes[0].positions, vis[0][:, 0]
        near = up[np.linalg.norm(p - [0.0, 0.0, 1.5], axis=1) < 0.6]
        far = up[p[:, 2] < -1.0]
        return float(near.max()) if len(near) else 0.0, float(far.mean())

    near, far = floor_sky(refine_scene(scene))
    assert near > 0.05 and near > 3.0 * far, (near, far)
    assert floor_sky(scene)[0] == 0.0  # one quad: no vertex near the window at all


def test_the_status_bar_counts_the_models_own_triangles_not_the_split():
    """A designer compares the count with their modelling tool's: the split's extra triangles
    are named in the tooltip, not in the count."""
    from ui.main_window import scene_label, scene_tip

    floor = quad("floor", (-4, 0, -3), (8, 0, 0), (0, 0, 6), (0, 1, 0))
    scene = Scene("room", [floor], [Material("m")], [], [], Viewpoint((0, 1.6, 0)))
    refined = refine_scene(scene).sanitized()
    assert refined.triangle_count > scene.triangle_count == 2
    assert refined.model_triangle_count == 2
    assert scene_label(refined) == "room · 2 triangles"
    assert f"{refined.triangle_count:,} drawn" in scene_tip(refined)
    assert "drawn" not in scene_tip(scene)
    assert "2 triangles in the model" in scene_tip(scene)
    assert scene_label(None) == ""
