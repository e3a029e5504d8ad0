"""The built-in vection corridor and its automatic walk (the CPS paper's benchmark setting).

Geometry, lights and the walk are checked as data with the app's own :class:`RayCaster`; one
small headless render checks that the walk's frame 120 shows a lit corridor in stereo.
"""

from __future__ import annotations

import numpy as np
import pytest

from app.paths import FIXED_DT, CameraPath
from app.raycast import RayCaster
from app.scene import Scene
from assets.corridor import (
    BAY_M,
    BEAM_H,
    HEIGHT,
    HW,
    LENGTH,
    PILASTER_W,
    build_corridor,
    corridor_irradiance,
    corridor_walk,
    irradiance_profile,
    make_corridor_lights,
)
from tests.test_showroom import _clear_around as clear_around

CLEARANCE_M = 0.4
#: Body heights the walk must keep clear: ankles, knees, seat and cabinet tops, hips, shoulders,
#: the eyes and the top of the head.
BODY_HEIGHTS = (0.05, 0.15, 0.3, 0.45, 0.6, 0.8, 1.0, 1.3, 1.6, 1.8)


@pytest.fixture(scope="module")
def corridor() -> Scene:
    return build_corridor()


@pytest.fixture(scope="module")
def caster(corridor: Scene) -> RayCaster:
    return RayCaster(corridor.triangles(), corridor.triangle_owner())


@pytest.fixture(scope="module")
def walk() -> CameraPath:
    return corridor_walk()


def _names(scene: Scene) -> list[str]:
    return [m.name for m in scene.meshes]


def _positions(walk: CameraPath, step_s: float = 0.02) -> np.ndarray:
    """Eye positions along the walk, sampled finely (the path is linear between keys)."""
    times = np.arange(0.0, walk.duration + 1e-9, step_s)
    return np.array([walk.sample(float(t)).position for t in times])


# -- the scene ----------------------------------------------------------------------------------


def test_scene_is_clean_named_and_furnished(corridor: Scene) -> None:
    assert corridor.name == "corridor" and corridor.source == "built-in"
    assert corridor.warnings == [], corridor.warnings
    names = _names(corridor)
    assert len(names) == len(set(names)), "mesh names must be unique"
    required = {
        "floor",
        "ceiling",
        "wall_left",
        "wall_right",
        "wall_far",
        "wall_near",
        "carpet_runner",
        "pilasters",
        "ceiling_beams",
        "window",
        "exit_sign",
    }
    assert required <= set(names), required - set(names)
    for kind, least in (
        ("door_", 10),
        ("bench_", 5),
        ("cabinet_", 5),
        ("planter_", 6),
        ("painting_", 10),
    ):
        count = sum(1 for n in names if n.startswith(kind) and n.count("_") == 1)
        assert count >= least, (kind, count)
    lo, hi = corridor.bounds()
    assert np.allclose(lo, (-HW, 0.0, -LENGTH), atol=1e-5)
    assert np.allclose(hi, (HW, HEIGHT, 0.0), atol=1e-5)
    sx, sy, sz = corridor.spawn.position
    assert (sx, sy) == (0.0, 1.6) and -3.0 < sz < -1.0, "at the near end, eye height"
    assert corridor.spawn.yaw_deg == 0.0, "looking down the corridor (-Z)"


def test_normals_are_unit_and_match_the_winding(corridor: Scene) -> None:
    for m in corridor.meshes:
        assert np.allclose(np.linalg.norm(m.normals, axis=1), 1.0, atol=1e-4), m.name
        tri = m.positions[m.indices].astype(np.float64)
        geometric = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        vertex = m.normals[m.indices].sum(axis=1)
        assert np.all(np.einsum("ij,ij->i", geometric, vertex) > 0), m.name


def test_shell_is_textured_with_repeating_textures(corridor: Scene) -> None:
    for name in ("floor", "ceiling", "wall_left", "wall_right", "wall_left_lower", "carpet_runner"):
        m = next(m for m in corridor.meshes if m.name == name)
        tex_index = corridor.materials[m.material].texture
        assert tex_index is not None, name
        assert corridor.textures[tex_index].repeat, name
        assert np.ptp(m.uvs, axis=0).max() > 5.0, (name, "the texture must repeat")


@pytest.mark.parametrize(
    "name,axes",
    [("plaster", (0, 1)), ("terrazzo", (0, 1)), ("ceiling_tiles", (0, 1)), ("carpet_runner", (0,))],
)
def test_corridor_textures_tile_seamlessly(
    corridor: Scene, name: str, axes: tuple[int, ...]
) -> None:
    img = next(t for t in corridor.textures if t.name == name).rgba[..., :3].astype(np.float64)
    assert img.std(axis=(0, 1)).max() > 3.0, "a texture, not a flat fill"
    for axis in axes:  # the runner repeats only along its length (image rows)
        steps = np.abs(np.diff(img, axis=axis)).mean(axis=(1 - axis, 2))
        wrap = np.abs(np.take(img, 0, axis=axis) - np.take(img, -1, axis=axis)).mean()
        assert wrap <= np.percentile(steps, 99) + 1e-9, (name, axis, wrap)


def test_builtin_registration() -> None:
    from app import scenes

    assert "corridor" in scenes.BUILTIN
    assert scenes.BUILTIN_PATHS["corridor"] == "corridor_walk"
    path = scenes.resolve_path("corridor_walk")
    assert path.scene == "corridor" and len(path.keys) == len(corridor_walk().keys)


def test_side_walls_close_the_corridor(caster: RayCaster, walk: CameraPath) -> None:
    pos = _positions(walk, 0.1)
    for h in (0.3, 1.0, 1.6, 2.4):
        origins = pos.copy()
        origins[:, 1] = h
        for side in (-1.0, 1.0):
            dist, _ = caster.cast_many(origins, np.tile([side, 0.0, 0.0], (len(pos), 1)))
            assert np.all(dist <= 1.6), (h, side, float(dist.max()))
        for along in (-1.0, 1.0):  # and both ends are closed too
            dist, _ = caster.cast_many(origins, np.tile([0.0, 0.0, along], (len(pos), 1)))
            assert np.all(np.isfinite(dist)), (h, along)


# -- lights -------------------------------------------------------------------------------------


@pytest.mark.parametrize("count", [0, 1, 4, 37, 100])
def test_light_count_is_honoured(count: int) -> None:
    lights = make_corridor_lights(count)
    assert len(lights) == count
    if count == 0:
        return
    pos = np.array([light.position for light in lights])
    assert np.all(np.abs(pos[:, 0]) < HW - 0.3)
    assert np.all((pos[:, 2] < 0.0) & (pos[:, 2] > -LENGTH))
    assert np.all((pos[:, 1] > 2.0) & (pos[:, 1] < HEIGHT)), "along the ceiling"
    s = -pos[:, 2]
    under_beam = np.abs(s - np.round(s / BAY_M) * BAY_M) < PILASTER_W / 2
    assert np.all(pos[under_beam, 1] < HEIGHT - BEAM_H), "no light inside a ceiling beam"
    assert len({tuple(p) for p in pos.round(3)}) == count
    assert all(light.intensity > 0 and light.range_m >= 2.9 for light in lights)
    assert corridor_irradiance(lights) == pytest.approx(
        corridor_irradiance(make_corridor_lights(4)), rel=0.01
    ), "the same overall brightness at every count"
    assert make_corridor_lights(count) == lights, "seeded: the same lights every time"


def test_lights_light_the_whole_corridor_evenly() -> None:
    many = irradiance_profile(make_corridor_lights(100))
    assert many.min() / many.max() > 0.75, "100 lights: an even corridor"
    # Four ceiling lights 10 m apart leave pools of light (deep ones under the physical inverse
    # square), but their ranges overlap so that the pools merge: every point of floor and walls
    # is within reach of at least two of them, and none falls below a tenth of the mean.
    lights = make_corridor_lights(4)
    four = irradiance_profile(lights)
    assert four.min() > 0.1 * many.mean()
    ends = np.array(
        [[0.0, 0.0, -0.5], [HW, 0.0, -0.5], [0.0, 0.0, 0.5 - LENGTH], [-HW, 2.5, 0.5 - LENGTH]]
    )
    pos = np.array([light.position for light in lights])
    for point in ends:
        reach = np.linalg.norm(pos - point, axis=1) < [light.range_m for light in lights]
        assert reach.sum() >= 2, point
    with pytest.raises(ValueError):
        make_corridor_lights(-1)


def test_scene_takes_the_light_count() -> None:
    few = build_corridor(lights=4)
    assert few.name == "corridor-4" and len(few.lights) == 4 and few.warnings == []


def test_lights_are_not_buried_in_geometry(corridor: Scene, caster: RayCaster) -> None:
    names = _names(corridor)
    pos = np.array([light.position for light in corridor.lights])
    up, who = caster.cast_many(pos, np.tile([0.0, 1.0, 0.0], (len(pos), 1)))
    assert {names[w] for w in who} <= {"ceiling", "ceiling_beams", "downlights"}
    down, _ = caster.cast_many(pos, np.tile([0.0, -1.0, 0.0], (len(pos), 1)))
    assert np.all(down > 1.0), "nothing hangs right under a light"


# -- the walk -----------------------------------------------------------------------------------


def test_walk_moves_forward_at_walking_pace(corridor: Scene, walk: CameraPath) -> None:
    assert walk.scene == "corridor"
    first, last = walk.keys[0], walk.keys[-1]
    assert first.position == pytest.approx(corridor.spawn.position)
    assert first.yaw_deg == pytest.approx(corridor.spawn.yaw_deg)
    assert first.pitch_deg == pytest.approx(corridor.spawn.pitch_deg)
    assert 11.5 <= walk.duration <= 12.5
    assert walk.frame_count(FIXED_DT) >= 700
    distance = first.position[2] - last.position[2]
    assert distance / walk.duration == pytest.approx(2.5, rel=0.02)
    z = np.array([k.position[2] for k in walk.keys])
    assert np.all(np.diff(z) < 0), "always forward, down -Z"
    for key in walk.keys:
        assert key.position[1] == pytest.approx(1.6)
        assert key.gaze == (0.5, 0.5) and not key.gaze_fixed


def test_walk_weaves_gently(walk: CameraPath) -> None:
    x = np.array([k.position[0] for k in walk.keys])
    yaw = np.array([k.yaw_deg for k in walk.keys])
    pitch = np.array([k.pitch_deg for k in walk.keys])
    assert 0.1 <= np.abs(x).max() <= 0.25, "a little sideways sway"
    assert np.sum(np.diff(np.sign(x[np.abs(x) > 0.02])) != 0) >= 4, "from side to side"
    assert 1.0 < np.abs(yaw).max() < 10.0 and np.ptp(pitch) < 5.0
    steps = np.abs(np.diff(yaw)) / np.diff([k.t for k in walk.keys])
    assert steps.max() < 15.0, "turns in degrees per second, never a jerk"


def test_walk_stays_clear_of_walls_and_furniture(
    corridor: Scene, caster: RayCaster, walk: CameraPath
) -> None:
    pos = _positions(walk, 0.02)  # 5 cm apart at 2.5 m/s
    assert np.all(np.abs(pos[:, 0]) < HW - CLEARANCE_M)
    assert clear_around(caster, pos[:, [0, 2]], BODY_HEIGHTS, CLEARANCE_M, 32)
    # nothing stands in the way between samples either
    for h in BODY_HEIGHTS:
        a = pos[:-1].copy()
        a[:, 1] = h
        d = np.diff(pos, axis=0)
        length = np.linalg.norm(d, axis=1)
        dist, _ = caster.cast_many(a, d, t_max=float(length.max()) + CLEARANCE_M)
        assert np.all(np.isinf(dist)), h


def test_clearance_check_would_catch_a_collision(corridor: Scene, caster: RayCaster) -> None:
    cabinet = next(m for m in corridor.meshes if m.name == "cabinet_L1")
    lo, hi = cabinet.bounds()
    front_x = float(hi[0]) + 0.3  # 30 cm in front of a cabinet on the left wall
    assert not clear_around(
        caster, np.array([[front_x, float(lo[2] + hi[2]) / 2]]), (0.45,), CLEARANCE_M, 32
    )
    assert not clear_around(caster, np.array([[HW - 0.3, -20.0]]), (1.6,), CLEARANCE_M, 32)


# -- a frame ------------------------------------------------------------------------------------


def test_walk_frame_120_renders_a_lit_corridor_in_stereo(corridor: Scene, walk: CameraPath) -> None:
    from app.session import Session
    from app.settings import Settings
    from render.offscreen import OffscreenHost

    settings = Settings()
    session = Session(settings)
    session.set_scene(corridor, walk)
    with OffscreenHost(320, 180, settings) as host:
        host.set_scene(corridor)
        session.apply_path_frame(120)
        host.set_text_image(None)
        img = host.draw(session.frame_input(*host.eye_size))
        ids = host.object_ids(session.frame_input(*host.eye_size))
        assert not host.renderer.errors
    assert img.shape == (180, 320, 3)
    left, right = img[:, :160].astype(float), img[:, 160:].astype(float)
    for eye, owner in zip((left, right), ids):
        assert 40 < eye.mean() < 210 and eye.std() > 25  # lit, textured, not blown out
        # Enclosed: hardly any background (no surface; the filmic curve's toe shows the navy
        # carpet's darkest texels black, so dark pixels do not tell).
        assert (owner < 0).mean() < 0.02
        runner = eye[150:, 60:100].mean(axis=(0, 1))  # straight down: the navy carpet
        assert runner[2] > runner[0] and runner.mean() < 0.5 * eye.mean()
    assert np.abs(left - right).mean() > 2
