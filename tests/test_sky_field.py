"""The sky's share by place (app/sky_field.py): the light of a window on a wall, whatever
triangles the wall was cut into, and no glow from the gaps a real model has."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from app.raycast import RayCaster
from app.scene import Material, Mesh, Scene, Viewpoint
from app.settings import Settings
from app.sky_field import VisibilityBake, sky_field, spread_field
from app.sky_light import occluders, sky_portal
from app.sky_model import LUMA
from render.offscreen import OffscreenHost
from render.sky import GpuSkyField
from tests.test_sky import grid, look, pixel
from tests.test_sky_light import room


def field_of(scene: Scene, max_rays: int = 400_000):
    tri = occluders(scene)
    caster = RayCaster(tri)
    return sky_field(scene, caster, sky_portal(scene, caster, tri, 0), max_rays=max_rays)


@pytest.fixture(scope="module")
def host():
    s = Settings()
    s.set("stereo.ipd_mm", 0.0)
    s.set("sky.enabled", True)
    s.set("render.ambient_estimate", False)  # the sky's light alone, and the sun's
    s.set("render.ambient", 0.0)
    h = OffscreenHost(160, 90, s)
    yield h
    assert not h.renderer.errors
    h.close()


@pytest.mark.parametrize(("path", "mitigation"), [("deferred", "none"), ("forward", "none")])
def test_a_walls_sky_light_does_not_depend_on_how_it_was_cut_into_triangles(host, path, mitigation):
    """A real room's wall is a few long triangles. Drawn from its corners' shares, the light
    of a window on it showed as polygons (the daylit living room, stop 34); read by place,
    the wall cut into two triangles looks as the same wall cut into 512. (With the share per
    vertex alone the two differ by 82 % of the wall's mean here; read by place, by 4 %.)"""
    pose = ((1.5, 1.5, 0.0), 90.0, 0.0)  # facing the west wall, the window on the left
    pictures = []
    for cells in (1, 16):
        scene = room(n=cells)
        hdr = look(host, scene, *pose, render__path=path, cps__mode=mitigation, sky__time="07:00")
        pictures.append(hdr @ LUMA)
    top, left = pixel(host, *pose, (-2.0, 2.6, 1.6))  # looking west, the south on the left
    bottom, right = pixel(host, *pose, (-2.0, 0.4, -1.6))
    top, left = max(top, 0), max(left, 0)
    coarse, fine = (p[top:bottom, left:right] for p in pictures)
    assert coarse.size > 500
    # The window's side of the wall is brighter than its far side, in both.
    for wall in (coarse, fine):
        third = wall.shape[1] // 3
        assert wall[:, :third].mean() > 1.3 * wall[:, -third:].mean()
    assert np.abs(coarse - fine).mean() < 0.15 * fine.mean(), np.abs(coarse - fine).mean()


def test_the_field_reads_the_same_wall_alike_however_it_was_cut():
    """On the CPU twin: along the west wall from the window to the far corner, the share read
    from the field of a wall of two triangles is within a quarter of the largest of one of
    512 (8 % measured)."""
    along = np.stack([np.full(9, -1.99), np.full(9, 1.5), np.linspace(1.8, -1.8, 9)], axis=1)
    east = np.tile([1.0, 0.0, 0.0], (9, 1))
    shares = []
    for cells in (1, 16):
        field = field_of(room(n=cells), max_rays=2_000_000)  # the noise well below the gap
        assert field is not None
        shares.append(field.lookup(along, east, np.zeros(9)))
    coarse, fine = shares
    assert fine[1] > 2.5 * fine[-1] > 0.0  # by the window more than in the far corner
    assert np.abs(coarse - fine).max() < 0.25 * fine.max(), (coarse, fine)


def test_a_gap_in_the_model_does_not_light_what_is_near_it():
    """The living room's floor stops 4 cm short of its walls, and nothing lies under it. The
    floor's underside and the wall's foot below the floor see the ground through the void;
    spread by place, their share lit the underside of the sofa and the wall above the
    skirting in white. Sides whose rays leave the model elsewhere than through the room's
    windows weigh nothing."""
    base = room(n=4)
    meshes = [m for m in base.meshes if m.name not in ("floor", "west wall")]
    meshes += [
        grid("floor", (-1.96, 0, -2), (3.96, 0, 0), (0, 0, 4), 8, (0, 1, 0)),  # 4 cm short
        grid("west wall", (-2, -0.3, -2), (0, 0, 4), (0, 3.3, 0), 4, (1, 0, 0)),
        # A sofa's underside, 10 cm above the floor near the window.
        grid("sofa bottom", (-1.0, 0.1, 0.5), (2, 0, 0), (0, 0, 1), 4, (0, -1, 0)),
        grid("sofa top", (-1.0, 0.5, 0.5), (2, 0, 0), (0, 0, 1), 4, (0, 1, 0)),
    ]
    scene = dataclasses.replace(base, meshes=meshes).sanitized()
    field = field_of(scene)
    assert field is not None
    down = np.tile([0.0, -1.0, 0.0], (5, 1))
    under_sofa = np.stack([np.linspace(-0.8, 0.8, 5), np.full(5, 0.1), np.full(5, 1.0)], 1)
    assert field.lookup(under_sofa, down, np.zeros(5)).max() < 0.05
    east = np.tile([1.0, 0.0, 0.0], (5, 1))
    wall_foot = np.stack([np.full(5, -1.99), np.full(5, 0.15), np.linspace(-1.5, 1.5, 5)], 1)
    above = wall_foot + [0.0, 1.0, 0.0]
    foot = field.lookup(wall_foot, east, np.zeros(5))
    # The foot of the wall sees about as much sky as the wall a metre up (the void under the
    # floor would give it a fifth of the sky).
    assert foot.max() < 0.1 and foot.max() < 2.0 * field.lookup(above, east, np.zeros(5)).max()


def test_broken_meshes_and_empty_scenes_bake_without_error():
    """A mesh with NaN normals and zero-area triangles gets a field of finite shares; a scene
    with no surface gets none, and the bake reports no error."""
    bad = grid("bad", (-1, 0, -1), (2, 0, 0), (0, 0, 2), 4, (0, 1, 0))
    normals = bad.normals.copy()
    normals[::3] = np.nan
    squashed = bad.positions.copy()
    squashed[:, 1] = 0.0
    flat = Mesh("flat", squashed * [1.0, 0.0, 0.0], bad.normals, bad.uvs, bad.indices)
    scene = Scene(
        "bad",
        [dataclasses.replace(bad, normals=normals), flat],
        [Material("white", (0.7, 0.7, 0.7, 1.0))],
        [],
        [],
        Viewpoint((0, 1.6, 0)),
    )
    field = field_of(scene, max_rays=20_000)
    assert field is not None and np.isfinite(field.total).all() and np.isfinite(field.weight).all()
    share = field.lookup(np.array([[0.0, 0.01, 0.0]]), np.array([[0.0, 1.0, 0.0]]), np.zeros(1))
    assert 0.9 < float(share[0]) <= 1.0  # an open floor sees the whole sky above it
    assert spread_field(np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0), np.zeros(0)) is None
    empty = Scene("empty", [], [Material("white", (1, 1, 1, 1))], [], [], Viewpoint((0, 1, 0)))
    bake = VisibilityBake(empty)
    assert bake.wait(30.0)
    assert bake.error is None and bake.field is None and bake.result == []


def test_where_the_field_holds_no_share_the_room_keeps_its_vertices_share(host):
    """Where the field holds no share (a model's outside, or a scene whose field was not
    made) a pixel keeps the share interpolated from its vertices, a coarser picture of the
    same light, not a missing term."""
    scene = room(n=16)
    pose = ((1.5, 1.5, 0.0), 90.0, 0.0)
    with_field = look(host, scene, *pose, sky__time="07:00") @ LUMA
    sky_pass = host.renderer.daylight
    field = sky_pass.field.field
    assert field is not None
    with host.ctx:
        sky_pass.field.set(None)
    try:
        without = look(host, scene, *pose, sky__time="07:00") @ LUMA
    finally:
        with host.ctx:
            sky_pass.field.set(field)
    wall = np.s_[20:70, 40:120]
    # The same light within a fifth on the wall: the vertices' share is a coarser picture of
    # the same thing, not a missing term.
    assert without[wall].mean() > 0.0
    assert abs(without[wall].mean() - with_field[wall].mean()) < 0.2 * with_field[wall].mean()


def gapped_room() -> Scene:
    """``room`` whose floor stops 4 cm short of its walls, the walls going on 30 cm below it
    (the living room's build): under the floor, nothing."""
    base = room(n=4)
    walls = ("floor", "west wall", "east wall", "north wall")
    meshes = [m for m in base.meshes if m.name not in walls]
    meshes += [
        grid("floor", (-1.96, 0, -1.96), (3.92, 0, 0), (0, 0, 3.92), 8, (0, 1, 0)),
        grid("west wall", (-2, -0.3, -2), (0, 0, 4), (0, 3.3, 0), 4, (1, 0, 0)),
        grid("east wall", (2, -0.3, -2), (0, 0, 4), (0, 3.3, 0), 4, (-1, 0, 0)),
        grid("north wall", (-2, -0.3, -2), (4, 0, 0), (0, 3.3, 0), 4, (0, 0, 1)),
    ]
    return dataclasses.replace(base, meshes=meshes).sanitized()


def test_the_daylight_bounce_does_not_come_up_through_a_gap_in_the_model():
    """The even light's daylight bounce (app.ambient) looks at the sky from where its rays
    hit: a hit at a wall's foot by the gap saw the ground under the floor with half its rays,
    and the living room's bounce was 1.4x Cycles'. Only rays out through the windows count:
    the gapped room's bounce is within 15 % of the same room with a whole floor."""
    from app.ambient import AmbientProbe
    from app.sky import bake_sky

    s = Settings()
    s.sky.enabled = True
    sh = bake_sky(s).sh
    whole = AmbientProbe(room(n=4)).estimate([], sh).ambient
    gapped = AmbientProbe(gapped_room()).estimate([], sh).ambient
    assert whole > 0.0
    assert gapped == pytest.approx(whole, rel=0.05), (gapped, whole)


def test_a_long_thin_model_gets_a_field_the_gpu_can_hold():
    """A 2 km street of 3 m: the grid's cell grows until no axis has more than 1024 cells (the
    texture stacks two slabs along z; GL promises 2048 texels a side), and the renderer
    uploads it."""
    pos = np.array([[x, 0.0, z] for x in np.linspace(-1000, 1000, 4000) for z in (-1.0, 1.0)])
    up = np.tile([0.0, 1.0, 0.0], (len(pos), 1))
    field = spread_field(pos, up, np.ones(len(pos)), np.ones(len(pos)))
    assert field is not None and max(field.dims) <= 1024
    host = OffscreenHost(32, 16, Settings())
    try:
        with host.ctx:
            gpu = GpuSkyField(host.ctx)
            gpu.set(field)
            assert gpu.texture.size == (field.dims[0], field.dims[1], 2 * field.dims[2])
            gpu.release()
    finally:
        host.close()


def test_a_slab_running_on_outside_the_wall_does_not_light_the_floor_inside():
    """The bathroom's floor slab runs 14 cm on past its outer wall, into the sun: those faces
    outside bounced thousands of cd/m2, and the even light by place carried it through the
    wall onto the floor inside (2x a path tracer's there). In daylight, faces whose rays leave
    other than through the windows stay out of the field: with a slab outside the windowless
    north wall in the sun, the floor inside by that wall reads what it reads without the
    slab, within 15 %."""
    from app.ambient import AmbientProbe
    from app.scene import Light
    from app.sky import bake_sky

    s = Settings()
    s.sky.enabled = True
    sh = bake_sky(s).sh
    # the sun from the north, high: on the slab and the north wall's outer side only
    sun = Light((0, 0, 0), (1.0, 0.95, 0.9), 60000.0, kind="directional", direction=(0, -0.8, 0.6))
    plain = room(n=8)
    slab = grid("slab outside", (-2, 0, -2.3), (4, 0, 0), (0, 0, 0.3), 8, (0, 1, 0))
    with_slab = dataclasses.replace(plain, meshes=[*plain.meshes, slab]).sanitized()
    inside = np.array(
        [(x, 0.0, z) for x in np.linspace(-1.5, 1.5, 13) for z in (-1.9, -1.75, -1.6)]
    )
    up = np.tile([0.0, 1.0, 0.0], (len(inside), 1))
    read = {}
    for label, scene in (("plain", plain), ("slab", with_slab)):
        field = AmbientProbe(scene).estimate([sun], sh).by_place
        assert field is not None
        read[label] = field.lookup(inside, up).mean()
    assert read["plain"] > 0.0
    assert read["slab"] == pytest.approx(read["plain"], rel=0.15), read
