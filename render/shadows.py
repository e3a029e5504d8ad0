"""Shadow maps: one depth atlas, drawn only when a light or the geometry changes.

Every light that casts shadows and reaches a surface in view gets tiles of the atlas: six
perspective cube faces for a point light, one perspective tile for a spot, one orthographic tile
fitted to the scene's bounds for the sun (a directional light). A tile's size follows the light's
size on screen (its range sphere's projected radius, 256 to 1024 texels a face; the sun 2048), so
a lamp far away costs little. Maps are cached: the key is the light's parameters, its tile and the
scene (a new ``GpuScene`` is new geometry); a static interior draws each map once and reuses it.
After a new scene's first frame (which draws every map), at most
``render.shadow_updates_per_frame`` lights are redrawn at a time (the most prominent first), and
each of them by at most ``FACES_PER_FRAME`` tiles a frame: a point light's six faces take three
frames (a lamp coming into view while walking cost one frame 10-15 ms in the corridor, over the
30 fps budget; a third of that fits), six at one light at a time (the frame-rate governor's
lowered step: about 2 ms a frame in the corridor). A light being redrawn keeps its last map's
matrices until its new one is complete (a moved lamp's shadow may mix old and new faces for a
few frames), or has no shadow until its first. A light whose wanted tile size changes by one
step (2x) keeps its tiles.

The pass fills the ``Shadows`` uniform block (shadows.glsl, binding 1) and binds the atlas to its
texture unit every frame, so every lighting path (deferred compute and fragment, forward, coarse
pixel shading) reads the same maps without binding anything itself.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import moderngl
import numpy as np

from app.camera import EyeView
from app.scene import Light
from render.constants import (
    MAX_LIGHTS,
    MAX_SHADOW_TILES,
    SHADOW_ATLAS,
    SHADOW_MASK_SLOTS,
    TEXTURE_UNITS,
)
from render.gpu_scene import GpuScene, light_rows, spot_cosines
from render.pass_graph import FrameContext, RenderPass, Resources, set_uniforms
from render.shaders import ShaderLibrary

MODES = {"off": 0, "hard": 1, "soft": 2}
MIN_FACE, MAX_FACE = 256, 1024  # a lamp's tile edge, texels
FACES_PER_FRAME = 2  # tiles a light being redrawn gets a frame (after a new scene's first)
SUN_TILE = 2048
NEAR_M = 0.05  # perspective maps' near plane
# glPolygonOffset(factor, units) while drawing a lamp's depth: against acne on the surfaces a
# lamp lights at a slant. The sun's map is drawn the other way, its occluders a slope's texel
# towards the sun: its texels are half a centimetre, so a wall or a skirting board the sun
# grazes changes depth by several centimetres a texel, and with the lamps' offset pushed back
# a decimetre the sun leaked in dotted lines where walls meet the ceiling and along the
# skirting boards (a soft edge's taps still leaked without any offset). The normal offset in
# shadows.glsl keeps a sunlit floor free of acne down to a 12-degree sun (at -1.25 a low
# sun's soft edge speckles the floor: tests/test_shadows.py guards both sides).
SLOPE_OFFSET = (2.0, 4.0)
SUN_SLOPE_OFFSET = (-1.0, 0.0)
# Soft shadows: the edge's half width on the receiving surface (metres); a lamp's shade is wide,
# the sun's disc small (half a degree: about 1 cm at a metre or two from the blinds).
SOFT_RADIUS_M = {
    "point": 0.025,
    "spot": 0.02,
    "directional": 0.006,
}
# Cube faces: the direction each looks along and its up vector.
CUBE_FACES = (
    ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0)),
    ((-1.0, 0.0, 0.0), (0.0, 1.0, 0.0)),
    ((0.0, 1.0, 0.0), (0.0, 0.0, 1.0)),
    ((0.0, -1.0, 0.0), (0.0, 0.0, 1.0)),
    ((0.0, 0.0, 1.0), (0.0, 1.0, 0.0)),
    ((0.0, 0.0, -1.0), (0.0, 1.0, 0.0)),
)


# -- matrices -----------------------------------------------------------------------------------


def look_at(eye: np.ndarray, forward: np.ndarray, up: np.ndarray) -> np.ndarray:
    """World -> view for a camera at ``eye`` looking along ``forward`` (OpenGL: down -z)."""
    z = -forward / np.linalg.norm(forward)
    if abs(float(np.dot(z, up))) > 0.99 * float(np.linalg.norm(up)):
        up = np.array([1.0, 0.0, 0.0]) if abs(z[0]) < 0.9 else np.array([0.0, 0.0, 1.0])
    x = np.cross(up, z)
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    m = np.eye(4)
    m[0, :3], m[1, :3], m[2, :3] = x, y, z
    m[:3, 3] = -m[:3, :3] @ eye
    return m


def perspective(tan_half: float, near: float, far: float) -> np.ndarray:
    m = np.zeros((4, 4))
    m[0, 0] = m[1, 1] = 1.0 / tan_half
    m[2, 2] = (far + near) / (near - far)
    m[2, 3] = 2.0 * far * near / (near - far)
    m[3, 2] = -1.0
    return m


def orthographic(radius: float, near: float, far: float) -> np.ndarray:
    m = np.eye(4)
    m[0, 0] = m[1, 1] = 1.0 / radius
    m[2, 2] = -2.0 / (far - near)
    m[2, 3] = -(far + near) / (far - near)
    return m


def to_tile(x: int, y: int, size: int) -> np.ndarray:
    """Clip space -> atlas (u, v, depth) of the tile at (x, y) (before the divide)."""
    s = size / SHADOW_ATLAS
    m = np.eye(4)
    m[0, 0] = m[1, 1] = 0.5 * s
    m[0, 3] = x / SHADOW_ATLAS + 0.5 * s
    m[1, 3] = y / SHADOW_ATLAS + 0.5 * s
    m[2, 2] = m[2, 3] = 0.5
    return m


# -- the atlas's space ---------------------------------------------------------------------------


class BuddyAtlas:
    """Power-of-two square tiles of a square atlas; freed siblings merge again."""

    def __init__(self, size: int) -> None:
        self.size = size
        self.free: dict[int, set[tuple[int, int]]] = {size: {(0, 0)}}

    def alloc(self, size: int) -> tuple[int, int] | None:
        s = size
        while s <= self.size and not self.free.get(s):
            s *= 2
        if s > self.size:
            return None
        x, y = min(self.free[s])  # deterministic
        self.free[s].discard((x, y))
        while s > size:
            s //= 2
            for dx, dy in ((s, 0), (0, s), (s, s)):
                self.free.setdefault(s, set()).add((x + dx, y + dy))
        return x, y

    def release(self, x: int, y: int, size: int) -> None:
        while size < self.size:
            parent = (x - x % (2 * size), y - y % (2 * size))
            siblings = {(parent[0] + dx, parent[1] + dy) for dx in (0, size) for dy in (0, size)}
            others = siblings - {(x, y)}
            if not others <= self.free.get(size, set()):
                break
            self.free[size] -= others
            x, y, size = parent[0], parent[1], size * 2
        self.free.setdefault(size, set()).add((x, y))


# -- what one light's map is ---------------------------------------------------------------------


@dataclass
class ShadowMap:
    """One light's tiles and the parameters its content was drawn with."""

    size: int
    tiles: list[tuple[int, int]]  # atlas texel origin of each tile (6 for a point light)
    drawn_key: tuple | None = None  # the light key of what the tiles hold (None: nothing yet)
    matrices: list[np.ndarray] = field(default_factory=list)  # world -> atlas, per tile
    texel: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 0.0)  # shadows.glsl's shadow_texel
    # A redraw under way (FACES_PER_FRAME tiles a frame): its key, the tiles done, and what
    # the lookups take once it is complete (until then they keep the last complete map).
    drawing_key: tuple | None = None
    faces_done: int = 0
    next: tuple = ()  # (views, matrices, texel) of the redraw under way


def light_key(light: Light) -> tuple:
    return tuple(round(float(v), 6) for v in light_rows([light])[0])


def faces_of(light: Light) -> int:
    return 6 if light.kind == "point" else 1


def scene_bounds(scene: GpuScene) -> tuple[np.ndarray, float]:
    """Centre and radius of the sphere around every shadow-casting mesh (not the glowing)."""
    points = [
        np.asarray(m.positions, np.float64).reshape(-1, 3)
        for m, g in zip(scene.scene.meshes, scene.meshes)
        if casts(g) and len(m.positions)
    ]
    if not points:
        return np.zeros(3), 1.0
    allp = np.concatenate(points)
    lo, hi = allp.min(axis=0), allp.max(axis=0)
    return 0.5 * (lo + hi), max(0.5 * float(np.linalg.norm(hi - lo)), 0.01)


def casts(mesh) -> bool:
    """Glowing surfaces (the sky beyond a window, a lamp's bulb) and glass (blended) cast no
    shadow: a window pane lets the sun through."""
    return not any(mesh.material.emissive) and mesh.material.alpha_mode != "BLEND"


def frustum_planes(view_projection: np.ndarray) -> np.ndarray:
    """The six planes (a, b, c, d; inside: ax + by + cz + d >= 0, normalised) of a frustum."""
    m = view_projection
    planes = np.array(
        [m[3] + m[0], m[3] - m[0], m[3] + m[1], m[3] - m[1], m[3] + m[2], m[3] - m[2]]
    )
    return planes / np.linalg.norm(planes[:, :3], axis=1, keepdims=True)


def wanted_sizes(lights: list[Light], eyes: list[EyeView]) -> dict[int, int]:
    """Per light whose range sphere meets either eye's frustum (the sun always does), its
    tile edge from its influence on screen: the projected radius of its range sphere in
    pixels, as a power of two within MIN_FACE..MAX_FACE (the sun: SUN_TILE). Every light at
    once (the corridor holds a hundred)."""
    local = [i for i, light in enumerate(lights) if light.kind != "directional"]
    size = np.zeros(len(local), np.int64)
    reach = np.zeros(len(local), bool)
    if local and eyes:
        pos = np.array([lights[i].position for i in local], np.float64)
        r = np.array([lights[i].range_m for i in local], np.float64)
        homo = np.c_[pos, np.ones(len(pos))]
        best = np.zeros(len(local))
        inside = np.zeros(len(local), bool)
        for eye in eyes:
            planes = frustum_planes(eye.view_projection)
            reach |= np.all(homo @ planes.T >= -r[:, None], axis=1)
            d = np.linalg.norm(pos - np.asarray(eye.position, np.float64), axis=1)
            inside |= d <= r
            px = float(eye.projection[1, 1]) * eye.height / 2
            radius = r / np.sqrt(np.maximum(d * d - r * r, 1e-12)) * px
            best = np.maximum(best, np.where(d <= r, 0.0, radius))
        edge = np.exp2(np.ceil(np.log2(np.maximum(best, 1.0))))
        size = np.where(inside, MAX_FACE, np.clip(edge, MIN_FACE, MAX_FACE)).astype(np.int64)
    at = {i: k for k, i in enumerate(local)}
    out = {}
    for i, light in enumerate(lights):
        if light.kind == "directional":
            out[i] = SUN_TILE
        elif reach[at[i]]:
            out[i] = int(size[at[i]])
    return out


def fit_sizes(
    wanted: dict[int, tuple[int, int]], capacity: int, current: dict[int, int] | None = None
) -> dict[int, tuple[int, int]]:
    """Halve the tiles of the light that takes the most texels until the lights' tiles fit
    ``capacity`` texels (size, faces); among equals first those that would not keep their
    ``current`` size (no redraw for them).

    By the light's texels, not its tile's edge: a lamp inside its range wants six 1024 tiles
    (6.3 M texels), the sun one 2048 tile (4.2 M) for the whole room. Halving the largest edge
    first gave the daylit showroom's sun 1 cm texels (the lamps near the eye filled the atlas),
    and hard shadows leaked sunlight in dots where a wall meets a skirting board (the sun
    grazing the wall: a texel's error there is as deep as the few centimetres that shut the
    corner; the shadow mask's part in those dots: shadow_mask.frag.glsl)."""
    sizes = dict(wanted)
    now = current or {}
    while sum(s * s * n for s, n in sizes.values()) > capacity:
        halvable = [k for k, (s, _n) in sizes.items() if s > 64]
        if not halvable:
            break
        i = max(
            halvable,
            key=lambda k: (
                sizes[k][0] ** 2 * sizes[k][1],
                sizes[k][0],
                now.get(k) != sizes[k][0],
                k,
            ),
        )
        s, n = sizes[i]
        sizes[i] = (s // 2, n)
    return sizes


def map_matrices(
    light: Light, size: int, tiles: list[tuple[int, int]], bounds: tuple[np.ndarray, float]
) -> tuple[list[np.ndarray], list[np.ndarray], tuple[float, float, float, float]]:
    """Per tile the light's view-projection and world -> atlas matrix; the texel terms."""
    pos = np.asarray(light.position, np.float64)
    direction = np.asarray(light.direction, np.float64)
    n = float(np.linalg.norm(direction))
    direction = direction / n if n > 1e-12 else np.array([0.0, -1.0, 0.0])
    views: list[np.ndarray] = []
    if light.kind == "directional":
        centre, radius = bounds
        view = look_at(centre - direction * radius * 1.05, direction, np.array([0.0, 1.0, 0.0]))
        views.append(orthographic(radius, 0.0, 2.1 * radius) @ view)
        texel = (1.0 / SHADOW_ATLAS, 2.0 * radius / size, 0.0, SOFT_RADIUS_M["directional"])
    else:
        far = max(light.range_m, NEAR_M * 2)
        if light.kind == "spot":
            cos_o, _ = spot_cosines(light)
            half = min(math.acos(cos_o) + math.radians(2.0), math.radians(85.0))
            tan_half = math.tan(half)
            faces = [(direction, np.array([0.0, 1.0, 0.0]))]
        else:
            tan_half = 1.0 + 4.0 / size  # a few texels beyond 90 degrees: the filter's margin
            faces = [(np.asarray(f), np.asarray(u)) for f, u in CUBE_FACES]
        proj = perspective(tan_half, NEAR_M, far)
        views = [proj @ look_at(pos, f, u) for f, u in faces]
        texel = (1.0 / SHADOW_ATLAS, 2.0 * tan_half / size, 1.0, SOFT_RADIUS_M[light.kind])
    atlas = [to_tile(x, y, size) @ vp for vp, (x, y) in zip(views, tiles)]
    return views, atlas, texel


# -- the pass ------------------------------------------------------------------------------------


class ShadowPass(RenderPass):
    """Before everything that lights: redraw the shadow maps that changed (within the per-frame
    budget), fill the Shadows block and bind the atlas."""

    name = "shadows"
    writes = ("shadow_maps",)

    def __init__(self, ctx: moderngl.Context, shaders: ShaderLibrary, res: Resources) -> None:
        super().__init__(ctx, shaders, res)
        self.mode = MODES["soft"]
        self.budget = 2
        self.block = ctx.buffer(reserve=_block_bytes())
        self.dummy = ctx.depth_texture((1, 1))
        _shadow_sampling(self.dummy)
        self.atlas: moderngl.Texture | None = None
        self.fbo: moderngl.Framebuffer | None = None
        self.space = BuddyAtlas(SHADOW_ATLAS)
        self.maps: dict[int, ShadowMap] = {}
        self.shaders.variant["SHADOW_FILTER"] = self.mode  # the default, for the warm-up
        self._scene: tuple | None = None
        self._scene_obj: GpuScene | None = None
        self._generation = 0
        self._bounds: tuple[np.ndarray, float] = (np.zeros(3), 1.0)
        # Statistics: lights drawn (a point light's six faces count once), ever and last frame.
        self.renders = 0
        self.face_renders = 0
        self.updates = 0
        self.pending = 0  # lights waiting for a redraw (or its end) after this frame
        self.frame_faces = 0  # tiles drawn this frame
        self.shadowed = 0  # lights with a map in use this frame
        self.mask_slots: list[int] = []  # the lights of the shadow mask's slots, in order

    def configure(self, settings, scene, frame) -> bool:
        self.mode = MODES.get(settings.render.shadows, MODES["soft"])
        self.budget = max(1, int(settings.render.shadow_updates_per_frame))
        # Off or no light that casts: the lighting compiles without the lookups.
        needed = any(light.casts_shadows for light in scene.light_list)
        self.shaders.variant["SHADOW_FILTER"] = self.mode if needed else 0
        return True  # also when off: the block then says so

    @property
    def memory_bytes(self) -> int:
        """GPU memory of the shadow maps (the atlas, 32-bit depth; 0 until a light needs it)."""
        return SHADOW_ATLAS * SHADOW_ATLAS * 4 if self.atlas is not None else 0

    def stats(self) -> dict:
        return {
            "shadow_memory_bytes": self.memory_bytes,
            "shadowed_lights": self.shadowed,
            "shadow_updates": self.updates,
            "shadow_updates_waiting": self.pending,
            "shadow_maps_drawn": self.renders,
        }

    # -- per frame ---------------------------------------------------------------------------
    def run(self, frame: FrameContext) -> None:
        """As every pass, timed; llvmpipe's timer query around the depth draws into the atlas
        reads 2^32 ns, so a frame that draws maps is timed on the clock (it waits for the GPU
        then: rare, maps are cached)."""
        start = time.perf_counter()
        self.frame_faces = 0
        super().run(frame)
        if self.frame_faces:
            self.ctx.finish()
            self._timed = False  # the clock's reading stands, not the query's
            self.last_ms = (time.perf_counter() - start) * 1000.0

    def execute(self, frame: FrameContext, res: Resources) -> None:
        scene = frame.scene
        lights = scene.light_list
        first = scene is not self._scene_obj
        if first:  # new geometry: every map is stale
            self._scene_obj = scene  # held, so a new scene can never reuse its id
            self._generation += 1
            self._scene = (self._generation,)
            self._drop_all()
            self._bounds = scene_bounds(scene)
        if frame.warming and not first:  # the maps as they are: none drawn, moved or resized
            self._bind(res)
            return
        self.updates = 0
        self.pending = 0
        wanted: dict[int, tuple[int, int]] = {}
        if self.mode:
            sizes = wanted_sizes(lights, frame.eyes)
            for i, light in enumerate(lights):
                if (
                    light.casts_shadows
                    and light.intensity > 0.0
                    and math.isfinite(light.intensity)
                    and i in sizes
                ):
                    wanted[i] = (sizes[i], faces_of(light))
        for i, (size, faces) in wanted.items():  # hysteresis: a step of 2x keeps the tiles
            if i in self.maps and size // 2 <= self.maps[i].size <= size * 2:
                wanted[i] = (self.maps[i].size, faces)
        wanted = self._within_tiles(wanted, lights, frame.eyes)
        current = {i: m.size for i, m in self.maps.items()}
        wanted = fit_sizes(wanted, SHADOW_ATLAS * SHADOW_ATLAS, current)
        self._allocate(wanted, lights)
        keys = {i: (light_key(lights[i]), self._scene) for i in wanted}
        dirty = [i for i in wanted if self.maps[i].drawn_key != keys[i]]
        # Redraws under way go on first (then the most prominent): a lamp's shadow is not left
        # half drawn while others start.
        dirty.sort(key=lambda i: self.maps[i].drawing_key != keys[i])
        # A new scene's first frame draws every map (it stalls for its shaders anyway, and a
        # still picture is then complete); later changes wait for the budget.
        budget = len(dirty) if first else self.budget
        # One light at a time (the governor's lowered step): one tile a frame, half the cost.
        per_light = None if first else (FACES_PER_FRAME if self.budget > 1 else 1)
        for i in dirty[:budget]:
            self._draw(frame, i, lights[i], per_light)
        self.pending = sum(1 for i in dirty if self.maps[i].drawn_key != keys[i])
        self._upload(wanted)
        self._bind(res)

    def _bind(self, res: Resources) -> None:
        """The Shadows block and the atlas (filtered for the mode) for the passes that light;
        the mask's lights."""
        self.block.bind_to_uniform_block(1)
        if self.atlas is not None:  # hard: one texel per lookup; soft: bilinear comparisons
            f = moderngl.NEAREST if self.mode == MODES["hard"] else moderngl.LINEAR
            self.atlas.filter = (f, f)
        (self.atlas or self.dummy).use(TEXTURE_UNITS["shadow_atlas"])
        # For the shadow mask (render/shadow_mask.py): its lights, and how many have shadows.
        res.put("shadow_maps", (list(self.mask_slots) if self.mode else [], self.shadowed))

    def _within_tiles(
        self, wanted: dict[int, tuple[int, int]], lights: list[Light], eyes: list[EyeView]
    ) -> dict[int, tuple[int, int]]:
        """The most prominent lights whose tiles fit the block (the sun, then the nearest)."""

        order = list(wanted)
        near = np.full(len(order), np.inf)
        if order and eyes:
            pos = np.array([lights[i].position for i in order], np.float64)
            for e in eyes:
                near = np.minimum(near, np.linalg.norm(pos - np.asarray(e.position), axis=1))
        gap = {i: float(d) - lights[i].range_m for i, d in zip(order, near)}

        def prominence(i: int) -> tuple:
            if lights[i].kind == "directional":
                return (0, 0.0, i)
            return (1, gap[i], i)

        out: dict[int, tuple[int, int]] = {}
        used = 0
        for i in sorted(wanted, key=prominence):
            if used + wanted[i][1] <= MAX_SHADOW_TILES:
                out[i] = wanted[i]
                used += wanted[i][1]
        return out

    def _allocate(self, wanted: dict[int, tuple[int, int]], lights: list[Light]) -> None:
        if wanted and self.atlas is None:
            self.atlas = self.ctx.depth_texture((SHADOW_ATLAS, SHADOW_ATLAS))
            _shadow_sampling(self.atlas)
            self.fbo = self.ctx.framebuffer(depth_attachment=self.atlas)
        for i in list(self.maps):  # resized or no longer a light: free the tiles
            if i >= len(lights) or (i in wanted and self.maps[i].size != wanted[i][0]):
                self._free(i)
        missing = [
            i for i in sorted(wanted, key=lambda k: (-wanted[k][0], k)) if i not in self.maps
        ]
        for i in missing:
            if not self._try_alloc(i, *wanted[i]):
                # Out of room: lights out of view give theirs up first, then everything repacks
                # (largest first, which always fits what fit_sizes allowed).
                for j in [j for j in self.maps if j not in wanted]:
                    self._free(j)
                if not self._try_alloc(i, *wanted[i]):
                    self._drop_all()
                    for k in sorted(wanted, key=lambda k: (-wanted[k][0], k)):
                        self._try_alloc(k, *wanted[k])
                    return

    def _try_alloc(self, i: int, size: int, faces: int) -> bool:
        tiles: list[tuple[int, int]] = []
        for _ in range(faces):
            at = self.space.alloc(size)
            if at is None:
                for x, y in tiles:
                    self.space.release(x, y, size)
                return False
            tiles.append(at)
        self.maps[i] = ShadowMap(size, tiles)
        return True

    def _free(self, i: int) -> None:
        m = self.maps.pop(i)
        for x, y in m.tiles:
            self.space.release(x, y, m.size)

    def _drop_all(self) -> None:
        self.maps.clear()
        self.space = BuddyAtlas(SHADOW_ATLAS)

    def _draw(self, frame: FrameContext, i: int, light: Light, faces: int | None = None) -> None:
        """Draw light ``i``'s next ``faces`` tiles (None: all that are left); the map is used
        with its new matrices once every tile is drawn."""
        m = self.maps[i]
        key = (light_key(light), self._scene)
        if m.drawing_key != key:  # a new redraw: from the first tile
            m.drawing_key, m.faces_done = key, 0
            m.next = map_matrices(light, m.size, m.tiles, self._bounds)
        views = m.next[0]
        faces_now = list(range(m.faces_done, len(m.tiles)))[: (faces or len(m.tiles))]
        ctx, fbo = self.ctx, self.fbo
        assert fbo is not None
        prog = self.shaders.program("shadow_depth.vert.glsl", "shadow_depth.frag.glsl")
        scene = frame.scene
        fbo.use()
        ctx.enable(moderngl.DEPTH_TEST)
        ctx.disable(moderngl.CULL_FACE | moderngl.BLEND)
        ctx.polygon_offset = SUN_SLOPE_OFFSET if light.kind == "directional" else SLOPE_OFFSET
        casters = [k for k in scene.standalone if casts(scene.meshes[k])]
        groups = [k for k, g in enumerate(scene.groups) if casts(g)]  # merged meshes
        for f in faces_now:
            vp, (x, y) = views[f], m.tiles[f]
            rect = (x, y, m.size, m.size)
            fbo.viewport = rect
            fbo.clear(depth=1.0, viewport=rect)
            set_uniforms(prog, {"u_light_view_projection": vp})
            for k in groups:
                scene.draw_group(scene.group_vao(prog, k), k, vp)  # culled to the light's frustum
            for k in casters:
                scene.draw(scene.vao(prog, k), k, vp)
            self.face_renders += 1
            self.frame_faces += 1
        ctx.polygon_offset = (0.0, 0.0)
        ctx.disable(moderngl.DEPTH_TEST)
        m.faces_done += len(faces_now)
        if m.faces_done >= len(m.tiles):  # complete: the lookups take it from now on
            _, m.matrices, m.texel = m.next
            m.drawn_key = key
            self.renders += 1
            self.updates += 1

    def _upload(self, wanted: dict[int, tuple[int, int]]) -> None:
        info = np.zeros((MAX_LIGHTS, 4), np.int32)
        info[:, 0] = -1
        info[:, 2] = -1  # no slot in the shadow mask
        matrices = np.zeros((MAX_SHADOW_TILES, 4, 4), np.float32)
        rects = np.zeros((MAX_SHADOW_TILES, 4), np.float32)
        texels = np.zeros((MAX_SHADOW_TILES, 4), np.float32)
        tile = 0
        self.shadowed = 0
        self.mask_slots = []
        for i in wanted:  # the most prominent first (_within_tiles): they get the mask's slots
            m = self.maps.get(i)
            if m is None or m.drawn_key is None or not m.matrices:
                continue  # never drawn yet: no shadow this frame
            if len(self.mask_slots) < SHADOW_MASK_SLOTS:
                info[i, 2] = len(self.mask_slots)
                self.mask_slots.append(i)
            info[i, :2] = (tile, len(m.tiles))
            for (x, y), mat in zip(m.tiles, m.matrices):
                matrices[tile] = mat.T  # std140 mat4: columns
                rects[tile] = np.array([x, y, x + m.size, y + m.size]) / SHADOW_ATLAS
                texels[tile] = m.texel
                tile += 1
            self.shadowed += 1
        head = np.array([self.mode, SHADOW_ATLAS, 0, 0], np.int32)
        self.block.write(
            head.tobytes()
            + info.tobytes()
            + matrices.tobytes()
            + rects.tobytes()
            + texels.tobytes()
        )

    def release(self) -> None:
        super().release()
        for obj in (self.fbo, self.atlas, self.dummy, self.block):
            if obj is not None:
                obj.release()
        self.fbo = self.atlas = None
        self.maps.clear()


def _block_bytes() -> int:
    return 16 + MAX_LIGHTS * 16 + MAX_SHADOW_TILES * (64 + 16 + 16)


def _shadow_sampling(tex: moderngl.Texture) -> None:
    tex.compare_func = "<="
    tex.filter = (moderngl.LINEAR, moderngl.LINEAR)
    tex.repeat_x = tex.repeat_y = False
