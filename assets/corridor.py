"""The built-in 'vection' corridor: a 40 m hotel corridor walked automatically at 2.5 m/s.

The CPS paper benchmarks its mitigation on an auto-moving flight through a narrow space; this is
the interior equivalent: near walls stream past on both sides and furniture sits low in view, so
the left, right and bottom edge rays of SPEC C all hit something close.

Layout (Y up, metres): the corridor runs from the near end wall at z = 0 down -Z to the far end
wall at z = -40, between walls at x = -1.2 (left, seen walking) and x = +1.2 (right), under a
3 m ceiling. "s" below is the distance from the near end (z = -s).

* shell: tiled terrazzo floor with a carpet runner, two-tone painted walls (deep blue-grey below
  the dado rail, warm white above) with skirting, an acoustic-tile ceiling;
* every 4 m a pilaster on each wall and a soffit beam across the ceiling, with recessed
  downlights between the beams;
* doors on alternating sides (walnut, with frames, kick plates, levers and number plates),
  benches and low cabinets under paintings, planters and fire extinguishers along both walls;
* the far end is a tall window with an exit sign over it; the near end has double doors.

:func:`corridor_walk` is the automatic walk, :func:`make_corridor_lights` spreads any number of
point lights along the ceiling with the corridor's overall brightness kept the same.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from app.paths import CameraPath, PathKey
from app.scene import Mesh, PointLight, Scene, Texture, Viewpoint, lamp_falloff
from assets.showroom import MeshBuilder, _Materials, rot_x, rot_y, srgb
from assets.textures import (
    PAINTING_ASPECTS,
    _fbm,
    _noise,
    _paint,
    _rng,
    _smoothstep,
    _solid,
    _texture,
    fabric,
    painting_abstract,
    painting_circles,
    painting_colorfield,
    painting_landscape,
    painting_stripes,
    wood,
)

HW = 1.2  # half width (m): walls at x = -HW (left) and x = +HW (right)
HEIGHT = 3.0
LENGTH = 40.0
EYE_HEIGHT = 1.6
BAY_M = 4.0  # pilasters and ceiling beams every 4 m
PILASTER_W, PILASTER_D = 0.36, 0.10
BEAM_H = 0.25  # how far the soffit beams hang below the ceiling
DADO_Y = 0.95  # the dado rail: the two wall colours meet here
FLOOR_TILE_M = 1.2  # one 512 px texture = 2 x 2 terrazzo tiles of 60 cm
CEILING_TILE_M = 1.2  # one 256 px texture = 2 x 2 acoustic tiles of 60 cm
WALL_TILE_M = 2.0
RUNNER_W = 1.3  # carpet runner width; its texture repeats every RUNNER_W along the corridor
DOOR_W, DOOR_H, ARCHITRAVE = 0.95, 2.1, 0.08

LIGHT_SEED = 4_242
WARM_WHITE = (1.0, 0.87, 0.72)
LIGHT_Y = 2.6
#: Mean irradiance over floor, walls and ceiling (luminance, the renderer's light model) that
#: every light count is scaled to: about what the showroom gets from its four ceiling lights.
TARGET_IRRADIANCE = 0.75

WALK_SPEED_MPS = 2.5
WALK_S = 12.0
WALK_START_S = 1.5  # distance from the near end wall where the walk (and the spawn) begins
SWAY_M = 0.15  # sideways weave either side of the centre line
SWAY_PERIOD_S = 4.0
KEY_DT = 0.1

SIDES = {"L": -1.0, "R": 1.0}  # x sign of each wall

#: What stands along each wall: (kind, s of its centre, painting hung above it or "").
LAYOUT: dict[str, list[tuple[str, float, str]]] = {
    "L": [
        ("door", 2.0, ""),
        ("bench", 6.0, "painting_landscape"),
        ("door", 9.2, ""),
        ("planter", 11.2, ""),
        ("cabinet", 14.0, "painting_abstract"),
        ("extinguisher", 16.7, ""),
        ("door", 18.0, ""),
        ("bench", 22.0, "painting_circles"),
        ("planter", 23.35, ""),
        ("door", 26.0, ""),
        ("cabinet", 30.0, "painting_stripes"),
        ("door", 33.2, ""),
        ("planter", 35.2, ""),
        ("bench", 38.0, "painting_colorfield"),
    ],
    "R": [
        ("planter", 0.7, ""),
        ("cabinet", 2.4, "painting_colorfield"),
        ("door", 6.0, ""),
        ("bench", 10.0, "painting_stripes"),
        ("door", 13.2, ""),
        ("planter", 15.2, ""),
        ("cabinet", 18.0, "painting_landscape"),
        ("door", 22.0, ""),
        ("bench", 25.6, "painting_abstract"),
        ("planter", 27.2, ""),
        ("door", 30.0, ""),
        ("extinguisher", 31.4, ""),
        ("cabinet", 34.0, "painting_circles"),
        ("door", 37.2, ""),
        ("planter", 39.45, ""),
    ],
}


# -- textures -----------------------------------------------------------------------------------


def plaster(size: int = 256) -> Texture:
    """Near-white painted plaster with a faint roller stipple; tinted per wall by its material."""
    rng = _rng(101)
    shade = 1.0 + 0.018 * _fbm(rng, size, 2.0, 3) + 0.008 * _noise(rng, size, 28.0)
    img = _solid(size, (244, 242, 238)) * shade[..., None]
    return _texture("plaster", np.clip(img, 0, 1))


def terrazzo(size: int = 512) -> Texture:
    """Warm grey terrazzo: 2 x 2 tiles per texture, stone chips, cloudy tone, grout joints."""
    rng = _rng(102)
    tile = size // 2
    y, x = np.mgrid[0:size, 0:size]
    cell = (y // tile) * 2 + x // tile
    tone = rng.normal(0.0, 1.0, 4).astype(np.float32)
    img = _solid(size, (196, 190, 180)) * (1.0 + 0.025 * tone[cell])[..., None]
    img *= (1.0 + 0.035 * _noise(rng, size, 36.0))[..., None]
    for colour, sigma, level in (
        ((124, 112, 100), 1.0, 2.1),
        ((236, 232, 224), 1.2, 2.2),
        ((86, 92, 100), 0.9, 2.4),
        ((168, 128, 96), 1.1, 2.5),
        ((64, 60, 58), 0.7, 2.7),
    ):
        chips = _noise(rng, size, sigma)
        _paint(img, _smoothstep(level, level + 0.35, chips), colour)
    grout = (x % tile < 2) | (x % tile >= tile - 2) | (y % tile < 2) | (y % tile >= tile - 2)
    _paint(img, grout, (132, 126, 118))
    return _texture("terrazzo", np.clip(img, 0, 1))


def ceiling_tiles(size: int = 256) -> Texture:
    """Mineral-fibre acoustic tiles, 2 x 2 per texture, fissured, on a white T-bar grid."""
    rng = _rng(103)
    tile = size // 2
    y, x = np.mgrid[0:size, 0:size]
    img = _solid(size, (238, 236, 230))
    fissures = _noise(rng, size, 1.1, 0.8)
    _paint(img, 0.22 * _smoothstep(1.3, 2.2, fissures), (170, 166, 158))
    img *= (1.0 + 0.015 * _noise(rng, size, 12.0))[..., None]
    px, py = x % tile, y % tile
    bar = (px < 2) | (px >= tile - 2) | (py < 2) | (py >= tile - 2)
    shadow = ((px == 2) | (py == 2)) & ~bar
    _paint(img, shadow, (196, 194, 188))
    _paint(img, bar, (250, 250, 248))
    return _texture("ceiling_tiles", np.clip(img, 0, 1))


def carpet_runner(size: int = 256) -> Texture:
    """The runner's wool: a navy field with a lattice of diamonds between rust and gold borders.

    u runs across the runner (0..1, borders at both sides), v along it (repeats seamlessly).
    """
    rng = _rng(104)
    y, x = np.mgrid[0:size, 0:size].astype(np.float32)
    u, v = (x + 0.5) / size, (y + 0.5) / size
    img = _solid(size, (34, 48, 78))
    n = 4.0  # diamonds across the field and per repeat along it
    du = np.abs(((u - 0.5) * n) % 1.0 - 0.5)
    dv = np.abs((v * n) % 1.0 - 0.5)
    diamond = du + dv
    _paint(img, _smoothstep(0.05, 0.0, np.abs(diamond - 0.36)), (92, 118, 150))
    _paint(img, _smoothstep(0.07, 0.0, diamond - 0.08), (196, 150, 72))
    edge = np.minimum(u, 1.0 - u)
    _paint(img, (edge < 0.11) & (edge > 0.03), (134, 62, 40))
    _paint(img, (edge < 0.075) & (edge > 0.06), (214, 176, 96))
    _paint(img, edge <= 0.03, (30, 30, 36))
    wool = 1.0 + 0.06 * _noise(rng, size, 0.8) + 0.04 * _noise(rng, size, 10.0)
    return _texture("carpet_runner", np.clip(img * wool[..., None], 0, 1))


def make_corridor_textures() -> dict[str, Texture]:
    makers = [
        plaster,
        terrazzo,
        ceiling_tiles,
        carpet_runner,
        wood,
        fabric,
        painting_abstract,
        painting_landscape,
        painting_stripes,
        painting_circles,
        painting_colorfield,
    ]
    textures = [make() for make in makers]
    return {t.name: t for t in textures}


def _corridor_materials(textures: dict[str, Texture]) -> _Materials:
    m = _Materials(textures)
    m.add("wall_upper", "plaster", color=srgb(240, 232, 216), roughness=0.85)
    m.add("wall_lower", "plaster", color=srgb(74, 92, 112), roughness=0.7)
    m.add("terrazzo", "terrazzo", roughness=0.25)
    m.add("carpet", "carpet_runner", roughness=1.0)
    m.add("ceiling", "ceiling_tiles", roughness=0.95)
    m.add("white_paint", color=srgb(236, 233, 226), roughness=0.45)
    m.add("walnut", "wood", roughness=0.4)
    m.add("fabric", "fabric", color=srgb(255, 236, 206), roughness=0.95)
    for name in PAINTING_ASPECTS:
        m.add(name, name, roughness=0.75)
    m.add("frame_black", color=srgb(22, 20, 20), roughness=0.35)
    m.add("frame_brass", color=srgb(200, 160, 90), roughness=0.3, metallic=0.9)
    m.add("steel_black", color=srgb(34, 34, 36), roughness=0.4, metallic=0.6)
    m.add("brushed_steel", color=srgb(200, 200, 204), roughness=0.3, metallic=1.0)
    m.add("chrome", color=srgb(230, 230, 232), roughness=0.15, metallic=1.0)
    m.add("brass", color=srgb(190, 150, 90), roughness=0.3, metallic=1.0)
    m.add("ceramic_charcoal", color=srgb(58, 60, 62), roughness=0.3)
    m.add("ceramic_cream", color=srgb(232, 224, 206), roughness=0.2)
    m.add("ceramic_teal", color=srgb(40, 110, 120), roughness=0.15)
    m.add("leaves", color=srgb(52, 104, 44), roughness=0.7)
    m.add("soil", color=srgb(48, 36, 28), roughness=1.0)
    m.add("lamp_shade", color=srgb(240, 228, 205), roughness=0.9, emissive=(0.9, 0.62, 0.32))
    m.add("downlight", color=srgb(250, 245, 235), roughness=0.5, emissive=(2.0, 1.75, 1.45))
    m.add("window_sky", color=srgb(30, 34, 40), roughness=0.1, emissive=(0.62, 0.78, 1.0))
    m.materials[m["window_sky"]].sky_standin = True  # daylight shows the sky itself there
    m.add("bronze", color=srgb(62, 54, 46), roughness=0.35, metallic=0.7)
    m.add("exit_sign", color=srgb(20, 160, 70), roughness=0.3, emissive=(0.1, 1.2, 0.35))
    m.add("signal_red", color=srgb(190, 24, 20), roughness=0.25)
    return m


# -- the shell ----------------------------------------------------------------------------------


def _spans(side: str) -> list[tuple[float, float]]:
    """Stretches of a wall (s0, s1) covered by a door frame or a pilaster, sorted."""
    half_door = DOOR_W / 2 + ARCHITRAVE
    spans = [(s - half_door, s + half_door) for kind, s, _ in LAYOUT[side] if kind == "door"]
    spans += [(s - PILASTER_W / 2, s + PILASTER_W / 2) for s in _pilaster_s()]
    return sorted(spans)


def _free(side: str) -> list[tuple[float, float]]:
    """The stretches of a wall not covered by a door frame or pilaster (for rails, skirting)."""
    out, s = [], 0.0
    for a, b in _spans(side):
        if a > s:
            out.append((s, a))
        s = max(s, b)
    if s < LENGTH:
        out.append((s, LENGTH))
    return out


def _pilaster_s() -> list[float]:
    return [BAY_M * k for k in range(1, round(LENGTH / BAY_M))]


def _wall_box(
    b: MeshBuilder,
    side: str,
    s0: float,
    s1: float,
    y0: float,
    y1: float,
    depth: float,
    uv_tile: float | None = None,
) -> None:
    """A box against wall ``side`` from s0 to s1, y0 to y1, standing ``depth`` out of it."""
    sx = SIDES[side]
    b.box(
        (sx * (HW - depth / 2), (y0 + y1) / 2, -(s0 + s1) / 2),
        (depth, y1 - y0, s1 - s0),
        uv_tile=uv_tile,
    )


def _shell(mats: _Materials) -> list[Mesh]:
    ex, ey, ez = np.eye(3)
    meshes = []
    b = MeshBuilder()
    b.quad((-HW, 0, 0), ex * 2 * HW, -ez * LENGTH, FLOOR_TILE_M)
    meshes.append(b.mesh("floor", mats["terrazzo"]))
    b = MeshBuilder()
    b.box((0.0, 0.006, -LENGTH / 2), (RUNNER_W, 0.012, LENGTH - 1.0))
    m = b.mesh("carpet_runner", mats["carpet"])
    # Across the runner u runs 0..1 over its width; along it v counts runner widths.
    m.uvs[:] = np.stack(
        [(m.positions[:, 0] + RUNNER_W / 2) / RUNNER_W, -m.positions[:, 2] / RUNNER_W], axis=1
    )
    meshes.append(m)
    b = MeshBuilder()
    b.quad((-HW, HEIGHT, -LENGTH), ex * 2 * HW, ez * LENGTH, CEILING_TILE_M, (0.25, 0.0))
    meshes.append(b.mesh("ceiling", mats["ceiling"]))
    for side, name in (("L", "left"), ("R", "right")):
        start, run = ((-HW, 0, 0), -ez * LENGTH) if side == "L" else ((HW, 0, -LENGTH), ez * LENGTH)
        lower, upper = MeshBuilder(), MeshBuilder()
        lower.quad(start, run, ey * DADO_Y, WALL_TILE_M)
        upper.quad(
            np.add(start, ey * DADO_Y),
            run,
            ey * (HEIGHT - DADO_Y),
            WALL_TILE_M,
            (0.0, DADO_Y / WALL_TILE_M),
        )
        meshes.append(lower.mesh(f"wall_{name}_lower", mats["wall_lower"]))
        meshes.append(upper.mesh(f"wall_{name}", mats["wall_upper"]))
        trim = MeshBuilder()
        for s0, s1 in _free(side):
            _wall_box(trim, side, s0, s1, 0.0, 0.12, 0.016)  # skirting
            _wall_box(trim, side, s0, s1, DADO_Y - 0.025, DADO_Y + 0.03, 0.022)  # dado rail
        meshes.append(trim.mesh(f"trim_{name}", mats["white_paint"]))
    for z, yaw, name in ((-LENGTH, 0.0, "wall_far"), (0.0, 180.0, "wall_near")):
        for y0, y1, suffix, mat in (
            (0.0, DADO_Y, "_lower", "wall_lower"),
            (DADO_Y, HEIGHT, "", "wall_upper"),
        ):
            b = MeshBuilder((0.0, 0.0, z), yaw)
            b.quad(
                (-HW, y0, 0.0), ex * 2 * HW, ey * (y1 - y0), WALL_TILE_M, (0.0, y0 / WALL_TILE_M)
            )
            meshes.append(b.mesh(name + suffix, mats[mat]))
    pilasters, beams, lights = MeshBuilder(), MeshBuilder(), MeshBuilder()
    for s in _pilaster_s():
        for side in SIDES:
            _wall_box(
                pilasters, side, s - PILASTER_W / 2, s + PILASTER_W / 2, 0.0, HEIGHT, PILASTER_D
            )
        beams.box((0.0, HEIGHT - BEAM_H / 2, -s), (2 * HW - 2 * PILASTER_D, BEAM_H, PILASTER_W))
    for k in range(round(LENGTH / BAY_M)):
        for off in (1.0, 3.0):
            lights.cylinder((0.0, HEIGHT - 0.012, -(BAY_M * k + off)), 0.075, 0.075, 0.012, 20)
    meshes += [
        pilasters.mesh("pilasters", mats["white_paint"]),
        beams.mesh("ceiling_beams", mats["white_paint"]),
        lights.mesh("downlights", mats["downlight"]),
    ]
    return meshes


def _far_window(mats: _Materials) -> list[Mesh]:
    """A tall window filling most of the far end wall, and the exit sign above it."""
    w, y0, y1 = 1.8, 0.45, 2.5
    glass = MeshBuilder((0.0, 0.0, -LENGTH))
    glass.quad((-w / 2, y0, 0.004), (w, 0, 0), (0, y1 - y0, 0))
    frame = MeshBuilder((0.0, 0.0, -LENGTH))
    d, f = 0.07, 0.06
    frame.box((0.0, y1 + f / 2, d / 2), (w + 2 * f, f, d))
    frame.box((0.0, y0 - f / 2, 0.08), (w + 2 * f + 0.1, f, 0.16))  # sill
    for x in (-(w + f) / 2, (w + f) / 2, -w / 6, w / 6):  # jambs and mullions
        frame.box((x, (y0 + y1) / 2, d / 2), (f if abs(x) > w / 2 else 0.045, y1 - y0, d))
    frame.box((0.0, 2.0, d / 2), (w, 0.045, d))  # transom
    sign = MeshBuilder((0.0, 0.0, -LENGTH))
    sign.box((0.0, 2.72, 0.04), (0.36, 0.15, 0.08))
    return [
        glass.mesh("window", mats["window_sky"]),
        frame.mesh("window_frame", mats["bronze"]),
        sign.mesh("exit_sign", mats["exit_sign"]),
    ]


# -- things along the walls ---------------------------------------------------------------------


def _at(side: str, s: float) -> MeshBuilder:
    """A builder whose local frame stands on wall ``side`` at s: +z points into the corridor,
    +x runs along the wall, y is up."""
    sx = SIDES[side]
    return MeshBuilder((sx * HW, 0.0, -s), -sx * 90.0)


def _like(b: MeshBuilder, n: int) -> list[MeshBuilder]:
    """``n`` empty builders in the same frame as ``b`` (one per material of an object)."""
    out = [MeshBuilder() for _ in range(n)]
    for m in out:
        m.origin, m.frame = b.origin, b.frame
    return out


def _door(mats: _Materials, name: str, b: MeshBuilder, handle_x: float) -> list[Mesh]:
    """A walnut door in its architrave, centred at local x = 0 on the wall (local z = 0)."""
    leaf, trim, metal, plate = _like(b, 4)
    leaf.box((0.0, DOOR_H / 2, 0.012), (DOOR_W, DOOR_H, 0.024), uv_tile=1.0)
    a = ARCHITRAVE
    for sx in (-1, 1):
        trim.box((sx * (DOOR_W + a) / 2, (DOOR_H + a) / 2, 0.0175), (a, DOOR_H + a, 0.035))
    trim.box((0.0, DOOR_H + a / 2, 0.0175), (DOOR_W, a, 0.035))
    metal.box((0.0, 0.13, 0.026), (DOOR_W - 0.08, 0.24, 0.004))  # kick plate
    hx = handle_x * (DOOR_W / 2 - 0.08)
    metal.cylinder(
        (hx, 1.0, 0.024), 0.027, 0.027, 0.01, 20, rot=rot_x(90.0), pivot=(hx, 1.0, 0.024)
    )
    metal.cylinder(
        (hx, 1.0, 0.034), 0.009, 0.009, 0.055, 12, rot=rot_x(90.0), pivot=(hx, 1.0, 0.034)
    )
    metal.box((hx - handle_x * 0.055, 1.0, 0.085), (0.13, 0.018, 0.018))
    px = -handle_x * (DOOR_W / 2 + a + 0.17)  # the number plate, on the hinge side
    plate.box((px, 1.55, 0.004), (0.15, 0.1, 0.008))
    return [
        leaf.mesh(f"door_{name}", mats["walnut"]),
        trim.mesh(f"door_{name}_frame", mats["white_paint"]),
        metal.mesh(f"door_{name}_hardware", mats["brushed_steel"]),
        plate.mesh(f"door_{name}_number", mats["brass"]),
    ]


def _bench(mats: _Materials, name: str, b: MeshBuilder) -> list[Mesh]:
    length, depth, z = 1.5, 0.42, 0.23
    seat, legs, cushion = _like(b, 3)
    seat.box((0.0, 0.38, z), (length, 0.04, depth), uv_tile=0.8)
    for sx in (-1, 1):
        for sz in (-1, 1):
            legs.box(
                (sx * (length / 2 - 0.07), 0.18, z + sz * (depth / 2 - 0.05)), (0.04, 0.36, 0.04)
            )
        legs.box((sx * (length / 2 - 0.07), 0.08, z), (0.03, 0.03, depth - 0.1))
    legs.box((0.0, 0.08, z), (length - 0.14, 0.03, 0.03))
    cushion.box((0.0, 0.435, z), (length - 0.05, 0.07, depth - 0.04), uv_tile=0.35)
    return [
        seat.mesh(f"bench_{name}", mats["walnut"]),
        legs.mesh(f"bench_{name}_frame", mats["steel_black"]),
        cushion.mesh(f"bench_{name}_cushion", mats["fabric"]),
    ]


def _cabinet(mats: _Materials, name: str, b: MeshBuilder) -> list[Mesh]:
    length, depth, top = 1.6, 0.44, 0.75
    z = 0.015 + depth / 2
    body, feet, lamp, shade, vase = _like(b, 5)
    body.box((0.0, (0.12 + top) / 2, z), (length, top - 0.12, depth), uv_tile=0.8)
    for sx in (-1, 1):
        for sz in (-1, 1):
            feet.box(
                (sx * (length / 2 - 0.08), 0.06, z + sz * (depth / 2 - 0.06)), (0.035, 0.12, 0.035)
            )
    for x in (-0.4, 0.0, 0.4):  # door gaps on the front
        feet.box((x, (0.12 + top) / 2, z + depth / 2), (0.008, top - 0.16, 0.006))
    for x in (-0.6, -0.2, 0.2, 0.6):  # pulls
        feet.box((x + (0.15 if x < 0 else -0.15), 0.62, z + depth / 2 + 0.01), (0.012, 0.12, 0.012))
    lamp.cylinder((0.5, top, z), 0.075, 0.05, 0.3, 24)
    shade.cylinder((0.5, top + 0.28, z), 0.16, 0.12, 0.22, 28)
    vase.cylinder((-0.45, top, z), 0.06, 0.1, 0.2, 28)
    vase.cylinder((-0.45, top + 0.2, z), 0.1, 0.035, 0.13, 28)
    return [
        body.mesh(f"cabinet_{name}", mats["walnut"]),
        feet.mesh(f"cabinet_{name}_hardware", mats["steel_black"]),
        lamp.mesh(f"lamp_{name}", mats["ceramic_cream"]),
        shade.mesh(f"lamp_{name}_shade", mats["lamp_shade"]),
        vase.mesh(f"vase_{name}", mats["ceramic_teal"]),
    ]


def _planter(mats: _Materials, name: str, b: MeshBuilder, seed: int) -> list[Mesh]:
    """A tall pot with a sansevieria-like plant whose leaves stay within 0.3 m of its axis."""
    z = 0.3
    pot, soil, plant = _like(b, 3)
    pot.cylinder((0.0, 0.0, z), 0.15, 0.2, 0.55, 28)
    soil.cylinder((0.0, 0.55, z), 0.185, 0.185, 0.01, 28, caps=True)
    rng = np.random.default_rng([LIGHT_SEED, seed])
    count = 18
    for i in range(count):
        heading = i * (360.0 / count) + float(rng.uniform(-8, 8))
        tilt = float(rng.uniform(3, 15))
        length = float(rng.uniform(0.55, 0.95))
        base = np.array([0.0, 0.5, z]) + 0.08 * np.array(
            [math.sin(math.radians(heading)), 0.0, math.cos(math.radians(heading))]
        )
        r = rot_y(heading) @ rot_x(-tilt)
        plant.box(base + np.array([0.0, length / 2, 0.0]), (0.07, length, 0.008), rot=r, pivot=base)
    return [
        pot.mesh(f"planter_{name}", mats["ceramic_charcoal"]),
        soil.mesh(f"planter_{name}_soil", mats["soil"]),
        plant.mesh(f"plant_{name}", mats["leaves"]),
    ]


def _extinguisher(mats: _Materials, name: str, b: MeshBuilder) -> list[Mesh]:
    body, parts, sign = _like(b, 3)
    z = 0.1
    body.cylinder((0.0, 0.5, z), 0.075, 0.075, 0.42, 24)
    body.cylinder((0.0, 0.92, z), 0.075, 0.03, 0.05, 24)
    parts.cylinder((0.0, 0.97, z), 0.018, 0.018, 0.05, 12)
    parts.box((0.0, 1.03, z + 0.02), (0.03, 0.02, 0.12))  # lever
    parts.box((0.06, 0.8, z + 0.06), (0.02, 0.3, 0.02))  # hose
    parts.box((0.0, 0.75, 0.012), (0.06, 0.12, 0.024))  # wall bracket
    sign.box((0.0, 1.35, 0.003), (0.2, 0.2, 0.006))
    return [
        body.mesh(f"extinguisher_{name}", mats["signal_red"]),
        parts.mesh(f"extinguisher_{name}_fittings", mats["steel_black"]),
        sign.mesh(f"extinguisher_{name}_sign", mats["signal_red"]),
    ]


def _painting(
    mats: _Materials, name: str, b: MeshBuilder, texture: str, frame_mat: str
) -> list[Mesh]:
    aspect = PAINTING_ASPECTS[texture]
    h = 0.72 if aspect > 1.0 else 0.9
    w, yc = h * aspect, 1.68
    canvas, frame = _like(b, 2)
    canvas.quad((-w / 2, yc - h / 2, 0.03), (w, 0.0, 0.0), (0.0, h, 0.0))
    fw, fd = 0.05, 0.04
    for dx, dy, lx, ly in (
        (0, (h + fw) / 2, w + 2 * fw, fw),
        (0, -(h + fw) / 2, w + 2 * fw, fw),
        ((w + fw) / 2, 0, fw, h),
        (-(w + fw) / 2, 0, fw, h),
    ):
        frame.box((dx, yc + dy, fd / 2), (lx, ly, fd), uv_tile=0.5)
    return [
        canvas.mesh(f"painting_{name}", mats[texture]),
        frame.mesh(f"frame_{name}", mats[frame_mat]),
    ]


def _near_doors(mats: _Materials) -> list[Mesh]:
    """Double doors in the near end wall, behind the start of the walk."""
    b = MeshBuilder((0.0, 0.0, 0.0), 180.0)
    meshes = []
    for k, x in enumerate((-0.45, 0.45)):
        leaf = MeshBuilder((0.0, 0.0, 0.0), 180.0)
        leaf.box((x, DOOR_H / 2, 0.012), (0.88, DOOR_H, 0.024), uv_tile=1.0)
        meshes.append(leaf.mesh(f"door_near_{k + 1}", mats["walnut"]))
    a = ARCHITRAVE
    for sx in (-1, 1):
        b.box((sx * (0.9 + a / 2), (DOOR_H + a) / 2, 0.0175), (a, DOOR_H + a, 0.035))
    b.box((0.0, DOOR_H + a / 2, 0.0175), (1.8 + 2 * a, a, 0.035))
    bars = MeshBuilder((0.0, 0.0, 0.0), 180.0)
    bars.box((0.0, 1.0, 0.06), (1.5, 0.04, 0.03))  # push bars
    for x in (-0.7, -0.2, 0.2, 0.7):
        bars.box((x, 1.0, 0.04), (0.04, 0.06, 0.04))
    return meshes + [
        b.mesh("door_near_frame", mats["white_paint"]),
        bars.mesh("door_near_bars", mats["brushed_steel"]),
    ]


def _wall_things(mats: _Materials) -> list[Mesh]:
    meshes: list[Mesh] = []
    frames = ("frame_black", "frame_brass")
    for side in SIDES:
        count: dict[str, int] = {}
        for kind, s, painting in LAYOUT[side]:
            count[kind] = count.get(kind, 0) + 1
            name = f"{side}{count[kind]}"
            b = _at(side, s)
            if kind == "door":
                # The lever sits on the side of the door nearer the walker (hinges away).
                meshes += _door(mats, name, b, 1.0 if side == "R" else -1.0)
            elif kind == "bench":
                meshes += _bench(mats, name, b)
            elif kind == "cabinet":
                meshes += _cabinet(mats, name, b)
            elif kind == "planter":
                meshes += _planter(mats, name, b, seed=int(s * 100) + (0 if side == "L" else 1))
            elif kind == "extinguisher":
                meshes += _extinguisher(mats, name, b)
            else:
                raise ValueError(f"unknown wall item {kind!r}")
            if painting:
                count["painting"] = count.get("painting", 0) + 1
                meshes += _painting(
                    mats, f"{side}{count['painting']}", b, painting, frames[count["painting"] % 2]
                )
    return meshes


# -- lights -------------------------------------------------------------------------------------


def _irradiance_samples() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Points and inward normals on floor, walls and ceiling along the corridor, and each point's
    0.5 m slice index (to compare light setups and to measure evenness)."""
    ss = np.arange(2.0, LENGTH - 2.0 + 1e-9, 0.5)
    pts, nrm, slices = [], [], []
    for x in np.linspace(-HW + 0.3, HW - 0.3, 5):
        pts.append(np.stack([np.full_like(ss, x), np.zeros_like(ss), -ss], 1))
        nrm.append(np.tile([0.0, 1.0, 0.0], (ss.size, 1)))
        slices.append(np.arange(ss.size))
    for x in np.linspace(-HW + 0.3, HW - 0.3, 3):
        pts.append(np.stack([np.full_like(ss, x), np.full_like(ss, HEIGHT), -ss], 1))
        nrm.append(np.tile([0.0, -1.0, 0.0], (ss.size, 1)))
        slices.append(np.arange(ss.size))
    for sx in (-1.0, 1.0):
        for y in (0.5, 1.2, 1.9, 2.6):
            pts.append(np.stack([np.full_like(ss, sx * HW), np.full_like(ss, y), -ss], 1))
            nrm.append(np.tile([-sx, 0.0, 0.0], (ss.size, 1)))
            slices.append(np.arange(ss.size))
    return np.concatenate(pts), np.concatenate(nrm), np.concatenate(slices)


def irradiance_profile(lights: Sequence[PointLight]) -> np.ndarray:
    """Mean Lambert irradiance of floor, walls and ceiling per 0.5 m slice (s = 2..38 m)."""
    pts, nrm, slices = _irradiance_samples()
    total = np.zeros(pts.shape[0])
    for light in lights:
        v = np.asarray(light.position, np.float64) - pts
        d2 = np.einsum("ij,ij->i", v, v)
        d = np.sqrt(d2)
        cos = np.clip(np.einsum("ij,ij->i", v, nrm) / np.maximum(d, 1e-9), 0.0, None)
        lum = float(np.dot(light.color, (0.2126, 0.7152, 0.0722)))
        total += lum * light.intensity * cos * lamp_falloff(d2, light.range_m)
    return np.bincount(slices, total) / np.bincount(slices)


def corridor_irradiance(lights: Sequence[PointLight]) -> float:
    """Mean irradiance over the corridor's shell (what the light counts are matched on)."""
    return float(irradiance_profile(lights).mean())


def light_range(count: int) -> float:
    """Range of each of ``count`` lights: it reaches the floor 2.5 light spacings away (so every
    point is lit by several lights and the pools of light merge), and never less than 1.6 m."""
    spacing = (LENGTH - 1.0) / max(1, count)  # between neighbours along the corridor
    return round(math.hypot(LIGHT_Y, max(1.6, 2.5 * spacing)), 3)


def make_corridor_lights(count: int) -> list[PointLight]:
    """``count`` point lights spread along the ceiling (seeded), scaled to the same brightness.

    Up to 23 lights hang in one row on the centre line, evenly spaced; more alternate between
    two rows 1 m apart with a little jitter, like a real two-row layout.
    """
    if count < 0:
        raise ValueError(f"light count must be >= 0, got {count}")
    if count == 0:
        return []
    rng = np.random.default_rng(LIGHT_SEED)
    margin = 0.5
    span = LENGTH - 2 * margin
    i = np.arange(count)
    if count < 24:
        s = margin + (i + 0.5) * span / count
        x = np.zeros(count)
        y = np.full(count, LIGHT_Y)
        tint = np.tile(WARM_WHITE, (count, 1))
    else:
        step = span / count
        s = margin + (i + 0.5 + rng.uniform(-0.25, 0.25, count)) * step
        x = np.where(i % 2 == 0, -0.5, 0.5) + rng.uniform(-0.08, 0.08, count)
        y = LIGHT_Y + rng.uniform(-0.12, 0.08, count)
        tint = np.clip(np.asarray(WARM_WHITE) + rng.uniform(-0.04, 0.04, (count, 3)), 0.0, 1.0)
    near_beam = np.abs(s - np.round(s / BAY_M) * BAY_M) < PILASTER_W / 2 + 0.05
    y[near_beam] = np.minimum(y[near_beam], HEIGHT - BEAM_H - 0.1)  # below the soffit beams
    r = light_range(count)
    lights = [
        PointLight(
            (float(x[k]), float(y[k]), float(-s[k])),
            (float(tint[k, 0]), float(tint[k, 1]), float(tint[k, 2])),
            1.0,
            r,
        )
        for k in range(count)
    ]
    scale = TARGET_IRRADIANCE / max(corridor_irradiance(lights), 1e-12)
    for light in lights:
        light.intensity = round(scale, 6)
    return lights


# -- scene and walk -----------------------------------------------------------------------------

SPAWN = Viewpoint((0.0, EYE_HEIGHT, -WALK_START_S), yaw_deg=0.0, pitch_deg=-3.0)


def build_corridor(lights: int = 100) -> Scene:
    """The furnished corridor with ``lights`` point lights along its ceiling.

    Named "corridor" with the paper's 100 lights, "corridor-N" otherwise.
    """
    mats = _corridor_materials(make_corridor_textures())
    meshes = _shell(mats) + _far_window(mats) + _near_doors(mats) + _wall_things(mats)
    name = "corridor" if lights == 100 else f"corridor-{lights}"
    scene = Scene(
        name,
        meshes,
        mats.materials,
        mats.textures,
        make_corridor_lights(lights),
        Viewpoint(SPAWN.position, SPAWN.yaw_deg, SPAWN.pitch_deg),
        floor_y=0.0,
        source="built-in",
    )
    return scene.sanitized()


def corridor_walk() -> CameraPath:
    """Walk down the corridor at 2.5 m/s for 12 s, weaving gently, the gaze at the centre.

    The weave eases in over the first 1.5 s, so the walk starts exactly at the spawn: x sways
    +-0.15 m with a 4 s period, the view turns a little into each sway and looks around slowly.
    """
    keys = []
    omega = 2 * math.pi / SWAY_PERIOD_S
    for i in range(round(WALK_S / KEY_DT) + 1):
        t = i * KEY_DT
        ease = _ease(t / 1.5)
        s = WALK_START_S + WALK_SPEED_MPS * t
        x = ease * SWAY_M * math.sin(omega * t)
        heading = math.degrees(math.atan2(SWAY_M * omega * math.cos(omega * t), WALK_SPEED_MPS))
        yaw = ease * (-0.7 * heading + 2.5 * math.sin(2 * math.pi * t / 6.5))
        pitch = SPAWN.pitch_deg + ease * 1.2 * math.sin(2 * math.pi * t / 3.1)
        keys.append(
            PathKey(
                round(t, 6),
                (round(x, 6), EYE_HEIGHT, round(-s, 6)),
                round(yaw, 4),
                round(pitch, 4),
                (0.5, 0.5),
                False,
            )
        )
    return CameraPath(keys, "corridor")


def _ease(u: float) -> float:
    u = min(max(u, 0.0), 1.0)
    return u * u * (3.0 - 2.0 * u)
