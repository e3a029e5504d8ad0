"""The built-in showroom: a furnished 8 x 6 x 3 m living room made entirely in code.

Layout (Y up, metres, origin at the centre of the floor, x in [-4, 4], z in [-3, 3]):

* north wall (z = -3): three paintings; a grand piano angled in the north-west corner with its
  bench; a floor lamp in the north-east corner;
* east wall (x = +4): a sofa facing the room under the fourth painting, a rug, a coffee table and
  a wooden chair facing the sofa;
* south wall (z = +3): the door (x ~ 3) with the light switch beside it, a sideboard with a vase
  under the fifth painting, a plant in the south-west corner;
* west wall (x = -4): a window, a real opening in the wall with venetian blinds whose tilted
  slats stripe the floor with sunlight (the pane shows the sky: it glows and casts no
  shadow); the room's north (:data:`NORTH_DEG`) turns this wall to the sun at 10:00.

Every piece is its own :class:`Mesh` with a meaningful name. Faces are wound counter-clockwise
seen from the side their normal points to; the room's shell faces into the room.

:func:`build_texture_test_scene` is a one-quad scene whose checker quadrants tell whether texture
orientation survives the whole pipeline.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from app.color import srgb8_to_linear
from app.scene import Material, Mesh, PointLight, Scene, Texture, Viewpoint, lamp_falloff
from assets.textures import PAINTING_ASPECTS, checker_quadrants, make_textures

ROOM_X = 8.0  # width along x (m)
ROOM_Z = 6.0  # depth along z (m)
ROOM_H = 3.0  # height (m)
HX, HZ = ROOM_X / 2, ROOM_Z / 2
EYE_HEIGHT = 1.6
WALL_TILE_M = 2.0  # one 512 px wallpaper / parquet tile per 2 m
CEILING_TILE_M = 1.0  # one 64 px ceiling tile per metre
LIGHT_SEED = 7_301
WARM_WHITE = (1.0, 0.87, 0.72)
# candela of each of the four ceiling lights (physical inverse square: 5.6 lux at 1 m; 6.5
# under the old 1 / (d^2 + 1) law, scaled by 0.86 so the room keeps its brightness)
FOUR_LIGHT_INTENSITY = 5.6
FOUR_LIGHT_RANGE_M = 6.0
GRID_LIGHT_RANGE_M = 2.5
# The room's north for daylight (Scene.north_deg, as sky.north_deg): the window wall faces
# west-south-west of the sun's 10:00 bearing on the default date and site, so the morning sun
# falls through the blinds onto the floor inside.
NORTH_DEG = 200.0
# The window opening in the west wall: z and height ranges (m).
WINDOW_Z = (-0.5, 1.7)
WINDOW_Y = (0.9, 2.3)

Vec = Sequence[float] | np.ndarray  # a 3-vector (or a uv pair) as a tuple or an array
_QUAD_TRIS = np.array([[0, 1, 2], [0, 2, 3]], np.int64)  # a quad's corners as two triangles


# -- small linear algebra -----------------------------------------------------------------------


def rot_x(deg: float) -> np.ndarray:
    c, s = math.cos(math.radians(deg)), math.sin(math.radians(deg))
    return np.array([[1, 0, 0], [0, c, -s], [0, s, c]], np.float64)


def rot_y(deg: float) -> np.ndarray:
    """Counter-clockwise seen from above: rot_y(90) turns -Z (forward) into -X."""
    c, s = math.cos(math.radians(deg)), math.sin(math.radians(deg))
    return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]], np.float64)


def rot_z(deg: float) -> np.ndarray:
    c, s = math.cos(math.radians(deg)), math.sin(math.radians(deg))
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]], np.float64)


def srgb(r: int, g: int, b: int, a: float = 1.0) -> tuple[float, float, float, float]:
    """An sRGB 0..255 colour as the linear RGBA a :class:`Material` wants."""
    return srgb8_to_linear(r, g, b, a)


# -- mesh building ------------------------------------------------------------------------------


class MeshBuilder:
    """Accumulates primitives into one mesh, in a frame placed at ``origin`` turned by ``yaw_deg``.

    Each primitive may carry its own rotation about a pivot (in the builder's frame). Triangles are
    re-wound where needed so that they are counter-clockwise seen from the side their vertex
    normals point to: the primitives only have to get the normals right.
    """

    def __init__(self, origin: Vec = (0.0, 0.0, 0.0), yaw_deg: float = 0.0) -> None:
        self.origin = np.asarray(origin, np.float64)
        self.frame = rot_y(yaw_deg)
        self._pos: list[np.ndarray] = []
        self._nrm: list[np.ndarray] = []
        self._uv: list[np.ndarray] = []
        self._idx: list[np.ndarray] = []
        self._count = 0

    def add(
        self,
        pos: np.ndarray,
        nrm: np.ndarray,
        uv: np.ndarray,
        tri: np.ndarray,
        rot: np.ndarray | None = None,
        pivot: Vec | None = None,
    ) -> None:
        pos = np.asarray(pos, np.float64).reshape(-1, 3)
        nrm = np.asarray(nrm, np.float64).reshape(-1, 3)
        if rot is not None:
            pv = np.zeros(3) if pivot is None else np.asarray(pivot, np.float64)
            pos = (pos - pv) @ rot.T + pv
            nrm = nrm @ rot.T
        pos = pos @ self.frame.T + self.origin
        nrm = nrm @ self.frame.T
        nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
        tri = np.asarray(tri, np.int64).reshape(-1, 3).copy()
        p0, p1, p2 = pos[tri[:, 0]], pos[tri[:, 1]], pos[tri[:, 2]]
        geometric = _cross(p1 - p0, p2 - p0)
        wanted = nrm[tri[:, 0]] + nrm[tri[:, 1]] + nrm[tri[:, 2]]
        flip = np.einsum("ij,ij->i", geometric, wanted) < 0
        tri[flip] = tri[flip][:, [0, 2, 1]]
        self._pos.append(pos)
        self._nrm.append(nrm)
        self._uv.append(np.asarray(uv, np.float64).reshape(-1, 2))
        self._idx.append(tri + self._count)
        self._count += pos.shape[0]

    def quad(
        self,
        origin: Vec,
        u_axis: Vec,
        v_axis: Vec,
        uv_tile: float | None = None,
        uv_origin: Vec = (0.0, 0.0),
        rot: np.ndarray | None = None,
        pivot: Vec | None = None,
    ) -> None:
        """The parallelogram origin + s*u_axis + t*v_axis, facing cross(u_axis, v_axis).

        uvs run 0..1 over the quad, or (with ``uv_tile``) in metres / tile from ``uv_origin``.
        """
        o, u, v = (np.asarray(a, np.float64) for a in (origin, u_axis, v_axis))
        n = _cross(u, v)
        st = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], np.float64)
        pos = o + st[:, :1] * u + st[:, 1:] * v
        if uv_tile is None:
            uv = st
        else:
            uv = np.asarray(uv_origin, np.float64) + st * [
                np.linalg.norm(u) / uv_tile,
                np.linalg.norm(v) / uv_tile,
            ]
        self.add(pos, np.repeat(n[None], 4, axis=0), uv, _QUAD_TRIS, rot, pivot)

    def box(
        self,
        center: Vec,
        size: Vec,
        rot: np.ndarray | None = None,
        pivot: Vec | None = None,
        uv_tile: float | None = None,
    ) -> None:
        """An axis-aligned box (before ``rot`` about ``pivot``, default its centre).

        uvs run 0..1 over each face, or (with ``uv_tile``) in metres / tile from a face corner.
        """
        c = np.asarray(center, np.float64)
        half = 0.5 * np.abs(np.asarray(size, np.float64))
        n, u, v = _BOX_N, _BOX_U, _BOX_V
        hn, hu, hv = (np.abs(a) @ half for a in (n, u, v))  # half-extents along n, u, v per face
        st = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], np.float64)
        corner = n * hn[:, None] - u * hu[:, None] - v * hv[:, None]  # (6, 3)
        pos = (
            c
            + corner[:, None, :]
            + st[None, :, :1] * (2 * u * hu[:, None])[:, None, :]
            + st[None, :, 1:] * (2 * v * hv[:, None])[:, None, :]
        )
        if uv_tile is None:
            uv = np.broadcast_to(st, (6, 4, 2))
        else:
            uv = st[None] * (np.stack([2 * hu, 2 * hv], 1) / uv_tile)[:, None, :]
        nrm = np.repeat(n[:, None, :], 4, axis=1)
        tri = np.array([[0, 1, 2], [0, 2, 3]])[None] + 4 * np.arange(6)[:, None, None]
        self.add(
            pos.reshape(-1, 3),
            nrm.reshape(-1, 3),
            uv.reshape(-1, 2),
            tri.reshape(-1, 3),
            rot,
            c if pivot is None else pivot,
        )

    def cylinder(
        self,
        base: Vec,
        r_bottom: float,
        r_top: float,
        height: float,
        segments: int = 24,
        caps: bool = True,
        rot: np.ndarray | None = None,
        pivot: Vec | None = None,
    ) -> None:
        """A (truncated) cone along +Y from ``base``, with smooth side normals."""
        b = np.asarray(base, np.float64)
        a = np.linspace(0.0, 2 * np.pi, segments + 1)
        ca, sa = np.cos(a), np.sin(a)
        slope = (r_bottom - r_top) / height
        side_n = np.stack([ca, np.full_like(a, slope), sa], axis=1)
        ring_b = b + np.stack([r_bottom * ca, np.zeros_like(a), r_bottom * sa], axis=1)
        ring_t = b + np.stack([r_top * ca, np.full_like(a, height), r_top * sa], axis=1)
        pos = np.concatenate([ring_b, ring_t])
        nrm = np.concatenate([side_n, side_n])
        uv = np.concatenate(
            [
                np.stack([a / (2 * np.pi), np.zeros_like(a)], 1),
                np.stack([a / (2 * np.pi), np.ones_like(a)], 1),
            ]
        )
        k = np.arange(segments)
        m = segments + 1
        tri = np.concatenate(
            [np.stack([k, k + 1, k + m + 1], 1), np.stack([k, k + m + 1, k + m], 1)]
        )
        pv = b if pivot is None else pivot
        self.add(pos, nrm, uv, tri, rot, pv)
        if not caps:
            return
        for ring, r, ny in ((ring_b[:-1], r_bottom, -1.0), (ring_t[:-1], r_top, 1.0)):
            if r <= 0:
                continue
            centre = ring.mean(axis=0, keepdims=True)
            cpos = np.concatenate([centre, ring])
            cuv = np.concatenate([[[0.5, 0.5]], 0.5 + 0.5 * np.stack([ca[:-1], sa[:-1]], 1)])
            cn = np.repeat([[0.0, ny, 0.0]], segments + 1, axis=0)
            ctri = np.stack([np.zeros(segments, np.int64), 1 + k, 1 + (k + 1) % segments], 1)
            self.add(cpos, cn, cuv, ctri, rot, pv)

    def prism(
        self,
        outline_xz: np.ndarray,
        y0: float,
        y1: float,
        rot: np.ndarray | None = None,
        pivot: Vec | None = None,
        uv_tile: float = 1.0,
    ) -> None:
        """A vertical extrusion of a simple polygon (x, z) between heights y0 and y1."""
        poly = np.asarray(outline_xz, np.float64)
        x, z = poly[:, 0], poly[:, 1]
        if 0.5 * np.sum(x * np.roll(z, -1) - np.roll(x, -1) * z) < 0:
            poly = poly[::-1]
        tri = triangulate(poly)
        n = poly.shape[0]
        for y, ny in ((y1, 1.0), (y0, -1.0)):
            pos = np.stack([poly[:, 0], np.full(n, y), poly[:, 1]], 1)
            self.add(pos, np.repeat([[0.0, ny, 0.0]], n, 0), poly / uv_tile, tri, rot, pivot)
        nxt = np.roll(poly, -1, axis=0)
        d = nxt - poly
        out = np.stack([d[:, 1], np.zeros(n), -d[:, 0]], 1)
        out /= np.linalg.norm(out, axis=1, keepdims=True)
        along = np.concatenate([[0.0], np.cumsum(np.linalg.norm(d, axis=1))])
        for i in range(n):
            a, b = poly[i], nxt[i]
            pos = np.array([[a[0], y0, a[1]], [b[0], y0, b[1]], [b[0], y1, b[1]], [a[0], y1, a[1]]])
            uv = (
                np.array([[along[i], y0], [along[i + 1], y0], [along[i + 1], y1], [along[i], y1]])
                / uv_tile
            )
            self.add(pos, np.repeat(out[i : i + 1], 4, 0), uv, _QUAD_TRIS, rot, pivot)

    def mesh(self, name: str, material: int) -> Mesh:
        return Mesh(
            name,
            np.concatenate(self._pos).astype(np.float32),
            np.concatenate(self._nrm).astype(np.float32),
            np.concatenate(self._uv).astype(np.float32),
            np.concatenate(self._idx).astype(np.uint32),
            material,
        )


_BOX_N = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], np.float64)
_BOX_U = np.array([[0, 0, -1], [0, 0, 1], [1, 0, 0], [1, 0, 0], [1, 0, 0], [-1, 0, 0]], np.float64)
_BOX_V = np.array([[0, 1, 0], [0, 1, 0], [0, 0, -1], [0, 0, 1], [0, 1, 0], [0, 1, 0]], np.float64)


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise cross product (np.cross is slow on the small arrays built here)."""
    return np.stack(
        [
            a[..., 1] * b[..., 2] - a[..., 2] * b[..., 1],
            a[..., 2] * b[..., 0] - a[..., 0] * b[..., 2],
            a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0],
        ],
        axis=-1,
    )


def triangulate(poly: np.ndarray) -> np.ndarray:
    """Ear-clipping triangulation of a simple counter-clockwise (x, z) polygon: (n-2, 3) indices."""

    def cross(o: np.ndarray, a: np.ndarray, b: np.ndarray) -> float:
        return float((a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0]))

    remaining = list(range(len(poly)))
    out: list[tuple[int, int, int]] = []
    while len(remaining) > 3:
        m = len(remaining)
        for k in range(m):
            i0, i1, i2 = remaining[k - 1], remaining[k], remaining[(k + 1) % m]
            a, b, c = poly[i0], poly[i1], poly[i2]
            if cross(a, b, c) <= 1e-12:
                continue  # reflex or flat corner
            inside = False
            for j in remaining:
                if j in (i0, i1, i2):
                    continue
                p = poly[j]
                if cross(a, b, p) >= 0 and cross(b, c, p) >= 0 and cross(c, a, p) >= 0:
                    inside = True
                    break
            if not inside:
                out.append((i0, i1, i2))
                remaining.pop(k)
                break
        else:
            raise ValueError("polygon is not simple")
    out.append((remaining[0], remaining[1], remaining[2]))
    return np.asarray(out, np.int64)


# -- materials ----------------------------------------------------------------------------------


class _Materials:
    def __init__(self, textures: dict[str, Texture]) -> None:
        self.textures = list(textures.values())
        self._tex_index = {t.name: i for i, t in enumerate(self.textures)}
        self.materials: list[Material] = []
        self._by_name: dict[str, int] = {}

    def add(
        self,
        name: str,
        texture: str | None = None,
        color: tuple[float, float, float, float] = (1.0, 1.0, 1.0, 1.0),
        roughness: float = 0.6,
        metallic: float = 0.0,
        emissive: tuple[float, float, float] = (0.0, 0.0, 0.0),
    ) -> int:
        tex = None if texture is None else self._tex_index[texture]
        self._by_name[name] = len(self.materials)
        self.materials.append(Material(name, color, tex, roughness, metallic, emissive))
        return self._by_name[name]

    def __getitem__(self, name: str) -> int:
        return self._by_name[name]


def _showroom_materials(textures: dict[str, Texture]) -> _Materials:
    m = _Materials(textures)
    m.add("wallpaper", "wallpaper", roughness=0.9)
    m.add("parquet", "parquet", roughness=0.35)
    # the planks' relief (assets.textures.parquet_relief): render.normal_maps
    m.materials[m["parquet"]].normal_texture = m._tex_index["parquet_relief"]
    m.add("ceiling", "ceiling", roughness=0.95)
    m.add("white_paint", color=srgb(236, 232, 224), roughness=0.45)
    for name in PAINTING_ASPECTS:
        m.add(name, name, roughness=0.75)
    m.add("frame_black", color=srgb(22, 20, 20), roughness=0.35)
    m.add("frame_gold", color=srgb(212, 168, 84), roughness=0.3, metallic=0.9)
    m.add("frame_oak", "wood", color=srgb(255, 236, 200), roughness=0.5)
    m.add("piano_lacquer", color=srgb(8, 8, 9), roughness=0.06)
    m.add("piano_ivory", color=srgb(240, 236, 224), roughness=0.2)
    m.add("fabric", "fabric", roughness=0.95)
    m.add("walnut", "wood", roughness=0.45)
    m.add("rug", "rug", roughness=1.0)
    m.add("brass", color=srgb(190, 150, 90), roughness=0.3, metallic=1.0)
    m.add("lamp_shade", color=srgb(240, 228, 205), roughness=0.9, emissive=(0.9, 0.62, 0.32))
    m.add("window_sky", color=srgb(30, 34, 40), roughness=0.1, emissive=(0.62, 0.78, 1.0))
    m.materials[m["window_sky"]].sky_standin = True  # daylight shows the sky itself there
    m.add("blinds", color=srgb(226, 222, 212), roughness=0.4)
    m.add("switch_plastic", color=srgb(244, 242, 236), roughness=0.3)
    m.add("chrome", color=srgb(230, 230, 232), roughness=0.15, metallic=1.0)
    m.add("downlight", color=srgb(250, 245, 235), roughness=0.5, emissive=(2.0, 1.75, 1.45))
    m.add("leaves", color=srgb(52, 104, 44), roughness=0.7)
    m.add("terracotta", color=srgb(170, 90, 60), roughness=0.85)
    m.add("ceramic_blue", color=srgb(40, 80, 150), roughness=0.15)
    return m


# -- the room -----------------------------------------------------------------------------------


def _shell(mats: _Materials) -> list[Mesh]:
    """Floor, ceiling and four walls, all facing into the room, textures repeated."""
    meshes = []
    ex, ey, ez = np.eye(3)
    b = MeshBuilder()  # floor: u along +x, v along -z
    b.quad(
        (-HX, 0, HZ), ex * ROOM_X, -ez * ROOM_Z, WALL_TILE_M, (-HX / WALL_TILE_M, -HZ / WALL_TILE_M)
    )
    meshes.append(b.mesh("floor", mats["parquet"]))
    b = MeshBuilder()
    b.quad(
        (-HX, ROOM_H, -HZ),
        ex * ROOM_X,
        ez * ROOM_Z,
        CEILING_TILE_M,
        (-HX / CEILING_TILE_M, -HZ / CEILING_TILE_M),
    )
    meshes.append(b.mesh("ceiling", mats["ceiling"]))
    walls = [  # name, bottom-left corner seen from inside, direction to the right, length
        ("wall_north", (-HX, 0, -HZ), ex, ROOM_X),
        ("wall_east", (HX, 0, -HZ), ez, ROOM_Z),
        ("wall_south", (HX, 0, HZ), -ex, ROOM_X),
        ("wall_west", (-HX, 0, HZ), -ez, ROOM_Z),
    ]
    for name, corner, right, length in walls:
        b = MeshBuilder()
        if name == "wall_west":  # around the window's opening
            _wall_with_opening(b, np.asarray(corner, np.float64), right)
        else:
            b.quad(corner, right * length, ey * ROOM_H, WALL_TILE_M)
        meshes.append(b.mesh(name, mats["wallpaper"]))
    b = MeshBuilder()  # skirting boards, 10 cm high, 1.5 cm deep
    t, h = 0.015, 0.10
    b.box((0, h / 2, -HZ + t / 2), (ROOM_X, h, t))
    b.box((0, h / 2, HZ - t / 2), (ROOM_X, h, t))
    b.box((-HX + t / 2, h / 2, 0), (t, h, ROOM_Z - 2 * t))
    b.box((HX - t / 2, h / 2, 0), (t, h, ROOM_Z - 2 * t))
    meshes.append(b.mesh("skirting", mats["white_paint"]))
    return meshes


#: Where each painting hangs: wall, offset along the wall (to the right seen from inside, from the
#: wall's middle), centre height, canvas height (width follows the aspect) and frame material.
PAINTINGS: list[tuple[str, str, float, float, float, str]] = [
    ("painting_abstract", "north", -1.7, 1.65, 1.0, "frame_black"),
    ("painting_landscape", "north", 0.2, 1.65, 1.0, "frame_gold"),
    ("painting_stripes", "north", 2.3, 1.65, 0.96, "frame_black"),
    ("painting_circles", "east", -0.5, 1.62, 0.9, "frame_gold"),
    ("painting_colorfield", "south", 1.5, 1.62, 1.0, "frame_oak"),
]

_WALLS: dict[str, tuple[tuple[float, float, float], tuple[float, float, float]]] = {
    # wall -> (point at the middle of the wall on the floor, inward normal)
    "north": ((0.0, 0.0, -HZ), (0.0, 0.0, 1.0)),
    "south": ((0.0, 0.0, HZ), (0.0, 0.0, -1.0)),
    "east": ((HX, 0.0, 0.0), (-1.0, 0.0, 0.0)),
    "west": ((-HX, 0.0, 0.0), (1.0, 0.0, 0.0)),
}


def painting_center(index: int) -> tuple[float, float, float]:
    """World centre of painting ``index`` (1-based) on its canvas."""
    _, wall, along, height, _, _ = PAINTINGS[index - 1]
    point, normal = (np.asarray(v) for v in _WALLS[wall])
    right = np.cross([0.0, 1.0, 0.0], normal)
    c = point + right * along + normal * 0.025 + np.array([0.0, height, 0.0])
    return (float(c[0]), float(c[1]), float(c[2]))


def _paintings(mats: _Materials) -> list[Mesh]:
    meshes = []
    ey = np.array([0.0, 1.0, 0.0])
    for k, (tex, wall, along, height, canvas_h, frame_mat) in enumerate(PAINTINGS, start=1):
        point, normal = (np.asarray(v, np.float64) for v in _WALLS[wall])
        right = np.cross(ey, normal)
        w, h = canvas_h * PAINTING_ASPECTS[tex], canvas_h
        centre = point + right * along + ey * height
        canvas = MeshBuilder()
        canvas.quad(centre + normal * 0.025 - right * w / 2 - ey * h / 2, right * w, ey * h)
        meshes.append(canvas.mesh(f"painting_{k}", mats[tex]))
        frame = MeshBuilder()
        fw, fd = 0.06, 0.045  # moulding width and depth
        absr, absn = np.abs(right), np.abs(normal)
        pieces = (
            (0, (h + fw) / 2, w + 2 * fw, fw),
            (0, -(h + fw) / 2, w + 2 * fw, fw),
            ((w + fw) / 2, 0, fw, h),
            (-(w + fw) / 2, 0, fw, h),
        )
        for dx, dy, lx, ly in pieces:
            c = centre + right * dx + ey * dy + normal * fd / 2
            frame.box(c, absr * lx + ey * ly + absn * fd, uv_tile=0.5)
        meshes.append(frame.mesh(f"frame_{k}", mats[frame_mat]))
    return meshes


def _door_and_switch(mats: _Materials) -> list[Mesh]:
    door = MeshBuilder()
    door.box((3.0, 1.05, HZ - 0.0125), (0.9, 2.1, 0.025))  # the leaf
    for x0, x1, y0, y1 in ((2.45, 2.55, 0, 2.2), (3.45, 3.55, 0, 2.2), (2.45, 3.55, 2.1, 2.2)):
        door.box(((x0 + x1) / 2, (y0 + y1) / 2, HZ - 0.0175), (x1 - x0, y1 - y0, 0.035))
    for y0, y1 in ((0.25, 0.95), (1.15, 1.95)):  # raised panels
        door.box((3.0, (y0 + y1) / 2, HZ - 0.03), (0.62, y1 - y0, 0.01))
    handle = MeshBuilder()
    handle.cylinder((2.66, 1.0, HZ - 0.025), 0.028, 0.028, 0.012, 20, rot=rot_x(-90))
    handle.cylinder((2.66, 1.0, HZ - 0.037), 0.01, 0.01, 0.05, 12, rot=rot_x(-90))
    handle.box((2.72, 1.0, HZ - 0.09), (0.13, 0.018, 0.018))
    switch = MeshBuilder()
    switch.box((2.22, 1.05, HZ - 0.006), (0.086, 0.086, 0.012))  # plate
    switch.box((2.22, 1.05, HZ - 0.015), (0.032, 0.05, 0.006))  # rocker
    return [
        door.mesh("door", mats["white_paint"]),
        handle.mesh("door_handle", mats["chrome"]),
        switch.mesh("light_switch", mats["switch_plastic"]),
    ]


def _wall_with_opening(b: MeshBuilder, corner: np.ndarray, right: np.ndarray) -> None:
    """The west wall as four pieces around the window (wallpaper continuous across them)."""
    ey = np.array([0.0, 1.0, 0.0])
    a0, a1 = HZ - WINDOW_Z[1], HZ - WINDOW_Z[0]  # the opening along the wall, from its corner
    y0, y1 = WINDOW_Y
    pieces = [(0.0, ROOM_Z, 0.0, y0), (0.0, ROOM_Z, y1, ROOM_H), (0.0, a0, y0, y1)]
    pieces.append((a1, ROOM_Z, y0, y1))
    for s0, s1, t0, t1 in pieces:
        b.quad(
            corner + right * s0 + ey * t0,
            right * (s1 - s0),
            ey * (t1 - t0),
            WALL_TILE_M,
            (s0 / WALL_TILE_M, t0 / WALL_TILE_M),
        )


def _window(mats: _Materials) -> list[Mesh]:
    (z0, z1), (y0, y1) = WINDOW_Z, WINDOW_Y
    glass = MeshBuilder()  # the pane shows the sky: it glows and casts no shadow
    glass.quad((-HX + 0.005, y0, z1), (0, 0, z0 - z1), (0, y1 - y0, 0))
    frame = MeshBuilder()
    d = 0.05
    frame.box((-HX + d / 2, y1 + 0.03, (z0 + z1) / 2), (d, 0.06, z1 - z0 + 0.12))
    frame.box((-HX + 0.075, y0 - 0.03, (z0 + z1) / 2), (0.15, 0.06, z1 - z0 + 0.2))  # sill
    frame.box((-HX + d / 2, (y0 + y1) / 2, z0 - 0.03), (d, y1 - y0, 0.06))
    frame.box((-HX + d / 2, (y0 + y1) / 2, z1 + 0.03), (d, y1 - y0, 0.06))
    frame.box((-HX + 0.02, (y0 + y1) / 2, (z0 + z1) / 2), (0.04, y1 - y0, 0.05))  # mullion
    blinds = MeshBuilder()  # 9 cm slats 8 cm apart, tilted open 40 degrees (room side down)
    x = -HX + 0.075
    width = z1 - z0 - 0.04
    zc = (z0 + z1) / 2
    blinds.box((x, y1 - 0.03, zc), (0.08, 0.05, width))  # head rail
    slats, pitch = 16, 0.08
    for i in range(slats):
        y = y1 - 0.1 - i * pitch
        blinds.box((x, y, zc), (0.09, 0.003, width), rot=rot_z(-40.0))
    blinds.box((x, y1 - 0.1 - slats * pitch, zc), (0.07, 0.02, width))  # bottom rail
    for zl in (z0 + 0.35, zc, z1 - 0.35):  # ladder tapes
        blinds.box((x + 0.036, (y1 + y0) / 2 - 0.05, zl), (0.003, y1 - y0 - 0.1, 0.012))
        blinds.box((x - 0.036, (y1 + y0) / 2 - 0.05, zl), (0.003, y1 - y0 - 0.1, 0.012))
    return [
        glass.mesh("window", mats["window_sky"]),
        frame.mesh("window_frame", mats["white_paint"]),
        blinds.mesh("blinds", mats["blinds"]),
    ]


PIANO_POS = (-2.4, -1.6)
PIANO_YAW = 50.0  # the keyboard faces south-east, into the room


def _piano_outline(front_z: float) -> np.ndarray:
    """A grand piano's plan in its own frame: keyboard side at +z, straight bass side at -x."""
    t = np.linspace(0.0, 1.0, 12)
    s = t * t * (3 - 2 * t)
    treble = np.stack([0.75 - 0.7 * s, 0.15 - 0.75 * t], 1)  # bent side, S-curve
    a = np.linspace(0.0, -np.pi, 14)[1:]
    tail = np.stack([-0.35 + 0.4 * np.cos(a), -0.6 + 0.4 * np.sin(a)], 1)
    return np.concatenate([[[-0.75, front_z], [0.75, front_z]], treble, tail])


def _piano(mats: _Materials) -> list[Mesh]:
    body = MeshBuilder((PIANO_POS[0], 0.0, PIANO_POS[1]), PIANO_YAW)
    body.prism(_piano_outline(0.6), 0.66, 0.98)  # the case
    hinge = (-0.75, 1.0, 0.0)
    body.prism(_piano_outline(0.32), 0.98, 1.0, rot=rot_z(28.0), pivot=hinge)  # open lid
    body.box((0.6, 1.29, -0.05), (0.022, 0.62, 0.022), rot=rot_z(4.0))  # lid prop
    body.box((0.0, 0.67, 0.775), (1.5, 0.1, 0.35))  # key bed
    for sx in (-1, 1):  # cheek blocks either side of the keys
        body.box((sx * 0.72, 0.74, 0.775), (0.06, 0.16, 0.35))
    body.box((0.0, 0.81, 0.61), (1.38, 0.12, 0.06))  # fallboard / name board
    body.box((0.0, 1.13, 0.42), (0.8, 0.28, 0.02), rot=rot_x(-14.0))  # music desk
    for lx, lz in ((-0.65, 0.78), (0.65, 0.78), (-0.35, -0.78)):
        body.cylinder((lx, 0.0, lz), 0.035, 0.05, 0.66, 16)
    body.box((0.0, 0.33, 0.45), (0.2, 0.62, 0.05))  # pedal lyre
    white_w = 1.36 / 52
    letters = "ABCDEFG"
    for i in range(51):
        if letters[i % 7] in "ACDFG":  # a sharp follows A, C, D, F and G
            x = -0.68 + (i + 1) * white_w
            body.box((x, 0.752, 0.715), (0.013, 0.014, 0.19))
    keys = MeshBuilder((PIANO_POS[0], 0.0, PIANO_POS[1]), PIANO_YAW)
    for i in range(52):
        keys.box((-0.68 + (i + 0.5) * white_w, 0.7325, 0.77), (white_w - 0.0015, 0.025, 0.3))
    pedals = MeshBuilder((PIANO_POS[0], 0.0, PIANO_POS[1]), PIANO_YAW)
    for px in (-0.06, 0.0, 0.06):
        pedals.box((px, 0.07, 0.53), (0.03, 0.012, 0.12))
    bench = MeshBuilder((PIANO_POS[0], 0.0, PIANO_POS[1]), PIANO_YAW)
    bench.box((0.0, 0.49, 1.3), (0.8, 0.06, 0.36))
    for sx in (-1, 1):
        for sz in (-1, 1):
            bench.box((sx * 0.36, 0.23, 1.3 + sz * 0.14), (0.045, 0.46, 0.045))
    return [
        body.mesh("piano", mats["piano_lacquer"]),
        keys.mesh("piano_keys", mats["piano_ivory"]),
        pedals.mesh("piano_pedals", mats["brass"]),
        bench.mesh("piano_bench", mats["piano_lacquer"]),
    ]


SOFA_POS = (3.5, -0.5)
TABLE_POS = (2.2, -0.5)
CHAIR_POS = (1.0, -0.5)
LAMP_POS = (3.5, -2.3)
PLANT_POS = (-3.4, 2.4)
SIDEBOARD_POS = (-1.5, HZ - 0.23)


def _living_area(mats: _Materials) -> list[Mesh]:
    sofa = MeshBuilder((SOFA_POS[0], 0.0, SOFA_POS[1]), -90.0)  # faces -x, back to the wall
    tile = 0.35
    sofa.box((0.0, 0.24, 0.0), (1.7, 0.28, 0.9), uv_tile=tile)  # base
    sofa.box((0.0, 0.5, -0.34), (1.7, 0.72, 0.22), uv_tile=tile)  # back
    for sx in (-1, 1):
        sofa.box((sx * 0.925, 0.4, 0.0), (0.15, 0.6, 0.9), uv_tile=tile)  # arms
        for sz in (-1, 1):
            sofa.box((sx * 0.9, 0.05, sz * 0.38), (0.06, 0.1, 0.06), uv_tile=tile)  # feet
    for i in range(3):
        x = -0.565 + i * 0.565
        sofa.box((x, 0.445, 0.09), (0.555, 0.13, 0.68), uv_tile=tile)  # seat cushions
        sofa.box((x, 0.68, -0.17), (0.555, 0.34, 0.14), rot=rot_x(-8.0), uv_tile=tile)
    table = MeshBuilder((TABLE_POS[0], 0.0, TABLE_POS[1]))
    table.box((0.0, 0.42, 0.0), (0.6, 0.04, 1.1), uv_tile=0.6)
    table.box((0.0, 0.12, 0.0), (0.5, 0.02, 1.0), uv_tile=0.6)  # lower shelf
    for sx in (-1, 1):
        for sz in (-1, 1):
            table.box((sx * 0.26, 0.2, sz * 0.51), (0.04, 0.4, 0.04), uv_tile=0.6)
    chair = MeshBuilder((CHAIR_POS[0], 0.0, CHAIR_POS[1]), 90.0)  # faces +x, towards the sofa
    chair.box((0.0, 0.45, 0.0), (0.46, 0.04, 0.46), uv_tile=0.5)
    for sx in (-1, 1):
        chair.box((sx * 0.2, 0.215, 0.2), (0.04, 0.43, 0.04), uv_tile=0.5)  # front legs
        chair.box((sx * 0.2, 0.45, -0.2), (0.04, 0.9, 0.04), uv_tile=0.5)  # back legs / posts
        chair.box((sx * 0.2, 0.12, 0.0), (0.02, 0.03, 0.36), uv_tile=0.5)  # side stretchers
    for y in (0.62, 0.86):
        chair.box((0.0, y, -0.2), (0.36, 0.07 if y > 0.8 else 0.05, 0.025), uv_tile=0.5)
    for x in (-0.09, 0.0, 0.09):
        chair.box((x, 0.74, -0.2), (0.03, 0.2, 0.015), uv_tile=0.5)  # back spindles
    rug = MeshBuilder((2.05, 0.0, -0.5))
    rug.box((0.0, 0.006, 0.0), (2.4, 0.012, 3.0))
    lamp = MeshBuilder((LAMP_POS[0], 0.0, LAMP_POS[1]))
    lamp.cylinder((0, 0, 0), 0.17, 0.15, 0.03, 28)
    lamp.cylinder((0, 0.03, 0), 0.015, 0.015, 1.3, 12)
    shade = MeshBuilder((LAMP_POS[0], 0.0, LAMP_POS[1]))
    shade.cylinder((0, 1.3, 0), 0.23, 0.17, 0.32, 32)
    return [
        sofa.mesh("sofa", mats["fabric"]),
        table.mesh("coffee_table", mats["walnut"]),
        chair.mesh("chair", mats["walnut"]),
        rug.mesh("rug", mats["rug"]),
        lamp.mesh("floor_lamp", mats["brass"]),
        shade.mesh("lamp_shade", mats["lamp_shade"]),
    ]


def _decor(mats: _Materials) -> list[Mesh]:
    sideboard = MeshBuilder((SIDEBOARD_POS[0], 0.0, SIDEBOARD_POS[1]))
    sideboard.box((0.0, 0.46, 0.0), (1.6, 0.64, 0.42), uv_tile=0.8)
    for sx in (-1, 1):
        for sz in (-1, 1):
            sideboard.box((sx * 0.74, 0.07, sz * 0.16), (0.04, 0.14, 0.04), uv_tile=0.8)
    for x in (-0.4, 0.0, 0.4):  # door gaps
        sideboard.box((x, 0.46, -0.212), (0.008, 0.58, 0.006), uv_tile=0.8)
    vase = MeshBuilder((SIDEBOARD_POS[0] + 0.5, 0.78, SIDEBOARD_POS[1]))
    vase.cylinder((0, 0, 0), 0.06, 0.1, 0.18, 24)
    vase.cylinder((0, 0.18, 0), 0.1, 0.04, 0.12, 24)
    pot = MeshBuilder((PLANT_POS[0], 0.0, PLANT_POS[1]))
    pot.cylinder((0, 0, 0), 0.16, 0.21, 0.4, 28)
    plant = MeshBuilder((PLANT_POS[0], 0.0, PLANT_POS[1]))
    rng = np.random.default_rng(LIGHT_SEED + 1)
    for i in range(14):
        heading = i * (360.0 / 14) + float(rng.uniform(-10, 10))
        tilt = float(rng.uniform(18, 42))
        length = float(rng.uniform(0.5, 0.75))
        base = np.array([0.0, 0.38, 0.0])
        r = rot_y(heading) @ rot_x(-tilt)
        plant.box(base + np.array([0.0, length / 2, 0.0]), (0.1, length, 0.008), rot=r, pivot=base)
    downlights = MeshBuilder()
    for x, z in _four_light_xz():
        downlights.cylinder((x, ROOM_H - 0.015, z), 0.09, 0.09, 0.015, 24)
    return [
        sideboard.mesh("sideboard", mats["walnut"]),
        vase.mesh("vase", mats["ceramic_blue"]),
        pot.mesh("plant_pot", mats["terracotta"]),
        plant.mesh("plant", mats["leaves"]),
        downlights.mesh("ceiling_lights", mats["downlight"]),
    ]


# -- lights -------------------------------------------------------------------------------------


def _four_light_xz() -> list[tuple[float, float]]:
    return [(-2.0, -1.5), (2.0, -1.5), (-2.0, 1.5), (2.0, 1.5)]


#: (x, z) centre, radius and top height of what a light hung low in the room must clear.
_TALL_FURNITURE: list[tuple[tuple[float, float], float, float]] = [
    (PIANO_POS, 1.3, 1.7),  # the piano with its lid open
    (LAMP_POS, 0.45, 1.62),  # the floor lamp
]


def _shell_samples() -> tuple[np.ndarray, np.ndarray]:
    """Points and inward normals on the floor and walls, to compare light setups."""
    xs = np.linspace(-HX + 0.25, HX - 0.25, 16)
    zs = np.linspace(-HZ + 0.25, HZ - 0.25, 12)
    ys = np.linspace(0.3, 2.4, 5)
    pts: list[np.ndarray] = []
    nrm: list[np.ndarray] = []
    gx, gz = np.meshgrid(xs, zs)
    pts.append(np.stack([gx.ravel(), np.zeros(gx.size), gz.ravel()], 1))
    nrm.append(np.tile([0.0, 1.0, 0.0], (gx.size, 1)))
    for fixed, normal, axis, values in (
        (-HZ, (0, 0, 1), 0, xs),
        (HZ, (0, 0, -1), 0, xs),
        (-HX, (1, 0, 0), 2, zs),
        (HX, (-1, 0, 0), 2, zs),
    ):
        a, y = np.meshgrid(values, ys)
        p = np.zeros((a.size, 3))
        p[:, axis] = a.ravel()
        p[:, 1] = y.ravel()
        p[:, 2 - axis] = fixed
        pts.append(p)
        nrm.append(np.tile(np.asarray(normal, np.float64), (a.size, 1)))
    return np.concatenate(pts), np.concatenate(nrm)


def shell_irradiance(lights: Sequence[PointLight]) -> float:
    """Mean Lambert irradiance over floor and walls under our renderer's light model."""
    pts, nrm = _shell_samples()
    total = np.zeros(pts.shape[0])
    for light in lights:
        v = np.asarray(light.position, np.float64) - pts
        d = np.linalg.norm(v, axis=1)
        cos = np.clip(np.einsum("ij,ij->i", v, nrm) / np.maximum(d, 1e-9), 0.0, None)
        lum = float(np.dot(light.color, (0.2126, 0.7152, 0.0722)))
        total += lum * light.intensity * cos * lamp_falloff(d * d, light.range_m)
    return float(total.mean())


def make_lights(count: int) -> list[PointLight]:
    """Four warm ceiling lights, or ``count`` jittered lights (seeded) with matched brightness."""
    if count < 0:
        raise ValueError(f"light count must be >= 0, got {count}")
    four = [
        PointLight((x, 2.6, z), WARM_WHITE, FOUR_LIGHT_INTENSITY, FOUR_LIGHT_RANGE_M)
        for x, z in _four_light_xz()
    ]
    if count == 4:
        return four
    if count == 0:
        return []
    rng = np.random.default_rng(LIGHT_SEED)
    nz = max(1, round(math.sqrt(count * ROOM_Z / ROOM_X)))
    nx = math.ceil(count / nz)
    cells = rng.permutation(nx * nz)[:count]
    cells.sort()
    ix, iz = cells % nx, cells // nx
    margin = 0.25
    cx = (ROOM_X - 2 * margin) / nx
    cz = (ROOM_Z - 2 * margin) / nz
    x = -HX + margin + (ix + rng.uniform(0.15, 0.85, count)) * cx
    z = -HZ + margin + (iz + rng.uniform(0.15, 0.85, count)) * cz
    y = rng.uniform(1.2, 2.6, count)
    for (ox, oz), radius, top in _TALL_FURNITURE:  # stay above what stands beneath
        near = np.hypot(x - ox, z - oz) < radius
        y[near] = np.maximum(y[near], top + 0.2 + 0.5 * (y[near] - 1.2) / 1.4)
    tint = np.clip(np.asarray(WARM_WHITE) + rng.uniform(-0.04, 0.04, (count, 3)), 0.0, 1.0)
    lights = [
        PointLight(
            (float(x[i]), float(y[i]), float(z[i])),
            (float(tint[i, 0]), float(tint[i, 1]), float(tint[i, 2])),
            1.0,
            GRID_LIGHT_RANGE_M,
        )
        for i in range(count)
    ]
    scale = shell_irradiance(four) / max(shell_irradiance(lights), 1e-12)
    for light in lights:
        light.intensity = round(scale, 6)
    return lights


# -- scenes -------------------------------------------------------------------------------------

SPAWN = Viewpoint((3.0, EYE_HEIGHT, 2.3), yaw_deg=20.0, pitch_deg=-4.0)


def build_showroom(lights: int = 4) -> Scene:
    """The furnished showroom with ``lights`` point lights (4: ceiling lights; N: jittered grid)."""
    textures = make_textures()
    mats = _showroom_materials(textures)
    meshes = (
        _shell(mats)
        + _paintings(mats)
        + _door_and_switch(mats)
        + _window(mats)
        + _piano(mats)
        + _living_area(mats)
        + _decor(mats)
    )
    name = "showroom" if lights == 4 else f"showroom-{lights}"
    scene = Scene(
        name,
        meshes,
        mats.materials,
        mats.textures,
        make_lights(lights),
        Viewpoint(SPAWN.position, SPAWN.yaw_deg, SPAWN.pitch_deg),
        floor_y=0.0,
        source="built-in",
        north_deg=NORTH_DEG,
    )
    return scene.sanitized()


def build_texture_test_scene() -> Scene:
    """A 2 x 2 m quad facing +Z at z = -2, centred at eye height, showing four coloured quadrants.

    Seen from the spawn (0, 1.6, 0) looking down -Z, the top-left of the screen is red, top-right
    green, bottom-left blue and bottom-right white.
    """
    b = MeshBuilder()
    b.quad((-1.0, EYE_HEIGHT - 1.0, -2.0), (2.0, 0.0, 0.0), (0.0, 2.0, 0.0))
    material = Material("checker", (1.0, 1.0, 1.0, 1.0), 0, roughness=1.0)
    scene = Scene(
        "texture-test",
        [b.mesh("checker_quad", 0)],
        [material],
        [checker_quadrants()],
        [PointLight((0.0, EYE_HEIGHT, 0.0), (1.0, 1.0, 1.0), 4.8, 10.0)],  # 1.2 lux at 2 m
        Viewpoint((0.0, EYE_HEIGHT, 0.0), 0.0, 0.0),
        floor_y=0.0,
        source="built-in",
    )
    return scene.sanitized()
