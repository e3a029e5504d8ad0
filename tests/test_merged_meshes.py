"""Static meshes merged per material (render.gpu_scene.GpuGroup): the merged path draws the
same picture as one draw per mesh, in far fewer draw calls; TCR levels stay per object (the
per-object table); culling and levels of detail stay per chunk; object ids stay per mesh."""

from __future__ import annotations

import numpy as np
import pytest

from app.camera import StereoCamera
from app.frame import FrameInput
from app.lod import cached_lod
from app.scene import Light, Material, Mesh, Scene, Viewpoint
from app.session import Session
from app.settings import Settings
from assets.showroom import MeshBuilder
from render.offscreen import OffscreenHost
from render.passes import LEVEL_TINTS
from tests.test_culling_lod import grid_floor
from tests.test_render import quad
from tests.test_tcr_render import nearest_tint, texel_checker

W, H = 320, 180


def box(name: str, centre, size, material: int) -> Mesh:
    b = MeshBuilder()
    b.box(centre, size)
    return b.mesh(name, material)


def room() -> Scene:
    """Boxes of three opaque materials (several meshes each, one textured), a chunked floor
    with levels of detail, a glowing box and a glass pane, lit by a point light."""
    meshes = [
        grid_floor(120, 8.0),
        box("red-1", (-1.2, 0.4, -3.0), (0.8, 0.8, 0.8), 1),
        box("red-2", (1.2, 0.3, -4.0), (0.6, 0.6, 0.6), 1),
        box("red-3", (0.0, 1.2, -5.0), (0.5, 2.4, 0.5), 1),
        box("tex-1", (-0.6, 0.25, -2.0), (0.5, 0.5, 0.5), 2),
        box("tex-2", (0.7, 0.2, -2.4), (0.4, 0.4, 0.4), 2),
        box("lamp", (1.6, 1.8, -3.5), (0.2, 0.2, 0.2), 3),
        quad("glass", (-0.2, 0.8, -1.6), 0.3, material=4),
        box("red-far-left", (-9.0, 0.5, 1.0), (1.0, 1.0, 1.0), 1),  # out of the view
    ]
    materials = [
        Material("floor", (0.7, 0.7, 0.7, 1.0), None, roughness=0.9),
        Material("red", (0.8, 0.1, 0.1, 1.0), None, roughness=0.5),
        Material("checker", (1.0, 1.0, 1.0, 1.0), 0, roughness=0.8),
        Material("glow", (1.0, 1.0, 1.0, 1.0), None, emissive=(4.0, 3.0, 1.0)),
        Material("glass", (0.3, 0.5, 0.9, 0.4), None, roughness=0.1, alpha_mode="BLEND"),
    ]
    scene = Scene(
        "merge-room",
        meshes,
        materials,
        [texel_checker(16)],
        [Light((0.5, 2.6, -1.5), intensity=25.0, range_m=20.0)],
        Viewpoint((0.0, 1.4, 1.0), pitch_deg=-15.0),
        floor_y=0.0,
    ).sanitized()
    floor = scene.meshes[0]
    floor.lod, _ = cached_lod(floor.positions, floor.indices, floor.normals)
    return scene


@pytest.fixture(scope="module")
def host():
    s = Settings()
    s.render.overlay = False
    h = OffscreenHost(W, H, s)
    yield h
    assert not h.renderer.errors
    h.close()


def frame(host: OffscreenHost, scene: Scene, levels=None) -> FrameInput:
    session = Session(host.settings.copy())
    session.set_scene(scene)
    fi = session.frame_input(*host.eye_size)
    return FrameInput(fi.eyes, gaze=(-1, -1), levels=levels)


def draw(host: OffscreenHost, scene: Scene, merge: bool, levels=None, frames: int = 2):
    """The picture (the last of ``frames``, shadow maps settled), triangles and calls."""
    host.renderer.merge_meshes = merge
    host.set_scene(scene)
    fi = frame(host, scene, levels)
    for _ in range(frames):
        img = host.draw(fi).astype(np.float64)
    return img, host.renderer.triangles_drawn(), host.renderer.draw_calls()


@pytest.fixture(autouse=True)
def per_mesh_afterwards(host):
    yield
    host.renderer.merge_meshes = True
    for key in ("render.path", "render.shadows", "render.lod_bias", "tcr.enabled", "tcr.tint"):
        host.settings.set(key, Settings().get(key))


def test_groups_are_the_materials():
    host = OffscreenHost(64, 32, Settings())
    try:
        scene = room()
        host.set_scene(scene)
        gpu = host.renderer.gpu_scene
        assert gpu is not None
        members = {scene.materials[g.material_index].name: g.members for g in gpu.groups}
        assert members == {
            "floor": [0],
            "red": [1, 2, 3, 8],
            "checker": [4, 5],
            "glow": [6],
            "glass": [7],
        }
        assert gpu.standalone == []
    finally:
        host.close()


def test_merged_geometry_is_held_once_on_the_gpu(host):
    """Merged, a mesh's vertices and indices live in its group's buffers only: the scene's
    geometry bytes are the per-mesh path's (plus each vertex's 4-byte mesh index), not
    both paths' buffers side by side (about twice that)."""
    scene = room()
    host.renderer.merge_meshes = False
    host.set_scene(scene)
    per_mesh = host.renderer.gpu_scene
    assert per_mesh is not None and not per_mesh.groups
    per_mesh_bytes = per_mesh.geometry_bytes
    assert all(m.vbo is not None and m.ibo is not None for m in per_mesh.meshes)
    host.renderer.merge_meshes = True
    host.set_scene(scene)
    merged = host.renderer.gpu_scene
    assert merged is not None and merged.groups
    vertices = sum(len(m.positions) for m in scene.meshes)
    # Per vertex: position, normal, uv, colour (44 bytes) and sky visibility (8): the floor
    # alone holds thousands, so the merged scene holding both copies would be ~2x.
    assert per_mesh_bytes > 52 * vertices
    assert all(m.vbo is None and m.ibo is None and m.sky_vbo is None for m in merged.meshes)
    assert merged.geometry_bytes == pytest.approx(per_mesh_bytes + 4 * vertices, rel=0.01)
    assert merged.geometry_bytes < 0.55 * (per_mesh_bytes + merged.geometry_bytes)
    with pytest.raises(ValueError, match="merged into a group"):
        with host.ctx:
            prog = host.ctx.program(
                vertex_shader="#version 330\nin vec3 in_position;\n"
                "void main() { gl_Position = vec4(in_position, 1.0); }",
                fragment_shader="#version 330\nout vec4 c;\nvoid main() { c = vec4(1.0); }",
            )
            merged.vao(prog, 0)


@pytest.mark.parametrize("path", ["deferred", "forward"])
@pytest.mark.parametrize("shadows", ["off", "soft"])
def test_merged_and_per_mesh_paths_draw_the_same_picture(host, path, shadows):
    host.settings.set("render.path", path)
    host.settings.set("render.shadows", shadows)
    scene = room()
    per_mesh, tris_a, calls_a = draw(host, scene, merge=False)
    merged, tris_b, calls_b = draw(host, scene, merge=True)
    assert per_mesh[..., :3].std() > 10  # something is in view
    diff = np.abs(per_mesh - merged)[..., :3].max(axis=-1)
    assert diff.mean() < 0.5, diff.mean()
    assert (diff > 8).mean() < 0.002, (diff > 8).mean()
    assert tris_a == tris_b  # the same chunks, at the same levels
    assert all(b < a for a, b in zip(calls_a, calls_b)), (calls_a, calls_b)


def test_draw_calls_drop_to_one_per_material_in_view(host):
    scene = room()
    _, _, per_mesh = draw(host, scene, merge=False, frames=1)
    _, _, merged = draw(host, scene, merge=True, frames=1)
    # Per mesh: the floor's visible chunks plus a call per opaque mesh in view (7 of 8).
    assert all(c >= 7 for c in per_mesh), per_mesh
    # Merged: one call per opaque group (4; the glass is the blend pass's), a split group's
    # ranges (the out-of-view box) as one multi-draw.
    assert merged == [4, 4], merged


def test_culling_and_levels_of_detail_stay_per_mesh_inside_a_group(host):
    scene = room()
    host.settings.set("render.lod_bias", 16.0)
    _, tris_a, _ = draw(host, scene, merge=False, frames=1)
    _, tris_b, _ = draw(host, scene, merge=True, frames=1)
    host.settings.set("render.lod_bias", 0.0)
    _, tris_full, _ = draw(host, scene, merge=True, frames=1)
    host.renderer.gpu_scene.cull = False  # type: ignore[union-attr]
    host.draw(frame(host, scene))
    tris_all = host.renderer.triangles_drawn()
    assert tris_a == tris_b  # the same per-chunk levels
    assert all(b < f for b, f in zip(tris_b, tris_full)), (tris_b, tris_full)
    assert all(f < a for f, a in zip(tris_full, tris_all))  # the far-left box is culled


def test_tcr_levels_stay_per_object_after_the_merge(host):
    """Three quads of one material (one group), each at its own TCR level: each shows its own
    level's legend colour in the tinted view, as on the per-mesh path."""
    host.settings.set("tcr.enabled", True)
    host.settings.set("tcr.tint", True)
    quads = [quad(f"q{i}", (x, 1.4, -2.0), 0.3, material=0) for i, x in enumerate((-0.8, 0, 0.8))]
    scene = Scene(
        "one-material",
        quads,
        [Material("checker", (1, 1, 1, 1), 0, roughness=1.0)],
        [texel_checker(64)],
        [Light((0, 1.4, 0), intensity=5.0, range_m=100.0)],
        Viewpoint((0, 1.4, 0)),
    ).sanitized()
    levels = [1, 3, 6]
    host.renderer.merge_meshes = True
    host.set_scene(scene)
    assert [g.members for g in host.renderer.gpu_scene.groups] == [[0, 1, 2]]  # type: ignore
    cam = StereoCamera(host.settings.stereo)
    cam.set_pose((0, 1.4, 0), 0.0, 0.0)
    fi = FrameInput(cam.eyes(*host.eye_size), gaze=(-1, -1), levels=levels)
    ids = host.object_ids(fi)[0]
    img = host.draw(fi)[:, : W // 2].astype(float)
    for obj, level in enumerate(levels):
        assert (ids == obj).sum() > 100
        mean = img[ids == obj].mean(axis=0)
        assert nearest_tint(mean) == level, (obj, level, mean, LEVEL_TINTS[level])
    # The same picture as one draw per mesh.
    host.renderer.merge_meshes = False
    host.set_scene(scene)
    per_mesh = host.draw(fi)[:, : W // 2].astype(float)
    assert np.abs(per_mesh - img).mean() < 0.5


def test_object_ids_are_per_mesh_on_the_merged_path(host):
    scene = room()
    host.renderer.merge_meshes = False
    host.set_scene(scene)
    fi = frame(host, scene)
    per_mesh = host.object_ids(fi)
    host.renderer.merge_meshes = True
    host.set_scene(scene)
    merged = host.object_ids(fi)
    for a, b in zip(per_mesh, merged):
        assert len(np.unique(a)) >= 6  # the floor, boxes, glass and background
        assert (a != b).mean() < 0.002


def test_a_group_split_into_ranges_is_one_multi_draw_with_the_same_picture(host):
    """Levels of detail and culled members split a group's index buffer into several ranges:
    one indirect multi-draw per group draws them, as one call per range would."""
    scene = room()
    chunks = scene.meshes[0].lod.chunks  # the flat floor's levels, exact: as if it were not
    chunks.error = np.array(chunks.error, copy=True)
    chunks.error[1:, chunks.lo[:, 2] >= 0.0] = 1.0  # the near half has to stay full
    host.settings.set("render.lod_bias", 16.0)
    host.renderer.merge_meshes = True
    host.set_scene(scene)
    gpu = host.renderer.gpu_scene
    assert gpu is not None
    fi = frame(host, scene)
    gpu.multi_draw = False
    host.draw(fi)
    per_range = host.draw(fi).astype(np.float64)
    calls_ranges, tris_ranges = host.renderer.draw_calls(), host.renderer.triangles_drawn()
    gpu.multi_draw = True
    host.draw(fi)
    multi = host.draw(fi).astype(np.float64)
    calls_multi, tris_multi = host.renderer.draw_calls(), host.renderer.triangles_drawn()
    assert tris_multi == tris_ranges
    assert all(m < r for m, r in zip(calls_multi, calls_ranges)), (calls_multi, calls_ranges)
    assert all(m == len(gpu.groups) - 1 for m in calls_multi)  # the glass: the blend pass
    assert np.abs(per_range - multi).max() == 0


def glass_panes() -> Scene:
    """Overlapping panes in depth, of two glass materials interleaved (blue, blue, green,
    blue from far to near), before a grey wall: the blend order shows in the picture."""
    panes = [
        quad("blue-far", (0.0, 1.4, -4.0), 0.8, material=1),
        quad("blue-mid", (0.2, 1.4, -3.5), 0.8, material=1),
        quad("green", (-0.2, 1.4, -3.0), 0.8, material=2),
        quad("blue-near", (0.1, 1.5, -2.5), 0.5, material=1),
    ]
    return Scene(
        "glass",
        [quad("wall", (0.0, 1.4, -5.0), 2.5, material=0), *panes],
        [
            Material("wall", (0.6, 0.6, 0.6, 1.0), None, roughness=1.0),
            Material("blue", (0.1, 0.3, 0.9, 0.5), None, roughness=0.3, alpha_mode="BLEND"),
            Material("green", (0.1, 0.9, 0.2, 0.5), None, roughness=0.3, alpha_mode="BLEND"),
        ],
        [],
        [Light((0.0, 1.6, 0.0), intensity=10.0, range_m=50.0)],
        Viewpoint((0.0, 1.4, 0.0)),
    ).sanitized()


def test_blended_meshes_of_one_material_draw_as_one_sorted_call(host):
    """The blend pass keeps its back-to-front order per mesh: a run of one material's panes
    is one multi-draw in that order, another material's pane between them splits the run."""
    scene = glass_panes()
    per_mesh, _, _ = draw(host, scene, merge=False)
    calls_per_mesh = host.renderer.frame_draw_calls()
    host.draw(frame(host, scene))
    calls_per_mesh = host.renderer.frame_draw_calls() - calls_per_mesh
    merged, _, _ = draw(host, scene, merge=True)
    calls_merged = host.renderer.frame_draw_calls()
    host.draw(frame(host, scene))
    calls_merged = host.renderer.frame_draw_calls() - calls_merged
    assert np.abs(per_mesh - merged)[..., :3].max() <= 1
    # Per eye: the wall, then the panes: per mesh 4 calls; merged blue (far, mid), green,
    # blue (near): 3. The shadow maps are cached after the first frames.
    assert calls_per_mesh == 2 * (1 + 4), calls_per_mesh
    assert calls_merged == 2 * (1 + 3), calls_merged
    # The order matters: the near blue pane drawn before the green one looks different.
    gpu = host.renderer.gpu_scene
    assert gpu is not None
    blue = gpu.group_of[1]
    assert [gpu.group_of[i] for i in (1, 2, 4)] == [blue] * 3 and gpu.group_of[3] != blue
