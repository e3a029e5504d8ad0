"""The spawn search on files that are not tidy rooms, the fallbacks, and the units check.

Synthetic scenes are built here with numpy (boxes and planes, in metres unless stated), run
through the loader's own placement and spawn steps; the shared interiors are loaded once each.
"""

from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np
import pytest

from app import placement, spawn
from app.placement import finish_scene, place
from app.raycast import RayCaster
from app.scene import Material, Mesh, Scene, vertex_normals
from app.spawn import EYE_HEIGHT_M, _main_level

# The shared scenes, found as tests/test_loaders.py finds them.
SCENES = Path(
    os.environ.get("VRPREVIEW_SCENES")
    or Path(__file__).resolve().parents[1].parent / "shared" / "scenes"
)

# Outward-facing (counter-clockwise seen from outside) quads over a box's corners, ordered
# x-major as in box_mesh.
_QUADS = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]


def mesh(name: str, positions, indices) -> Mesh:
    pos = np.asarray(positions, np.float64)
    idx = np.asarray(indices, np.uint32).reshape(-1, 3)
    normals = vertex_normals(pos.astype(np.float32), idx)
    return Mesh(name, pos, normals, np.zeros((len(pos), 2), np.float32), idx)


def box_mesh(name: str, lo, hi, inward: bool = False, skip: tuple[int, ...] = ()) -> Mesh:
    """An axis-aligned box; ``inward`` for a room (walls seen from inside), ``skip`` faces left
    out by index into _QUADS (0: -x, 1: +x, 2: -y floor, 3: +y ceiling, 4: -z, 5: +z)."""
    (x0, y0, z0), (x1, y1, z1) = lo, hi
    corners = [(x, y, z) for x in (x0, x1) for y in (y0, y1) for z in (z0, z1)]
    tris = []
    for i, q in enumerate(_QUADS):
        if i in skip:
            continue
        q = q[::-1] if inward else q
        tris += [(q[0], q[1], q[2]), (q[0], q[2], q[3])]
    return mesh(name, corners, tris)


def plane_mesh(name: str, half: float, y: float = 0.0, up: bool = True) -> Mesh:
    c = [(-half, y, -half), (-half, y, half), (half, y, half), (half, y, -half)]
    return mesh(name, c, [(0, 1, 2), (0, 2, 3)] if up else [(0, 2, 1), (0, 3, 2)])


def scene_of(meshes: list[Mesh], name: str = "synthetic") -> Scene:
    return Scene(name, meshes, [Material("m")])


def furnished_room(lo, hi, prefix: str = "room", skip: tuple[int, ...] = ()) -> list[Mesh]:
    """A room (inward box) with a table and a cupboard in it."""
    (x0, y0, z0), (x1, _, z1) = lo, hi
    return [
        box_mesh(prefix, lo, hi, inward=True, skip=skip),
        box_mesh(f"{prefix}-table", (x0 + 1.0, y0, z0 + 1.0), (x0 + 2.2, y0 + 0.75, z0 + 1.8)),
        box_mesh(f"{prefix}-cupboard", (x1 - 0.6, y0, z1 - 2.0), (x1, y0 + 2.0, z1 - 0.5)),
    ]


def prepared(scene: Scene, unit_scale: float | None = None) -> Scene:
    """What loading does after reading: units, repair, spawn, lights, units check."""
    return finish_scene(place(scene, unit_scale).sanitized(), unit_scale is None)


def forward(yaw_deg: float) -> np.ndarray:
    a = math.radians(yaw_deg)
    return np.array([-math.sin(a), 0.0, -math.cos(a)])


def spawn_warnings(scene: Scene) -> list[str]:
    words = ("stand", "unit", "ceiling", "across", "default lights")
    return [w for w in scene.warnings if any(k in w for k in words)]


def assert_inside(scene: Scene, lo, hi, floor: float = 0.0, eye: float = EYE_HEIGHT_M) -> None:
    """On the floor of the box lo..hi at eye height, a body's width from its walls, facing in."""
    assert scene.floor_y == pytest.approx(floor, abs=0.02), scene.warnings
    x, y, z = scene.spawn.position
    assert y == pytest.approx(floor + eye, abs=0.02)
    assert lo[0] + 0.3 < x < hi[0] - 0.3 and lo[2] + 0.3 < z < hi[2] - 0.3, (x, z)
    caster = RayCaster(scene.triangles())
    d, _ = caster.cast(scene.spawn.position, forward(scene.spawn.yaw_deg))
    assert math.isfinite(d) and d < max(hi[0] - lo[0], hi[2] - lo[2]) + 0.1, "faces out"
    assert not spawn_warnings(scene), scene.warnings


CLASS_LO, CLASS_HI = (-4.5, 0.0, -6.0), (4.5, 3.0, 6.0)


def classroom(scale: float = 1.0, ground_half: float = 111.0) -> list[Mesh]:
    """The reported file: a 9 x 3 x 12 m classroom, its 2-triangle floor plane scaled to 222 m,
    a corridor running outside one wall, and desks; ``scale`` in file units per metre."""
    meshes = furnished_room(CLASS_LO, CLASS_HI, "classroom")
    meshes.append(plane_mesh("ground", ground_half))
    meshes.append(box_mesh("corridor", (4.7, 0.0, -9.0), (7.2, 2.8, 9.0), inward=True))
    for i, x in enumerate((-3.0, -1.0, 1.0, 3.0)):
        meshes.append(box_mesh(f"desk{i}", (x - 0.6, 0.0, -1.0), (x + 0.6, 0.72, -0.4)))
    if scale != 1.0:
        for m in meshes:
            m.positions = m.positions * scale
    return meshes


@pytest.mark.parametrize("ground_half", [111.0, 900.0])
def test_classroom_on_a_huge_plane_with_a_corridor_spawns_inside(ground_half: float) -> None:
    scene = prepared(scene_of(classroom(ground_half=ground_half)))
    assert_inside(scene, CLASS_LO, CLASS_HI)


def test_sky_box_around_the_room() -> None:
    meshes = furnished_room((-3.0, 0.0, -4.0), (3.0, 2.7, 4.0))
    meshes.append(box_mesh("sky", (-500.0, -500.0, -500.0), (500.0, 500.0, 500.0), inward=True))
    meshes.append(plane_mesh("terrain", 400.0, y=-0.05))
    assert_inside(prepared(scene_of(meshes)), (-3.0, 0.0, -4.0), (3.0, 2.7, 4.0))


def terrain_mesh(half: float = 100.0, n: int = 60) -> Mesh:
    """Rolling ground 2 * half wide, a metre below the house's floor and up to a metre above
    it far away, as a grid of n x n quads."""
    g = np.linspace(-half, half, n + 1)
    x, z = np.meshgrid(g, g, indexing="ij")
    y = -1.0 + 2.0 * (np.hypot(x, z) / half) ** 2 * (0.5 + 0.5 * np.sin(x / 7.0))
    pos = np.column_stack([x.ravel(), y.ravel(), z.ravel()])
    i = np.arange(n)[:, None] * (n + 1) + np.arange(n)[None, :]
    a, b, c, d = i.ravel(), i.ravel() + 1, i.ravel() + n + 2, i.ravel() + n + 1
    return mesh("terrain", pos, np.column_stack([a, b, c, a, c, d]).reshape(-1, 3))


def test_house_in_a_large_terrain() -> None:
    lo, hi = (10.0, 0.0, 20.0), (16.0, 2.6, 28.0)
    meshes = furnished_room(lo, hi, "house")
    meshes.append(box_mesh("slab", (9.8, -1.5, 19.8), (16.2, 0.0, 28.2)))
    meshes.append(terrain_mesh())
    assert_inside(prepared(scene_of(meshes)), lo, hi)


def test_room_with_an_open_side() -> None:
    meshes = furnished_room((-3.0, 0.0, -4.0), (3.0, 2.7, 4.0), skip=(5,))  # no +z wall
    assert_inside(prepared(scene_of(meshes)), (-3.0, 0.0, -4.0), (3.0, 2.7, 4.0))


def test_two_storeys_spawn_on_the_ground_floor() -> None:
    meshes = furnished_room((-4.0, 0.0, -5.0), (4.0, 2.8, 5.0), "ground")
    meshes += furnished_room((-4.0, 3.0, -5.0), (4.0, 5.8, 5.0), "upper")
    meshes.append(box_mesh("slab", (-4.0, 2.8, -5.0), (4.0, 3.0, 5.0)))
    assert_inside(prepared(scene_of(meshes)), (-4.0, 0.0, -5.0), (4.0, 2.8, 5.0))


def test_a_small_room_among_large_floors_below_is_still_found() -> None:
    # A basement three times the room's area one storey down is the "main" level.
    meshes = furnished_room((-6.0, -3.0, -6.0), (6.0, -0.2, 6.0), "basement")
    meshes += furnished_room((-3.0, 0.0, -3.0), (3.0, 2.7, 3.0), "room")
    scene = prepared(scene_of(meshes))
    assert scene.floor_y == pytest.approx(-3.0, abs=0.02)
    assert not spawn_warnings(scene)


def test_an_object_with_no_floor_is_viewed_from_outside() -> None:
    meshes = [box_mesh("crate", (-0.5, 0.0, -0.4), (0.5, 0.8, 0.4))]
    meshes.append(box_mesh("lid", (-0.55, 0.8, -0.45), (0.55, 0.85, 0.45)))
    scene = prepared(scene_of(meshes))
    assert scene.floor_y is None
    eye = np.asarray(scene.spawn.position)
    to_centre = np.array([0.0, 0.425, 0.0]) - eye
    assert np.linalg.norm(to_centre) > 0.8
    assert float(np.dot(forward(scene.spawn.yaw_deg), to_centre)) > 0.0
    assert not spawn_warnings(scene), scene.warnings


def test_room_in_centimetres_with_unit_scale() -> None:
    scene = prepared(scene_of(classroom(scale=100.0)), unit_scale=0.01)
    assert scene.unit_scale == 0.01
    assert_inside(scene, CLASS_LO, CLASS_HI)


def test_room_in_centimetres_read_as_metres_says_what_was_assumed() -> None:
    scene = prepared(scene_of(furnished_room((-300.0, 0.0, -400.0), (300.0, 270.0, 400.0))))
    note = [w for w in scene.warnings if "unit_scale" in w]
    assert len(note) == 1, scene.warnings
    assert "taken as metres" in note[0] and "centimetres" in note[0], note
    assert "set scene.unit_scale to 0.01" in note[0]


def test_no_room_in_metres_but_one_in_centimetres_or_inches() -> None:
    for factor, unit in ((100.0, "centimetres"), (1 / 0.0254, "inches")):
        scene = place(scene_of(classroom(scale=factor)), None).sanitized()
        note = placement.unit_warning(scene, spawn.outside_view(scene))
        assert note is not None and f"read as {unit}" in note, note
        assert f"set scene.unit_scale to {1 / factor:g}" in note


def test_hall_in_centimetres_read_as_metres_warns_about_the_ceiling() -> None:
    # Narrow enough for its walls to count as walls even at 100x: the ceiling test speaks.
    scene = prepared(scene_of(furnished_room((-60.0, 0.0, -80.0), (60.0, 270.0, 80.0))))
    note = [w for w in scene.warnings if "unit_scale" in w]
    assert len(note) == 1 and "ceiling is 270 m high" in note[0] and "0.01" in note[0], note


def test_cathedral_sized_nave_is_plausible() -> None:
    scene = prepared(scene_of(furnished_room((-20.0, 0.0, -8.0), (20.0, 30.0, 8.0))))
    assert_inside(scene, (-20.0, 0.0, -8.0), (20.0, 30.0, 8.0))


@pytest.mark.parametrize(
    "size, expect", [(5000.0, "km across"), (0.2, "cm across"), (1.0, None), (30.0, None)]
)
def test_model_size_units_warning(size: float, expect: str | None) -> None:
    scene = prepared(scene_of([box_mesh("thing", (0.0, 0.0, 0.0), (size, size / 4, size / 2))]))
    notes = [w for w in scene.warnings if "unit" in w]
    if expect is None:
        assert not notes, notes
    else:
        assert len(notes) == 1 and expect in notes[0], notes


def test_unit_scale_given_turns_the_check_off() -> None:
    scene = prepared(scene_of([box_mesh("thing", (0, 0, 0), (5000.0, 100.0, 100.0))]), 1.0)
    assert not [w for w in scene.warnings if "unit" in w]


def test_main_level_with_few_candidates_does_not_raise() -> None:
    # The reported ValueError: fewer than three candidates on every level.
    for floors in ([0.0], [0.0, 3.0], [0.0, 0.0]):
        mask = _main_level(np.asarray(floors))
        assert mask.dtype == bool and mask.any()


def expect_logged(caplog, text: str) -> None:
    """The failure was logged with its traceback, as it should be (and is not a test error)."""
    records = [r for r in caplog.records if text in r.getMessage()]
    assert records and all(r.exc_info for r in records)
    for record in records:
        record.expected = True


def test_spawn_failure_falls_back_to_an_outside_view(monkeypatch, caplog) -> None:
    def broken(*_a, **_k):
        raise ValueError("zero-size array to reduction operation minimum which has no identity")

    monkeypatch.setattr(spawn, "_interior_spawn", broken)
    scene = prepared(scene_of(furnished_room((-3.0, 0.0, -4.0), (3.0, 2.7, 4.0))))
    assert scene.floor_y is None and all(math.isfinite(v) for v in scene.spawn.position)
    assert any("could not find where to stand" in w for w in scene.warnings)
    assert scene.lights  # lit all the same
    expect_logged(caplog, "spawn search failed")


def test_default_lights_failure_falls_back_to_one_light(monkeypatch, caplog) -> None:
    def broken(*_a, **_k):
        raise IndexError("boom")

    monkeypatch.setattr("app.default_lights._interior_light_positions", broken)
    scene = prepared(scene_of(furnished_room((-3.0, 0.0, -4.0), (3.0, 2.7, 4.0))))
    assert len(scene.lights) == 1 and scene.floor_y == pytest.approx(0.0, abs=0.02)
    assert any("could not place the default lights" in w for w in scene.warnings)
    expect_logged(caplog, "default lights failed")


def test_units_check_failure_is_only_logged(monkeypatch, caplog) -> None:
    def broken(*_a, **_k):
        raise RuntimeError("boom")

    monkeypatch.setattr(placement, "unit_warning", broken)
    scene = prepared(scene_of(furnished_room((-3.0, 0.0, -4.0), (3.0, 2.7, 4.0))))
    assert scene.floor_y == pytest.approx(0.0, abs=0.02)
    expect_logged(caplog, "units check failed")


# ------------------------------------------------------------------------------------------
# the shared interiors: inside, on the main floor, at eye height, no warning about the spawn
# ------------------------------------------------------------------------------------------

INTERIORS = {
    # file, main floor height, (lo, hi) of the room the spawn must be in (x, z)
    "bathroom": ("interiors/bathroom/bathroom.gltf", 0.0, ((-2.66, -2.5), (2.5, -0.05))),
    "staircase": ("interiors/staircase/staircase.gltf", 0.0, ((-4.11, -5.2), (2.5, 5.13))),
    "living-room-2": (
        "interiors/living-room-2/living-room-2.gltf",
        0.0,
        ((-2.58, 0.37), (3.15, 8.18)),
    ),
    "sibenik": ("sibenik/sibenik.obj", -15.3, ((-20.1, -8.5), (20.1, 8.5))),
}


@pytest.fixture(scope="module", params=list(INTERIORS))
def interior(request):
    from app.loaders import load_scene

    rel, floor, box = INTERIORS[request.param]
    path = SCENES / rel
    if not path.exists():
        pytest.skip(f"{path} is not here")
    return load_scene(path), floor, box


def test_shared_interiors_spawn_inside_on_the_main_floor(interior) -> None:
    scene, floor, ((x0, z0), (x1, z1)) = interior
    assert scene.floor_y is not None and abs(scene.floor_y - floor) < 0.05, scene.floor_y
    x, y, z = scene.spawn.position
    assert y == pytest.approx(scene.floor_y + EYE_HEIGHT_M, abs=0.01)
    assert x0 + 0.3 < x < x1 - 0.3 and z0 + 0.3 < z < z1 - 0.3
    caster = RayCaster(scene.triangles())
    up, _ = caster.cast(scene.spawn.position, (0.0, 1.0, 0.0))
    assert math.isfinite(up) and up > 0.3, "no ceiling above the spawn"
    ahead, _ = caster.cast(scene.spawn.position, forward(scene.spawn.yaw_deg))
    assert math.isfinite(ahead) and ahead > 1.0, "facing a wall, or out of the room"
    assert not spawn_warnings(scene), scene.warnings


def write_obj(path: Path, meshes: list[Mesh]) -> Path:
    lines, first = [], 1
    for m in meshes:
        lines.append(f"o {m.name}")
        lines += [f"v {x:.6f} {y:.6f} {z:.6f}" for x, y, z in np.asarray(m.positions)]
        lines += [f"f {a + first} {b + first} {c + first}" for a, b, c in m.indices]
        first += len(m.positions)
    path.write_text("\n".join(lines) + "\n")
    return path


def test_loading_a_centimetre_file_with_and_without_unit_scale(tmp_path: Path) -> None:
    from app.loaders import LoadOptions, load_scene

    path = write_obj(tmp_path / "classroom_cm.obj", classroom(scale=100.0))
    scene = load_scene(path, LoadOptions(unit_scale=0.01))
    assert_inside(scene, CLASS_LO, CLASS_HI)
    auto = load_scene(path)
    assert any("set scene.unit_scale to 0.01" in w for w in auto.warnings), auto.warnings


def _z_up(meshes: list[Mesh]) -> list[Mesh]:
    """The meshes as a Z-up program saves them (x, y, z -> x, -z, y)."""
    out = []
    for m in meshes:
        p = np.asarray(m.positions, np.float64)
        out.append(mesh(m.name, np.stack([p[:, 0], -p[:, 2], p[:, 1]], axis=1), m.indices))
    return out


def test_a_z_up_room_is_turned_upright(tmp_path: Path) -> None:
    """3ds Max, Rhino and scanners may save a room with Z up: read as Y up it lay on its side,
    with no floor to stand on, and the viewer looked at it from outside. It is turned upright:
    one stands on its floor, inside, and a note says so. The same room saved Y up, and a
    lone object either way, are left as they are."""
    from app.loaders import load_scene

    room = furnished_room(CLASS_LO, CLASS_HI, "classroom")
    upright = load_scene(write_obj(tmp_path / "y_up.obj", room))
    assert_inside(upright, CLASS_LO, CLASS_HI)
    turned = load_scene(write_obj(tmp_path / "z_up.obj", _z_up(room)))
    assert turned.floor_y == pytest.approx(0.0, abs=0.02), turned.warnings
    x, y, z = turned.spawn.position
    assert y == pytest.approx(EYE_HEIGHT_M, abs=0.02)
    assert CLASS_LO[0] < x < CLASS_HI[0] and CLASS_LO[2] < z < CLASS_HI[2]
    assert any("turned upright" in w for w in turned.warnings)
    lo, hi = turned.bounds()
    assert hi[1] - lo[1] == pytest.approx(3.0, abs=0.01)  # the ceiling 3 m over the floor
    chair = [box_mesh("chair", (0, 0, 0), (0.5, 0.9, 0.5))]
    for name, meshes in (("chair_y.obj", chair), ("chair_z.obj", _z_up(chair))):
        lone = load_scene(write_obj(tmp_path / name, meshes))
        assert lone.floor_y is None and not any("upright" in w for w in lone.warnings)
