"""Walking that feels right: stairs up and down, not onto tables, falling off ledges, thin walls
at running speed, flying, and a scene with no floor (synthetic scenes, the showroom, the shared
staircase)."""

from __future__ import annotations

import numpy as np
import pytest

from app.navigation import STEP_M, Walker
from app.raycast import RayCaster
from app.settings import NavigationSettings
from tests.test_spawn import SCENES, box_mesh, scene_of

EYE = 1.6
NORTH, WEST, SOUTH, EAST = 0.0, 90.0, 180.0, 270.0  # yaw: 0 looks down -z, 90 down -x


def caster_of(meshes) -> RayCaster:
    return RayCaster(scene_of(meshes).triangles())


def hall(half: float = 10.0, height: float = 3.0) -> list:
    """An empty 20 x 20 x 3 m room (floor at 0)."""
    return [box_mesh("hall", (-half, 0.0, -half), (half, height, half), inward=True)]


def walk(w: Walker, yaw: float, seconds: float, dt: float = 1 / 60, until=None) -> list[float]:
    """Hold W facing ``yaw``; the eye heights seen on the way."""
    w.yaw_deg = yaw
    heights = []
    for _ in range(int(round(seconds / dt))):
        w.step(1.0, 0.0, 0.0, dt)
        heights.append(float(w.position[1]))
        if until is not None and until(w.position):
            break
    return heights


def stairs(riser: float = 0.18, tread: float = 0.28, n: int = 10) -> list:
    """A flight climbing towards -z from z = 0 to a landing (n risers up), in a tall hall."""
    meshes = hall(height=6.0)
    for k in range(1, n + 1):
        z1 = -(k - 1) * tread
        z0 = -k * tread if k < n else -k * tread - 3.0  # the last step is the landing
        meshes.append(box_mesh(f"step{k}", (-0.6, 0.0, z0), (0.6, k * riser, z1)))
    return meshes


@pytest.mark.parametrize("riser, tread", [(0.18, 0.28), (0.3, 0.43)])
def test_stairs_up_and_down(riser: float, tread: float) -> None:
    n = 10
    w = Walker(NavigationSettings(), caster_of(stairs(riser, tread, n)))
    w.place((0.0, EYE, 1.0), NORTH)
    up = walk(w, NORTH, 8.0, until=lambda p: p[2] < -n * tread - 1.0)
    assert w.position[1] == pytest.approx(n * riser + EYE, abs=0.01), "did not reach the top"
    assert max(np.diff(up)) <= riser + 1e-6, "more than a riser at once"
    assert min(np.diff(up)) >= -1e-6, "a step down on the way up"
    down = walk(w, SOUTH, 8.0, until=lambda p: p[2] > 1.0)
    assert max(np.diff(down)) <= 1e-6 and min(np.diff(down)) >= -riser - 1e-6
    assert w.position[2] > 1.0 and w.position[1] == pytest.approx(EYE, abs=0.01)


def coffee_table(shelf: bool = True) -> list:
    """A 0.44 m coffee table (a 3 cm top on four legs) with a lower shelf at 0.15 m, north of
    the start."""
    x0, x1, z0, z1 = -0.6, 0.6, -2.4, -1.8
    parts = [box_mesh("top", (x0, 0.41, z0), (x1, 0.44, z1))]
    if shelf:
        parts.append(box_mesh("shelf", (x0 + 0.04, 0.12, z0 + 0.04), (x1 - 0.04, 0.15, z1 - 0.04)))
    for i, (x, z) in enumerate(
        [(x0, z0), (x1 - 0.04, z0), (x0, z1 - 0.04), (x1 - 0.04, z1 - 0.04)]
    ):
        parts.append(box_mesh(f"leg{i}", (x, 0.0, z), (x + 0.04, 0.41, z + 0.04)))
    return hall() + parts


@pytest.mark.parametrize("shelf", [True, False], ids=["lower-shelf", "no-shelf"])
@pytest.mark.parametrize("start_x", [0.0, 0.45])
def test_coffee_table_is_not_climbed(shelf: bool, start_x: float) -> None:
    w = Walker(NavigationSettings(), caster_of(coffee_table(shelf)))
    w.place((start_x, EYE, 0.0), NORTH)
    heights = walk(w, NORTH, 4.0)
    assert max(heights) == pytest.approx(EYE, abs=1e-6) and min(heights) == pytest.approx(EYE)
    assert w.position[2] > -1.8, "walked into (or under) the table"


def test_a_bed_and_a_sofa_are_not_climbed() -> None:
    meshes = hall() + [
        box_mesh("bed", (-1.0, 0.0, -4.0), (1.0, 0.5, -2.0)),
        box_mesh("sofa-seat", (2.0, 0.0, -4.0), (4.0, 0.45, -2.0)),
    ]
    for x in (0.0, 3.0):
        w = Walker(NavigationSettings(), caster_of(meshes))
        w.place((x, EYE, 0.0), NORTH)
        heights = walk(w, NORTH, 4.0)
        assert max(heights) == pytest.approx(EYE) and w.position[2] > -2.0


def test_a_low_platform_with_head_room_is_stepped_onto() -> None:
    w = Walker(
        NavigationSettings(), caster_of(hall() + [box_mesh("dais", (-3, 0, -6), (3, 0.2, -2))])
    )
    w.place((0.0, EYE, 0.0), NORTH)
    walk(w, NORTH, 3.0)
    assert w.position[2] < -2.5 and w.position[1] == pytest.approx(0.2 + EYE)


def test_walking_off_a_ledge_falls_to_the_floor_below() -> None:
    meshes = hall(height=4.0) + [box_mesh("ledge", (-10.0, 0.0, -1.0), (10.0, 1.0, 10.0))]
    w = Walker(NavigationSettings(), caster_of(meshes))
    w.place((0.0, 1.0 + EYE, 0.0), NORTH)
    walk(w, NORTH, 2.0, until=lambda p: p[2] < -1.0)  # just over the edge: down at once, so
    assert w.position[1] == pytest.approx(EYE, abs=1e-6)  # letting go of W leaves no one hanging
    w.place((0.0, 1.0 + EYE, 0.0), NORTH)
    heights = walk(w, NORTH, 3.0)
    assert w.position[2] < -2.0
    assert w.position[1] == pytest.approx(EYE, abs=1e-6), "floating above the floor"
    assert max(heights) <= 1.0 + EYE + 1e-6


def test_placed_on_a_table_one_walks_off_and_lands() -> None:
    w = Walker(NavigationSettings(), caster_of(coffee_table()))
    w.place((0.0, 0.44 + EYE, -2.1), SOUTH)  # standing on the table top
    walk(w, SOUTH, 2.0)
    assert w.position[2] > -1.0 and w.position[1] == pytest.approx(EYE, abs=1e-6)


def test_no_tunnelling_through_a_thin_wall_at_running_speed() -> None:
    wall = box_mesh("wall", (-10.0, 0.0, -3.01), (10.0, 3.0, -3.0))
    w = Walker(NavigationSettings(walk_speed_mps=10.0), caster_of(hall() + [wall]))
    w.place((0.0, EYE, 0.0), NORTH)
    walk(w, NORTH, 3.0, dt=0.1)
    assert w.position[2] > -3.0 + 0.2
    w.place((0.0, EYE, 0.0), 20.0)  # at an angle: slides along it, still on this side
    walk(w, 20.0, 3.0, dt=0.1)
    assert w.position[2] > -3.0 + 0.2


def test_no_floor_below_stays_at_height() -> None:
    w = Walker(NavigationSettings(), caster_of([box_mesh("crate", (-0.5, 0, -0.5), (0.5, 1, 0.5))]))
    w.place((0.0, 0.5, 5.0), NORTH)
    walk(w, EAST, 2.0)
    assert w.position[1] == pytest.approx(0.5) and w.position[0] > 2.0


def test_fly_has_no_gravity_and_optional_collision() -> None:
    c = caster_of(hall())
    w = Walker(NavigationSettings(fly=True), c)
    w.place((0.0, 2.0, 0.0), NORTH)
    for _ in range(30):
        w.step(0.0, 0.0, 0.0, 1 / 30)
    assert w.position[1] == pytest.approx(2.0), "fell in fly mode"
    for _ in range(120):
        w.step(0.0, 0.0, 1.0, 1 / 30)
    assert 2.0 < w.position[1] < 3.0, "through the ceiling with collision on"
    w = Walker(NavigationSettings(fly=True, collision=False), c)
    w.place((0.0, 2.0, 0.0), NORTH)
    for _ in range(300):
        w.step(1.0, 0.0, 0.0, 1 / 30)
    assert w.position[2] < -10.0 and w.position[1] == pytest.approx(2.0)


def test_step_is_a_riser() -> None:
    assert 0.3 <= STEP_M < 0.4


def test_showroom_walk_keeps_eye_height() -> None:
    from app.scenes import resolve

    scene = resolve("showroom")
    w = Walker(NavigationSettings(), RayCaster(scene.triangles(), scene.triangle_owner()))
    sp = scene.spawn
    w.place(sp.position, sp.yaw_deg, sp.pitch_deg)
    heights = []
    for _ in range(6 * 60):
        w.step(1.0, 0.0, 0.0, 1 / 60)
        heights.append(float(w.position[1]))
    assert min(heights) >= EYE - 0.02 and max(heights) <= EYE + 0.02, (min(heights), max(heights))


# ------------------------------------------------------------------------------------------
# the shared staircase: up the first flight to the half landing, up the second to the upper
# floor, and back down
# ------------------------------------------------------------------------------------------

STAIRCASE = SCENES / "interiors" / "staircase" / "staircase.gltf"


@pytest.fixture(scope="module")
def staircase():
    if not STAIRCASE.exists():
        pytest.skip(f"{STAIRCASE} is not here")
    from app.loaders import load_scene

    scene = load_scene(STAIRCASE)
    return RayCaster(scene.triangles(), scene.triangle_owner())


def test_staircase_up_and_down(staircase) -> None:
    w = Walker(NavigationSettings(), staircase)
    # The first flight climbs towards -z at x 0.75..2.5 to the landing (y 1.8) at z < -3.3;
    # the second climbs towards -x along z -3.4..-4.8 to the upper floor (y 3.56) at x < -1.6.
    w.place((1.6, 0.025 + EYE, 0.0), NORTH)
    walk(w, NORTH, 10.0, until=lambda p: p[2] < -4.1)
    assert w.position[1] == pytest.approx(1.79 + EYE, abs=0.05), "not on the half landing"
    walk(w, WEST, 10.0, until=lambda p: p[0] < -2.5)
    assert w.position[0] < -2.5, "stuck on the second flight"
    top = float(w.position[1])
    assert top == pytest.approx(3.55 + EYE, abs=0.05), "not on the upper floor"
    walk(w, EAST, 10.0, until=lambda p: p[0] > 1.6)
    assert w.position[1] == pytest.approx(1.79 + EYE, abs=0.05)
    walk(w, SOUTH, 10.0, until=lambda p: p[2] > 0.0)
    assert w.position[2] > 0.0 and w.position[1] == pytest.approx(0.025 + EYE, abs=0.05)
    assert top - float(w.position[1]) == pytest.approx(3.53, abs=0.1)  # the storey height
