"""The pass contract: each pass's own on/off rule, the read/write check, adding a pass."""

from __future__ import annotations

import numpy as np
import pytest

from app.camera import StereoCamera
from app.frame import FrameInput
from app.photon_map import PhotonMap
from app.scene import Material, Mesh, PointLight, Scene, Viewpoint
from app.settings import Settings
from render.offscreen import OffscreenHost
from render.pass_graph import RESOURCES, PassGraphError, RenderPass, check_graph
from render.passes import LightingPass
from render.present import OverlayPass, PresentPass
from render.renderer import PASS_TYPES, Renderer

W, H = 128, 64


def room(lights: int = 1) -> Scene:
    pos = np.array([[-1, 0.6, -2], [1, 0.6, -2], [1, 2.6, -2], [-1, 2.6, -2]], np.float32)
    mesh = Mesh(
        "wall",
        pos,
        np.tile([0, 0, 1], (4, 1)).astype(np.float32),
        np.zeros((4, 2), np.float32),
        np.array([[0, 1, 2], [0, 2, 3]], np.uint32),
        0,
    )
    ls = [PointLight((0.1 * i, 1.6, 0), (1, 1, 1), 5.0, 5.0) for i in range(lights)]
    scene = Scene("room", [mesh], [Material("m", (1, 1, 1, 1))], [], ls, Viewpoint((0, 1.6, 0)))
    return scene.sanitized()


def frame(host: OffscreenHost) -> FrameInput:
    cam = StereoCamera(host.settings.stereo)
    cam.set_pose((0, 1.6, 0), 0.0, 0.0)
    return FrameInput(cam.eyes(*host.eye_size), gaze=(0.5, 0.5))


@pytest.fixture(scope="module")
def host():
    h = OffscreenHost(W, H, Settings())
    yield h
    assert not h.renderer.errors
    h.close()


BASE = ["present", "overlay"]
# render.reflections (on by default) after the opaque picture, the deferred paths only.
DEFERRED = ["gbuffer", "lighting", "emissive", "reflections", *BASE]
CPS = ["gbuffer", "cps_levels", "cps_lighting", "cps_filter", "emissive", "reflections", *BASE]

# What the renderer enabled before the contract (Renderer.render / _configure_cps), per case:
# settings, lights in the scene, a photon map or not -> the passes in order.
CASES = [
    ({}, 1, False, DEFERRED),
    ({"render.path": "forward"}, 1, False, ["forward", *BASE]),
    ({"render.path": "forward", "cps.mode": "cps"}, 1, False, ["forward", *BASE]),
    ({"render.path": "forward"}, 1, True, ["forward", *BASE]),
    ({"render.lighting": "fragment"}, 1, False, DEFERRED),
    ({}, 20, False, ["gbuffer", "light_cull", *DEFERRED[1:]]),
    ({"render.light_culling": False}, 20, False, DEFERRED),
    ({}, 1, True, ["gbuffer", "photons", *DEFERRED[1:]]),
    ({"cps.mode": "cps", "cps.temporal": False}, 1, False, CPS),
    (
        {"cps.mode": "cps", "cps.temporal": True},
        1,
        False,
        [*CPS[:4], "cps_temporal", *CPS[4:]],
    ),
    (
        {"cps.mode": "cps", "cps.temporal": False},
        20,
        True,
        ["gbuffer", "light_cull", "cps_levels", "photons", *CPS[2:]],
    ),
    ({"cps.mode": "black-mask"}, 1, False, ["gbuffer", "lighting", "cps_mask", *DEFERRED[2:]]),
    ({"cps.mode": "blur-mask"}, 1, False, ["gbuffer", "lighting", "cps_mask", *DEFERRED[2:]]),
    (
        {"cps.mode": "black-mask", "cps.visualize": True},
        1,
        False,
        ["gbuffer", "cps_levels", "lighting", "cps_mask", *DEFERRED[2:]],
    ),
    ({"cps.visualize": True}, 1, False, ["gbuffer", "cps_levels", *DEFERRED[1:]]),
    # The screen-space shadow mask (render/shadow_mask.py), between the G-buffer and lighting.
    ({"render.shadow_detail": "half"}, 1, False, ["gbuffer", "shadow_mask", *DEFERRED[1:]]),
    (
        {"render.shadow_detail": "quarter", "cps.mode": "cps", "cps.temporal": False},
        1,
        False,
        ["gbuffer", "cps_levels", "shadow_mask", *CPS[2:]],
    ),
    ({"render.shadow_detail": "half", "render.shadows": "off"}, 1, False, DEFERRED),
    ({"render.shadow_detail": "half", "render.path": "forward"}, 1, False, ["forward", *BASE]),
]


@pytest.mark.parametrize("values, lights, photons, expected", CASES)
def test_each_pass_decides_and_the_list_is_what_the_old_renderer_ran(
    host, values, lights, photons, expected
):
    s = host.settings
    defaults = Settings()
    for key in (
        "render.path",
        "render.lighting",
        "render.light_culling",
        "cps.mode",
        "cps.temporal",
        "cps.visualize",
        "render.shadows",
    ):
        s.set(key, defaults.get(key))
    s.set("render.shadow_detail", "full")  # the cases before the mask; its own at the end
    s.set("render.ao", "off")  # the passes before ambient occlusion; its own: tests/test_ao.py
    for key, value in values.items():
        s.set(key, value)
    with host.ctx:
        r = host.renderer
        r.set_scene(room(lights))
        r.set_photons(PhotonMap.empty() if photons else None)
        fi = frame(host)
        r._ensure_targets(fi.eyes[0].width, fi.eyes[0].height)
        r.cps.ensure(r.targets)
        enabled = r.configure(r.frame_context(fi, host.fbo))
        assert [p.name for p in enabled] == ["shadows", *expected]  # shadows: before all
        host.fbo.use()
        r.render(fi, host.fbo)  # and the frame runs with it
        assert set(r.pass_ms()) == {"shadows", *expected}
        r.set_photons(None)
    host.set_scene(None)


class _Fake:
    def __init__(self, name, reads=(), writes=(), optional_reads=()):
        self.name, self.reads, self.writes = name, reads, writes
        self.optional_reads = optional_reads


def test_a_read_without_an_earlier_writer_names_the_pass_and_the_resource():
    check_graph([_Fake("gbuffer", writes=("depth",)), _Fake("cull", reads=("depth",))])
    with pytest.raises(PassGraphError, match="pass 'lighting' reads 'albedo' but no earlier"):
        check_graph([_Fake("gbuffer", writes=("depth",)), _Fake("lighting", reads=("albedo",))])
    with pytest.raises(PassGraphError, match="pass 'late' reads 'depth'"):
        check_graph([_Fake("late", reads=("depth",)), _Fake("gbuffer", writes=("depth",))])
    with pytest.raises(PassGraphError, match="pass 'odd' names unknown resource 'colour'"):
        check_graph([_Fake("odd", writes=("colour",))])
    # Optional reads need no writer: the pass runs its variant without them.
    check_graph([_Fake("present", reads=(), optional_reads=("levels",))])


def test_every_pass_names_known_resources_and_the_renderer_checks_its_list():
    for t in PASS_TYPES:
        for name in (*t.reads, *t.optional_reads, *t.writes):
            assert name in RESOURCES, (t.__name__, name)
    h = OffscreenHost(W, H, Settings())
    try:
        with h.ctx:
            r = Renderer(h.ctx, h.settings, (LightingPass, PresentPass, OverlayPass))
            try:
                r.set_scene(room())
                with pytest.raises(PassGraphError, match="pass 'lighting' reads 'depth'"):
                    r.render(frame(h), h.fbo)
            finally:
                r.release()
    finally:
        h.close()


class MarkerPass(RenderPass):
    """A pass added for the test: reads the HDR colour, writes it back (adds nothing)."""

    name = "marker"
    reads = ("hdr",)
    writes = ("hdr",)
    runs = 0

    def configure(self, settings, scene, frame) -> bool:
        return settings.render.path == "deferred"

    def execute(self, frame, res) -> None:
        assert res.get("hdr") is not None and len(res.get("hdr")) == len(frame.eyes)
        MarkerPass.runs += 1


def test_adding_a_pass_is_a_class_and_a_line():
    types = list(PASS_TYPES)
    types.insert(types.index(OverlayPass), MarkerPass)
    h = OffscreenHost(W, H, Settings())
    try:
        with h.ctx:
            r = Renderer(h.ctx, h.settings, tuple(types))
            try:
                r.set_scene(room())
                r.render(frame(h), h.fbo)
                assert MarkerPass.runs == 1 and "marker" in r.pass_ms()
                assert not r.errors
            finally:
                r.release()
    finally:
        h.close()
