"""The built-in showroom, its default walkthrough and the texture-orientation test scene.

No OpenGL here: geometry, textures, lights and the walkthrough are checked as data, and the
walkthrough is checked for collisions with the app's own :class:`RayCaster`.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from app.raycast import RayCaster
from app.scene import Mesh, Scene
from assets.showroom import (
    HX,
    HZ,
    ROOM_H,
    build_showroom,
    build_texture_test_scene,
    shell_irradiance,
)
from assets.textures import PAINTING_ASPECTS, make_textures

ROOT = Path(__file__).resolve().parent.parent
PATH_FILE = ROOT / "assets" / "paths" / "showroom_walkthrough.json"
CLEARANCE_M = 0.3
#: Heights above the floor where the walkthrough must be clear: ankles (sofa feet, bench legs),
#: knees (0.3 m), table and seat tops (0.42-0.5 m), the keyboard (0.7 m), hips (1.0 m), the
#: piano lid and lamp shade (1.3-1.6 m).
PATH_HEIGHTS = (0.05, 0.15, 0.3, 0.42, 0.5, 0.6, 0.7, 0.8, 0.9, 1.0, 1.3, 1.6)
FOV_DEG = 95.0  # the default vertical field of view per eye


@pytest.fixture(scope="module")
def room() -> Scene:
    return build_showroom()


@pytest.fixture(scope="module")
def caster(room: Scene) -> RayCaster:
    return RayCaster(room.triangles(), room.triangle_owner())


@pytest.fixture(scope="module")
def path_keys() -> list[dict[str, Any]]:
    doc = json.loads(PATH_FILE.read_text(encoding="utf-8"))
    assert doc["vrpreview_path"] == 1
    assert doc["scene"] == "showroom"
    return list(doc["keys"])


def mesh(scene: Scene, name: str) -> Mesh:
    found = [m for m in scene.meshes if m.name == name]
    assert len(found) == 1, f"expected one mesh named {name!r}"
    return found[0]


def texture_of(scene: Scene, name: str) -> np.ndarray:
    tex = scene.materials[mesh(scene, name).material].texture
    assert tex is not None, f"{name} has no texture"
    return scene.textures[tex].rgba


# -- the room -----------------------------------------------------------------------------------


def test_build_is_deterministic(room: Scene) -> None:
    again = build_showroom()
    assert [m.name for m in again.meshes] == [m.name for m in room.meshes]
    for a, b in zip(room.meshes, again.meshes, strict=True):
        for field in ("positions", "normals", "uvs", "indices"):
            assert np.array_equal(getattr(a, field), getattr(b, field)), (a.name, field)
        assert a.material == b.material
    assert again.materials == room.materials
    assert [t.name for t in again.textures] == [t.name for t in room.textures]
    for ta, tb in zip(room.textures, again.textures, strict=True):
        assert np.array_equal(ta.rgba, tb.rgba), ta.name
    assert again.lights == room.lights
    assert again.spawn == room.spawn
    hundred = [build_showroom(100).lights, build_showroom(100).lights]
    assert hundred[0] == hundred[1]


def test_scene_identity_and_required_objects(room: Scene) -> None:
    assert room.name == "showroom"
    assert room.source == "built-in"
    assert room.warnings == []
    names = [m.name for m in room.meshes]
    assert len(names) == len(set(names)), "mesh names must be unique"
    required = {
        "floor",
        "ceiling",
        "wall_north",
        "wall_south",
        "wall_east",
        "wall_west",
        "piano",
        "chair",
        "sofa",
        "blinds",
        "light_switch",
        "rug",
        "coffee_table",
        "floor_lamp",
        "door",
        "window",
    } | {f"painting_{k}" for k in range(1, 6)}
    assert required <= set(names), required - set(names)
    assert room.triangle_count > 2000
    assert mesh(room, "blinds").triangle_count >= 20 * 12, "blinds need many slats"


def test_texture_sizes_and_paintings(room: Scene) -> None:
    for name in ("floor", "wall_north", "wall_south", "wall_east", "wall_west"):
        assert texture_of(room, name).shape == (512, 512, 4), name
    assert texture_of(room, "ceiling").shape == (64, 64, 4)
    paintings = [texture_of(room, f"painting_{k}") for k in range(1, 6)]
    for img in paintings:
        assert img.shape == (512, 512, 4) and img.dtype == np.uint8
    for i in range(5):  # five clearly different pictures
        for j in range(i + 1, 5):
            diff = np.abs(paintings[i][..., :3].astype(int) - paintings[j][..., :3].astype(int))
            assert diff.mean() > 30, (i + 1, j + 1)
    for img in paintings:  # art, not a flat fill
        assert img[..., :3].reshape(-1, 3).std(axis=0).max() > 25
    piano = room.materials[mesh(room, "piano").material]
    assert piano.roughness <= 0.15 and max(piano.base_color[:3]) < 0.02  # black, glossy


def test_texture_set_is_complete() -> None:
    # How long it takes is a benchmark figure (``scene_load_s`` in ``vrpreview bench``).
    textures = make_textures()
    assert set(PAINTING_ASPECTS) <= set(textures)
    assert {"wallpaper", "parquet", "ceiling", "fabric", "wood"} <= set(textures)


@pytest.mark.parametrize("name", ["wallpaper", "parquet", "ceiling", "fabric", "wood"])
def test_tiling_textures_are_seamless(room: Scene, name: str) -> None:
    img = next(t for t in room.textures if t.name == name).rgba[..., :3].astype(np.float64)
    for axis in (0, 1):
        steps = np.abs(np.diff(img, axis=axis)).mean(axis=(1 - axis, 2))  # per row/column edge
        wrap = np.abs(np.take(img, 0, axis=axis) - np.take(img, -1, axis=axis)).mean()
        assert wrap <= np.percentile(steps, 99) + 1e-9, (name, axis, wrap)


def test_shell_uvs_repeat_and_paintings_do_not(room: Scene) -> None:
    for name in ("floor", "wall_north", "wall_south", "wall_east", "wall_west", "ceiling"):
        m = mesh(room, name)
        span = m.uvs.max(axis=0) - m.uvs.min(axis=0)
        assert span.max() > 1.0, (name, span)
        assert room.textures[room.materials[m.material].texture].repeat  # type: ignore[index]
    floor_span = np.ptp(mesh(room, "floor").uvs, axis=0)
    assert np.all(floor_span > 1.0)
    for k in range(1, 6):
        m = mesh(room, f"painting_{k}")
        uv = m.uvs
        assert uv.min() >= 0.0 and uv.max() <= 1.0
        assert np.allclose(np.ptp(uv, axis=0), 1.0)
        assert not room.textures[room.materials[m.material].texture].repeat  # type: ignore[index]


def test_normals_are_unit_and_match_the_winding(room: Scene) -> None:
    for m in room.meshes:
        lengths = np.linalg.norm(m.normals, axis=1)
        assert np.allclose(lengths, 1.0, atol=1e-4), m.name
        tri = m.positions[m.indices].astype(np.float64)
        geometric = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        vertex = m.normals[m.indices].sum(axis=1)
        assert np.all(np.einsum("ij,ij->i", geometric, vertex) > 0), (
            f"{m.name}: triangles not counter-clockwise seen from their normal side"
        )


def test_shell_faces_into_the_room(room: Scene) -> None:
    expected = {
        "floor": (0, 1, 0),
        "ceiling": (0, -1, 0),
        "wall_north": (0, 0, 1),
        "wall_south": (0, 0, -1),
        "wall_east": (-1, 0, 0),
        "wall_west": (1, 0, 0),
    }
    for name, normal in expected.items():
        m = mesh(room, name)
        assert np.allclose(m.normals, normal, atol=1e-6), name
        # the plane sits on the room's boundary, and the room centre is in front of it
        centre = np.array([0.0, ROOM_H / 2, 0.0])
        to_centre = centre - m.positions.mean(axis=0)
        assert float(np.dot(to_centre, normal)) > 1.0, name
    lo, hi = room.bounds()
    assert np.allclose(lo, (-HX, 0.0, -HZ), atol=1e-5)
    assert np.allclose(hi, (HX, ROOM_H, HZ), atol=1e-5)


def test_lights() -> None:
    four = build_showroom().lights
    assert len(four) == 4
    for light in four:
        assert abs(light.position[1] - 2.6) < 0.2
        assert 5.0 <= light.range_m <= 7.0
        assert light.intensity > 0
        r, g, b = light.color
        assert r >= g >= b > 0.5  # warm white
    many = build_showroom(100)
    assert many.name == "showroom-100"
    assert len(many.lights) == 100
    pos = np.array([light.position for light in many.lights])
    assert np.all(np.abs(pos[:, 0]) < HX) and np.all(np.abs(pos[:, 2]) < HZ)
    assert np.all((pos[:, 1] > 0.0) & (pos[:, 1] < ROOM_H))
    assert len({tuple(p) for p in pos.round(3)}) == 100
    assert all(abs(light.range_m - 2.5) < 0.3 for light in many.lights)
    ratio = shell_irradiance(many.lights) / shell_irradiance(four)
    assert 0.9 < ratio < 1.1, ratio
    # spread through the room: every quarter of the floor plan has its share
    for sx in (-1, 1):
        for sz in (-1, 1):
            n = np.sum((np.sign(pos[:, 0]) == sx) & (np.sign(pos[:, 2]) == sz))
            assert 15 <= n <= 35


def test_the_eight_lamp_showroom_is_built_in() -> None:
    """``showroom-8``: the bench's scene for issue 14's target (8 shadowed lamps)."""
    from app import scenes

    eight = scenes.resolve("showroom-8")
    assert eight.name == "showroom-8" and eight.source == "built-in"
    assert len(eight.lights) == 8
    assert all(light.casts_shadows and light.kind == "point" for light in eight.lights)
    assert scenes.default_path(eight).scene == "showroom"  # the showroom's walkthrough
    ratio = shell_irradiance(eight.lights) / shell_irradiance(build_showroom().lights)
    assert 0.9 < ratio < 1.1, ratio


def test_spawn(room: Scene, caster: RayCaster) -> None:
    x, y, z = room.spawn.position
    assert abs(x) < HX - CLEARANCE_M and abs(z) < HZ - CLEARANCE_M
    assert y == pytest.approx(1.6)
    assert room.floor_y == 0.0
    assert _clear_around(caster, np.array([[x, z]]), (0.3, 1.0, 1.6))
    # it looks into the room: the view ray runs at least 4 m before it meets something
    dist, _ = caster.cast(room.spawn.position, _forward(room.spawn.yaw_deg, 0.0))
    assert dist > 4.0


# -- the walkthrough ----------------------------------------------------------------------------


def _forward(yaw_deg: float, pitch_deg: float) -> np.ndarray:
    y, p = math.radians(yaw_deg), math.radians(pitch_deg)
    return np.array([-math.sin(y) * math.cos(p), math.sin(p), -math.cos(y) * math.cos(p)])


def _gaze_ray(key: dict[str, Any]) -> np.ndarray:
    """Direction through the gaze point (square viewport; exact for a centred gaze)."""
    fwd = _forward(key["yaw_deg"], key["pitch_deg"])
    yaw = math.radians(key["yaw_deg"])
    right = np.array([math.cos(yaw), 0.0, -math.sin(yaw)])
    up = np.cross(right, fwd)
    t = math.tan(math.radians(FOV_DEG) / 2)
    gx, gy = key["gaze"]
    d = fwd + (2 * gx - 1) * t * right + (1 - 2 * gy) * t * up
    return d / np.linalg.norm(d)


def _lerp_key(a: dict[str, Any], b: dict[str, Any], f: float) -> dict[str, Any]:
    out = {k: a[k] for k in ("gaze_fixed",)}
    for k in ("position", "gaze"):
        out[k] = [u + (v - u) * f for u, v in zip(a[k], b[k], strict=True)]
    for k in ("t", "yaw_deg", "pitch_deg"):
        out[k] = a[k] + (b[k] - a[k]) * f
    return out


def _clear_around(
    caster: RayCaster,
    xz: np.ndarray,
    heights: tuple[float, ...],
    radius: float = CLEARANCE_M,
    directions: int = 24,
) -> bool:
    """True when nothing lies within ``radius`` horizontally of any point, at every height."""
    ang = np.linspace(0.0, 2 * np.pi, directions, endpoint=False)
    dirs = np.stack([np.cos(ang), np.zeros_like(ang), np.sin(ang)], axis=1)
    origins, rays = [], []
    for h in heights:
        pts = np.stack([xz[:, 0], np.full(len(xz), h), xz[:, 1]], axis=1)
        origins.append(np.repeat(pts, directions, axis=0))
        rays.append(np.tile(dirs, (len(xz), 1)))
    dist, _ = caster.cast_many(np.concatenate(origins), np.concatenate(rays), t_max=radius)
    return bool(np.all(np.isinf(dist)))


def _segment_state(a: dict[str, Any], b: dict[str, Any]) -> tuple[str, str] | None:
    moved = (
        not np.allclose(a["position"], b["position"], atol=1e-6)
        or abs(a["yaw_deg"] - b["yaw_deg"]) > 1e-6
        or abs(a["pitch_deg"] - b["pitch_deg"]) > 1e-6
    )
    view = "moving" if moved else "still"
    if a["gaze_fixed"]:
        return view, "fixed"
    if not np.allclose(a["gaze"], b["gaze"], atol=1e-6):
        return view, "gaze moving"
    return None


def test_path_format(room: Scene, path_keys: list[dict[str, Any]]) -> None:
    assert len(path_keys) >= 4
    fields = {"t", "position", "yaw_deg", "pitch_deg", "gaze", "gaze_fixed"}
    for key in path_keys:
        assert set(key) == fields
        assert len(key["position"]) == 3 and len(key["gaze"]) == 2
        assert isinstance(key["gaze_fixed"], bool)
        assert all(
            math.isfinite(v)
            for v in [*key["position"], key["yaw_deg"], key["pitch_deg"], *key["gaze"]]
        )
        assert key["position"][1] == pytest.approx(1.6)
        assert all(0.0 <= g <= 1.0 for g in key["gaze"])
        assert -89.0 < key["pitch_deg"] < 89.0
    start = path_keys[0]
    assert math.dist(start["position"], room.spawn.position) < 0.5, "it starts at the spawn"
    times = [key["t"] for key in path_keys]
    assert times[0] == 0.0
    assert all(b > a for a, b in zip(times, times[1:], strict=False)), "t must increase"
    assert 8.0 <= times[-1] <= 14.0, "about ten seconds"
    for a, b in zip(path_keys, path_keys[1:], strict=False):
        step = math.dist(a["position"], b["position"]) / (b["t"] - a["t"])
        assert step < 2.0, "walking pace, not a teleport"


def test_path_covers_the_four_states(path_keys: list[dict[str, Any]]) -> None:
    spent: dict[tuple[str, str], float] = {}
    for a, b in zip(path_keys, path_keys[1:], strict=False):
        state = _segment_state(a, b)
        if state is not None:
            spent[state] = spent.get(state, 0.0) + b["t"] - a["t"]
    for state in (
        ("still", "gaze moving"),
        ("moving", "gaze moving"),
        ("still", "fixed"),
        ("moving", "fixed"),
    ):
        assert spent.get(state, 0.0) >= 0.5, (state, spent)


def test_fixed_gaze_rests_on_a_painting(
    room: Scene, caster: RayCaster, path_keys: list[dict[str, Any]]
) -> None:
    names = [m.name for m in room.meshes]
    seen: set[str] = set()
    for a, b in zip(path_keys, path_keys[1:], strict=False):
        if not a["gaze_fixed"]:
            continue
        for f in (0.0, 0.5, 1.0):
            key = _lerp_key(a, b, f)
            _, owner = caster.cast(key["position"], _gaze_ray(key))
            assert owner >= 0 and names[owner].startswith("painting_"), (key["t"], owner)
            seen.add(names[owner])
    assert len(seen) >= 1


def test_path_stays_clear_of_furniture_and_walls(
    room: Scene, caster: RayCaster, path_keys: list[dict[str, Any]]
) -> None:
    floor = room.floor_y or 0.0
    heights = tuple(floor + h for h in PATH_HEIGHTS)
    for a, b in zip(path_keys, path_keys[1:], strict=False):
        pa = np.array([a["position"][0], a["position"][2]])
        pb = np.array([b["position"][0], b["position"][2]])
        assert np.all(np.abs(pa) < [HX - CLEARANCE_M, HZ - CLEARANCE_M])
        length = float(np.linalg.norm(pb - pa))
        if length > 1e-9:  # nothing in the way along the segment
            d = np.array([pb[0] - pa[0], 0.0, pb[1] - pa[1]]) / length
            for h in heights:
                dist, who = caster.cast((pa[0], h, pa[1]), d, t_max=length + CLEARANCE_M)
                assert math.isinf(dist), (a["t"], h, who)
        n = max(2, int(math.ceil(length / 0.05)) + 1)
        samples = pa + np.linspace(0.0, 1.0, n)[:, None] * (pb - pa)
        assert _clear_around(caster, samples, heights), (a["t"], b["t"])


def test_clearance_check_would_catch_a_collision(caster: RayCaster) -> None:
    # the check itself must see furniture: standing in the sofa or at the keyboard fails
    assert not _clear_around(caster, np.array([[3.5, -0.5]]), (0.3, 1.0))
    assert not _clear_around(caster, np.array([[-1.63, -0.96]]), (0.7,))
    assert not _clear_around(caster, np.array([[1.0, -0.25]]), (0.3,))  # by the chair
    assert not _clear_around(caster, np.array([[HX - 0.1, 0.0]]), (1.0,))


# -- the texture test scene ---------------------------------------------------------------------


def _uv_at(m: Mesh, point: np.ndarray) -> np.ndarray:
    for tri in m.indices:
        p = m.positions[tri].astype(np.float64)
        e1, e2, r = p[1] - p[0], p[2] - p[0], point - p[0]
        d00, d01, d11 = e1 @ e1, e1 @ e2, e2 @ e2
        den = d00 * d11 - d01 * d01
        v = (d11 * (r @ e1) - d01 * (r @ e2)) / den
        w = (d00 * (r @ e2) - d01 * (r @ e1)) / den
        if v >= -1e-9 and w >= -1e-9 and v + w <= 1 + 1e-9:
            return (1 - v - w) * m.uvs[tri[0]] + v * m.uvs[tri[1]] + w * m.uvs[tri[2]]
    raise AssertionError(f"{point} is not on the mesh")


def test_texture_test_scene_quadrants() -> None:
    scene = build_texture_test_scene()
    assert scene.name == "texture-test"
    assert scene.spawn.position == (0.0, 1.6, 0.0) and scene.spawn.yaw_deg == 0.0
    assert len(scene.meshes) == 1 and len(scene.lights) == 1
    light = scene.lights[0]
    assert light.position == (0.0, 1.6, 0.0) and light.range_m == 10.0 and light.intensity > 0
    m = scene.meshes[0]
    assert np.allclose(m.positions[:, 2], -2.0)
    assert np.allclose(m.positions.min(axis=0)[:2], (-1.0, 0.6))
    assert np.allclose(m.positions.max(axis=0)[:2], (1.0, 2.6))
    assert np.allclose(m.normals, (0.0, 0.0, 1.0))
    tri = m.positions[m.indices].astype(np.float64)
    assert np.all(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])[:, 2] > 0)
    assert m.uvs.min() == 0.0 and m.uvs.max() == 1.0
    tex = scene.textures[scene.materials[m.material].texture]  # type: ignore[index]
    assert not tex.repeat
    img = tex.rgba
    h, w = img.shape[:2]
    # Seen from the spawn looking down -Z, screen right is +x and screen up is +y.
    expected = {
        (-1, 1): (255, 0, 0),
        (1, 1): (0, 255, 0),
        (-1, -1): (0, 0, 255),
        (1, -1): (255, 255, 255),
    }
    for (sx, sy), colour in expected.items():
        for off in (0.25, 0.5, 0.75):
            point = np.array([sx * off, 1.6 + sy * off, -2.0])
            u, v = _uv_at(m, point)
            row = min(int((1.0 - v) * h), h - 1)  # OpenGL: v = 0 is the image's bottom row
            col = min(int(u * w), w - 1)
            assert tuple(img[row, col, :3]) == colour, ((sx, sy), off)
