"""RCAS sharpening after EASU (render.sharpen): the upscale shader on small synthetic eyes."""

import moderngl
import numpy as np
import pytest

from render.context import create_headless
from render.shaders import ShaderLibrary
from render.upscale import rcas_con, sharpen_stops, upscale_defines

SRC = (32, 24)
DST = (64, 48)


@pytest.fixture(scope="module")
def gl():
    ctx = create_headless()
    with ctx:
        yield ctx, ShaderLibrary(ctx)
    ctx.release()


def _draw(ctx, prog, src: moderngl.Texture, size: tuple[int, int]) -> moderngl.Texture:
    out = ctx.texture(size, 4)
    fbo = ctx.framebuffer([out])
    fbo.use()
    fbo.viewport = (0, 0, *size)
    src.use(0)
    prog["u_eye_color"].value = 0
    vao = ctx.vertex_array(prog, [])
    vao.render(moderngl.TRIANGLES, vertices=3)
    vao.release()
    fbo.release()
    out.filter = (moderngl.NEAREST, moderngl.NEAREST)
    return out


def enlarge(gl, img: np.ndarray, sharpen: float, placement: str = "pass") -> np.ndarray:
    """``img`` (rows x columns x 3, 0-255, row 0 at the bottom) enlarged to DST as the present
    pass does: RCAS in its own pass at the drawn size, or folded into EASU's taps."""
    ctx, lib = gl
    defines = upscale_defines(SRC, DST, "easu", sharpen)
    rgba = np.concatenate([img, np.full(img.shape[:2] + (1,), 255)], axis=2).astype(np.uint8)
    src = ctx.texture(SRC, 4, rgba.tobytes())
    src.filter = (moderngl.NEAREST, moderngl.NEAREST)
    con = rcas_con(sharpen_stops(sharpen) or 0.0)
    if defines.get("RCAS") and placement == "pass":
        rcas = lib.program("fullscreen.vert.glsl", "rcas.frag.glsl")
        rcas["u_src_size"].value = SRC
        rcas["u_rcas_con"].value = con
        sharp = _draw(ctx, rcas, src, SRC)
        src.release()
        src, defines = sharp, {**defines, "RCAS": False}
    prog = lib.program("fullscreen.vert.glsl", "upscale.frag.glsl", defines)
    prog["u_src_size"].value = SRC
    prog["u_dst_size"].value = DST
    prog["u_origin"].value = (0, 0)
    if defines.get("RCAS"):
        prog["u_rcas_con"].value = con
    out = _draw(ctx, prog, src, DST)
    pixels = np.frombuffer(out.read(), np.uint8).reshape(DST[1], DST[0], 4)[..., :3]
    out.release()
    src.release()
    return pixels.astype(np.float32)


def soft_step() -> np.ndarray:
    """A vertical edge from 60 to 190 blurred over four drawn pixels (a binomial kernel, as a
    scaled render's soft edge)."""
    row = 60.0 + 130.0 * np.interp(
        np.arange(SRC[0]), np.arange(12, 18), np.cumsum([0, 1, 4, 6, 4, 1]) / 16
    )
    return np.repeat(np.repeat(row[None, :, None], SRC[1], axis=0), 3, axis=2)


def edge_slope(img: np.ndarray) -> float:
    """The steepest rise across the edge, in levels per output pixel (green, middle rows)."""
    g = img[10:-10, :, 1]
    return float(np.diff(g, axis=1).max(axis=1).mean())


@pytest.mark.parametrize("placement", ["pass", "folded"])
def test_sharpening_steepens_an_enlarged_edge_without_ringing(gl, placement):
    src = soft_step()
    plain = enlarge(gl, src, 0.0)
    sharp = enlarge(gl, src, 0.9, placement)  # FSR's default, 0.2 stops
    strongest = enlarge(gl, src, 1.0, placement)
    assert edge_slope(sharp) > 1.08 * edge_slope(plain)  # measured 37 against 33 levels/px
    assert edge_slope(strongest) >= edge_slope(sharp)
    # no overshoot beyond the neighbourhood: nothing darker or brighter than the two sides
    for img in (sharp, strongest):
        assert img.min() >= 60.0 - 1.0 and img.max() <= 190.0 + 1.0
        # the plateaus away from the edge stay where they were
        assert np.abs(img[:, :20] - 60.0).max() <= 1.0
        assert np.abs(img[:, -20:] - 190.0).max() <= 1.0


def test_sharpening_off_is_exactly_the_plain_edge_preserving_picture(gl):
    rng = np.random.default_rng(15)
    src = rng.integers(0, 256, (SRC[1], SRC[0], 3)).astype(np.float32)
    assert upscale_defines(SRC, DST, "easu", 0.0)["RCAS"] is False
    off = enlarge(gl, src, 0.0)
    assert np.array_equal(off, enlarge(gl, src, -0.5))  # below 0 is off too
    assert not np.array_equal(off, enlarge(gl, src, 0.9))  # while on changes the picture
    # both placements sharpen alike: within a level or two of each other
    diff = np.abs(enlarge(gl, src, 0.9) - enlarge(gl, src, 0.9, "folded"))
    assert diff.mean() < 2.0


@pytest.mark.parametrize("placement", ["pass", "folded"])
def test_a_flat_picture_stays_flat(gl, placement):
    for level in (0.0, 37.0, 200.0, 255.0):
        flat = np.full((SRC[1], SRC[0], 3), level, np.float32)
        sharp = enlarge(gl, flat, 1.0, placement)
        assert np.array_equal(sharp, np.full((DST[1], DST[0], 3), level))


def test_sharpness_maps_to_fsr_stops():
    assert sharpen_stops(0.0) is None
    assert sharpen_stops(0.9) == pytest.approx(0.2)  # FSR's default
    assert sharpen_stops(1.0) == 0.0 and rcas_con(0.0) == 1.0
    assert rcas_con(2.0) == 0.25
    assert "RCAS" not in upscale_defines(SRC, SRC, "easu", 0.9)  # nothing enlarged: no pass
    assert upscale_defines(SRC, DST, "bilinear", 0.9) == {"UPSCALE_BILINEAR": True}


def test_the_present_pass_sharpens_a_scaled_frame_without_changing_it(edge_host):
    from tests.test_governor import draw, edge_width

    edge_host.settings.set("render.sharpen", 0.0)
    easu = draw(edge_host, 0.5)
    present = edge_host.renderer.pass_named("present")
    edge_host.settings.set("render.sharpen", 1.0)
    widths = {}
    try:
        for placement in ("pass", "folded", "after"):
            present.rcas_placement = placement
            sharp = draw(edge_host, 0.5)
            widths[placement] = edge_width(sharp)
            assert np.abs(sharp - easu).mean() < 2.0  # the same picture, a little crisper
        edge_host.settings.set("render.sharpen", 0.9)
        present.rcas_placement = "pass"
        full = draw(edge_host, 1.0)  # at full resolution nothing is enlarged or sharpened
        edge_host.settings.set("render.sharpen", 0.0)
        assert np.array_equal(full, draw(edge_host, 1.0))
    finally:
        edge_host.settings.set("render.sharpen", 0.9)
        present.rcas_placement = "pass"
    # After EASU (FSR's placement) the enlarged hard edges get crisper (measured 0.120 against
    # 0.142 px); before EASU a drawn edge one pixel wide has nothing to sharpen (RCAS clamps
    # to its cross), so it stays as EASU draws it, soft detail alone gaining (the tests above).
    assert widths["after"] < 0.9 * edge_width(easu), widths
    assert max(widths["pass"], widths["folded"]) < 1.02 * edge_width(easu), widths
