"""The pass contract: what a render pass declares, the frame's resource table, and the checks.

A pass (``RenderPass``) names the resources it ``reads`` and ``writes`` (per eye unless noted,
see ``RESOURCES``) and owns its on/off rule, ``configure(settings, scene, frame) -> bool``.
``optional_reads`` are used when an earlier pass of this configuration writes them (the tile
light lists, the photons' indirect light, the level map for the visualisation), otherwise the
pass runs its variant without them. The renderer asks every pass of its list, checks the
enabled ones once per configuration (``check_graph``: every read has an earlier writer, or a
``PassGraphError`` names the pass and the resource), and runs them with the frame's inputs
(``FrameContext``) and the ``Resources`` table.

Textures are bound by sampler name with the one unit table (``render.constants.TEXTURE_UNITS``,
``bind_texture``), images likewise (``IMAGE_UNITS``, ``bind_image``); ``set_uniforms`` writes
uniforms a shader must have (a missing one is an error) and, separately, ones a variant may
drop (the GLSL compiler removes uniforms a variant does not read).
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from typing import Any, Generic, TypeVar, cast

import moderngl
import numpy as np

from app.camera import EyeView
from render.constants import IMAGE_UNITS, TEXTURE_UNITS
from render.gpu_scene import GpuScene
from render.shaders import ShaderLibrary

# The named resources passes hand each other (the contract's vocabulary).
RESOURCES = {
    "shadow_maps": "the shadow maps' atlas and their uniform block (bound for every lighting)",
    "shadow_mask": "per eye: up to 8 lights' shadow factors at every 2nd or 4th pixel",
    "depth": "per eye: G-buffer / forward depth",
    "normal": "per eye: world normal + roughness",
    "albedo": "per eye: albedo + metallic",
    "tile_lists": "per eye: per-tile light counts and lists (light culling)",
    "levels": "per eye: CPS detail level map (half resolution)",
    "blocks": "per eye: CPS lighting per block (atlas or full-size blocks image)",
    "filtered": "per eye: CPS reconstruction before the temporal filter",
    "history": "per eye: the temporal filter's previous frame",
    "indirect": "per eye: photon irradiance (rgba32f)",
    "photon_map": "the photon map and gather defines the lighting gathers itself (fused)",
    "show_reuse": "flag: paint the right eye's reused / gathered indirect pixels",
    "ao": "per eye: ambient occlusion of the ambient term (full resolution)",
    "sky": "the baked sky and the sun for this frame (daylight on)",
    "hdr": "per eye: linear HDR colour",
    "out": "the host's framebuffer: both eyes tone-mapped side by side",
}


class PassGraphError(RuntimeError):
    """A pass list whose reads are not all written by an earlier pass (or unknown names)."""


class UniformError(KeyError):
    """A uniform the shader must have is not in the program."""


@dataclass
class FrameContext:
    """The frame's inputs, the same for every pass (what passes make goes to ``Resources``)."""

    eyes: list[EyeView]
    scene: GpuScene
    light_scale: float
    ambient: float  # u_ambient: the even light's level (see ambient_gradient)
    exposure: float
    out: moderngl.Framebuffer
    out_origin: tuple[int, int]  # lower-left of the stereo view inside ``out``
    gaze: tuple[float, float]
    gaze_fixed: bool
    levels: list[int] | None = None  # TCR level per mesh (None: full quality)
    tcr_mode: str = "clamp"
    tint: bool = False
    cps: Any = None  # render.cps.CpsFrame: caps, frame index, edge-ray hits
    edge_hits: Sequence | None = None  # world points per eye, drawn with the level map
    split: Any = None  # render.ab_split.SplitFrame: the presenter's A/B split (None: none)
    # One eye's size in ``out`` (the eyes are drawn at render.scale of it; None: the targets').
    view_size: tuple[int, int] | None = None
    # Progressive refinement (app.refine, render.refine): this frame is sample
    # ``refine_sample`` of ``refine_target`` of the running mean.
    refining: bool = False
    refine_sample: int = 0
    refine_target: int = 0
    # render.normal_maps: the material variants sample their normal maps (off: flat normals)
    normal_maps: bool = True
    # A small frame no one sees, drawn to compile the programs of knobs the governor may
    # turn to (Renderer.warm_variants): the shadow maps stay as they are, nothing is metered.
    warming: bool = False
    # The even light of a surface of normal n: max(ambient + ambient_gradient . n, 0)
    # (app.ambient.AmbientEstimate.base_and_gradient; zero with the fixed ambient)
    ambient_gradient: tuple[float, float, float] = (0.0, 0.0, 0.0)
    # What the surfaces that hide part of a crease's hemisphere send back against the even
    # light they hide (app.ambient.AmbientEstimate.occluder_return); negative: unknown.
    occluder_return: float = -1.0
    # The even light by place (render.ambient_field.GpuAmbientField; None: the level alone).
    ambient_field: Any = None


# Resource name -> where the renderer's targets keep it: (table, attribute).
_TARGET_ATTRS = {
    "depth": ("targets", "depth"),
    "normal": ("targets", "normal"),
    "albedo": ("targets", "albedo"),
    "hdr": ("targets", "color"),
    "tile_lists": ("targets", "tile_lists"),
    "levels": ("cps", "levels"),
    "filtered": ("cps", "filtered"),
}


class Resources:
    """The frame's resource table: each eye's targets (``EyeTargets``, CPS targets) by name,
    plus what passes ``put`` this frame. ``get`` answers only for names an earlier pass of
    this frame writes (so a pass sees the tile lists only when culling ran)."""

    def __init__(self, cps_state: Any) -> None:
        self.cps_state = cps_state  # render.cps.CpsState: the CPS targets and their state
        self.targets: list = []  # render.passes.EyeTargets per eye
        self._written: set[str] = set()
        self._values: dict[str, Any] = {}

    @property
    def cps(self) -> list:
        return self.cps_state.eyes

    def begin_frame(self, targets: list) -> None:
        self.targets = targets
        self._written.clear()
        self._values.clear()

    def wrote(self, names: Iterable[str]) -> None:
        self._written.update(names)

    def put(self, name: str, value: Any) -> None:
        """A value a pass made this frame (``name`` must be among its writes)."""
        self._values[name] = value

    def written(self, name: str) -> bool:
        return name in self._written

    def get(self, name: str, default: Any = None) -> Any:
        """Per-eye list (or value) of ``name`` if an earlier pass wrote it this frame."""
        if name not in self._written:
            return default
        if name in self._values:
            return self._values[name]
        where = _TARGET_ATTRS.get(name)
        if where is None:
            return default
        table, attr = where
        return [getattr(t, attr) for t in getattr(self, table)]

    def eye(self, name: str, index: int) -> Any:
        """One eye's texture of ``name``, whether or not written this frame (a pass's own)."""
        table, attr = _TARGET_ATTRS[name]
        return getattr(getattr(self, table)[index], attr)


def has(prog: moderngl.Program | moderngl.ComputeShader, name: str) -> bool:
    """Whether ``prog`` has a member ``name``: one dictionary lookup (moderngl's Program has
    no ``__contains__``, so ``name in prog`` walks every member, about 4,600 steps a frame)."""
    return prog.get(name, None) is not None


def uniform(prog: moderngl.Program | moderngl.ComputeShader, name: str) -> moderngl.Uniform:
    """The uniform ``name`` of ``prog`` (a KeyError when the program has none). moderngl types
    ``prog[name]`` as any member (uniform, block, attribute, varying); the names passed here
    are plain uniforms, so this only narrows the type (no check at run time)."""
    return cast(moderngl.Uniform, prog[name])


def bind_texture(
    prog: moderngl.Program | moderngl.ComputeShader,
    name: str,
    tex: moderngl.Texture | moderngl.Texture3D,
    optional: bool = False,
) -> bool:
    """Bind ``tex`` to TEXTURE_UNITS[name] and point sampler ``u_<name>`` at it. ``optional``:
    the variant may not have the sampler (then nothing is bound and False is returned)."""
    sampler = "u_" + name
    if not has(prog, sampler):
        if optional:
            return False
        raise UniformError(f"shader has no sampler {sampler}")
    unit = TEXTURE_UNITS[name]
    tex.use(unit)
    uniform(prog, sampler).value = unit
    return True


def bind_image(tex: moderngl.Texture, name: str, read: bool = False, write: bool = True) -> None:
    """Bind ``tex`` to image unit IMAGE_UNITS[name] (the shader's IMAGE_UNIT_<NAME>)."""
    tex.bind_to_image(IMAGE_UNITS[name], read=read, write=write)


def set_uniforms(
    prog: moderngl.Program | moderngl.ComputeShader,
    values: dict[str, Any],
    optional: dict[str, Any] | None = None,
) -> None:
    """Write ``values`` (each must be in the shader) and ``optional`` (skipped where this
    variant does not have it). bytes and 4x4 matrices are written, the rest set as values."""
    for group, required in ((values, True), (optional or {}, False)):
        for name, value in group.items():
            if not has(prog, name):
                if required:
                    raise UniformError(f"shader has no uniform {name}")
                continue
            member = uniform(prog, name)
            if isinstance(value, np.ndarray) and value.shape == (4, 4):
                member.write(np.ascontiguousarray(value.T, dtype=np.float32).tobytes())
            elif isinstance(value, bytes):
                member.write(value)
            else:
                member.value = value


class RenderPass(ABC):
    """One pass: its contract (``name``, ``reads``, ``optional_reads``, ``writes``), its on/off
    rule (``configure``) and its work (``execute``), timed on the GPU (``last_ms``)."""

    name = "pass"
    reads: tuple[str, ...] = ()
    optional_reads: tuple[str, ...] = ()
    writes: tuple[str, ...] = ()
    # Only adds light to "hdr" (blended ONE, ONE) and reads nothing else of it: a pass after
    # the CPS filter that the present pass may fold the filter past (Renderer.fold_cps_filter).
    adds_to_hdr = False

    def __init__(self, ctx: moderngl.Context, shaders: ShaderLibrary, res: Resources) -> None:
        self.ctx = ctx
        self.shaders = shaders
        self.res = res
        self.enabled = True  # the renderer sets it from configure()
        self._query = ctx.query(time=True)
        self.last_ms = 0.0
        self._timed = False  # run() timed this frame's work, collect() not yet read it
        self.samples = 0  # shaded samples in the last frame, where the pass knows them
        self._fullscreen_vaos: dict[int, moderngl.VertexArray] = {}

    def configure(self, settings: Any, scene: GpuScene, frame: FrameContext) -> bool:
        """Whether this pass runs this frame (and its variant); the pass's own rule."""
        return True

    def adds_light(self, scene: GpuScene) -> bool:
        """A pass that adds to "hdr" (``adds_to_hdr``): whether it adds anything this frame
        (the colour under it must then be cleared when the CPS filter folds past it)."""
        return True

    def run(self, frame: FrameContext) -> None:
        if not self.enabled:
            self.last_ms = 0.0
            self._timed = False
            return
        with self._query:
            self.execute(frame, self.res)
        self._timed = True  # its time is read by collect(), once the whole frame is submitted

    def collect(self) -> None:
        """This frame's GPU time of the pass (``last_ms``). Read after every pass of the frame
        is submitted: reading a timer waits for its pass to finish, so reading each one as it
        ends made the CPU wait for every pass before it could submit the next."""
        if self._timed:
            self._timed = False
            self.last_ms = self._query.elapsed / 1e6

    @abstractmethod
    def execute(self, frame: FrameContext, res: Resources) -> None:
        """The pass's work for one frame (each pass defines it)."""

    def fullscreen(self, prog: moderngl.Program) -> None:
        """Draw one viewport-covering triangle with ``prog`` (no vertex buffer)."""
        vao = self._fullscreen_vaos.get(prog.glo)
        if vao is None:
            vao = self._fullscreen_vaos[prog.glo] = self.ctx.vertex_array(prog, [])
        vao.render(moderngl.TRIANGLES, vertices=3)

    def release(self) -> None:
        release_query(self._query)
        for vao in self._fullscreen_vaos.values():
            vao.release()
        self._fullscreen_vaos.clear()


def check_graph(passes: Sequence[RenderPass]) -> None:
    """Every read of every pass has an earlier writer in ``passes`` (and every name is known);
    else a PassGraphError naming the pass and the resource."""
    written: set[str] = set()
    for p in passes:
        for name in (*p.reads, *p.optional_reads, *p.writes):
            if name not in RESOURCES:
                raise PassGraphError(f"pass '{p.name}' names unknown resource '{name}'")
        for name in p.reads:
            if name not in written:
                raise PassGraphError(
                    f"pass '{p.name}' reads '{name}' but no earlier pass writes it"
                )
        written.update(p.writes)


T = TypeVar("T")

#: Sizes a frame's targets are kept for: the view's, the render scale the governor left last
#: (it steps back and forth) and the small unseen frames that compile its programs
#: (``Renderer.warm_variants``), which take turns with the view's while the window warms up.
KEEP_SIZES = 3


class BySize(Generic[T]):
    """Targets made for a size (``make(size)``), kept for the last ``keep`` sizes used, so
    that frames of sizes taking turns do not remake every target each time (a frame that
    remakes them costs tens of ms on llvmpipe). ``release(item)`` frees what is dropped."""

    def __init__(
        self,
        make: Callable[[tuple[int, int]], T],
        release: Callable[[T], None],
        keep: int = KEEP_SIZES,
    ) -> None:
        self._make = make
        self._release = release
        self.keep = max(1, int(keep))
        self._items: dict[tuple[int, int], T] = {}  # the most recently used last

    def get(self, size: Sequence[int]) -> T:
        key = (int(size[0]), int(size[1]))
        item = self._items.pop(key, None)
        if item is None:
            while len(self._items) >= self.keep:  # the least recently used goes first
                self._release(self._items.pop(next(iter(self._items))))
            item = self._make(key)
        self._items[key] = item
        return item

    def drop(self, size: Sequence[int]) -> None:
        """Release what is held for ``size`` (it is made anew on the next ``get``)."""
        item = self._items.pop((int(size[0]), int(size[1])), None)
        if item is not None:
            self._release(item)

    def sizes(self) -> list[tuple[int, int]]:
        """The sizes held, the most recently used last."""
        return list(self._items)

    def clear(self) -> None:
        items, self._items = list(self._items.values()), {}
        for item in items:
            self._release(item)


def release_all(items: Iterable[Any]) -> None:
    """``release()`` each of ``items`` (a pair of per-eye targets)."""
    for item in items:
        item.release()


def release_query(query: moderngl.Query) -> None:
    # moderngl 5.x exposes no Query.release(); its glo is freed with the context.
    release = getattr(query, "release", None) or getattr(query.mglo, "release", None)
    if release is not None:
        release()
