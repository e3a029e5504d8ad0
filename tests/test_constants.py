"""One source for the constants the Python side and the shaders share (render/constants.py)."""

from __future__ import annotations

import re
from importlib import resources

from app import scene as scene_model
from app.cps import MAX_LEVEL
from render import constants, passes, photon_gather
from render.constants import IMAGE_UNITS, SHADER_DEFINES, TEXTURE_UNITS
from render.shaders import ShaderError, assemble, with_constants


def shader_files() -> dict[str, str]:
    folder = resources.files("render").joinpath("shaders")
    files = [f for f in folder.iterdir() if f.name.endswith(".glsl")]
    return {f.name: f.read_text(encoding="utf-8") for f in files}


def code(text: str) -> str:
    """GLSL without comments."""
    text = re.sub(r"/\*.*?\*/", "", text, flags=re.S)
    return re.sub(r"//[^\n]*", "", text)


def test_no_shader_defines_an_injected_constant_itself():
    names = "|".join(map(re.escape, SHADER_DEFINES))
    define = re.compile(rf"^\s*#\s*define\s+({names})\b", re.M)
    const = re.compile(rf"\bconst\s+\w+\s+({names})\b")
    offenders = []
    for name, text in shader_files().items():
        body = code(text)
        offenders += [f"{name}: #define {m}" for m in define.findall(body)]
        offenders += [f"{name}: const {m}" for m in const.findall(body)]
    assert not offenders, offenders


def test_the_loader_injects_the_constants_and_refuses_to_override_them():
    src = assemble("light_cull.comp.glsl", with_constants({})).text
    assert "#define LIGHT_TILE 16" in src and "#define ALL_LIGHTS 65535u" in src
    try:
        with_constants({"LIGHT_TILE": 8})
    except ShaderError as exc:
        assert "LIGHT_TILE" in str(exc)
    else:
        raise AssertionError("a program may not redefine a shared constant")


def test_python_names_are_the_shared_ones():
    assert passes.LIGHT_TILE == constants.LIGHT_TILE == SHADER_DEFINES["LIGHT_TILE"]
    assert passes.MAX_PER_TILE == constants.MAX_PER_TILE
    assert passes.ALL_LIGHTS == constants.ALL_LIGHTS
    assert passes.CPS_LEVEL_COLOURS is constants.CPS_LEVEL_COLOURS
    assert passes.LEVEL_TINTS is constants.LEVEL_TINTS
    assert photon_gather.TEX_WIDTH == 1 << constants.PM_TEX_SHIFT
    assert photon_gather.NO_WINNER == constants.PM_NO_WINNER
    assert photon_gather.MAX_K == constants.PM_MAX_K and photon_gather.GROUP == constants.PM_GROUP
    assert constants.CPS_LEVELS == MAX_LEVEL + 1 == len(constants.CPS_LEVEL_COLOURS)
    assert SHADER_DEFINES["CPS_LEVEL_COLOURS"].count("vec3(") == constants.CPS_LEVELS
    assert constants.LIGHT_MIN_DIST2 == scene_model.LIGHT_MIN_DIST2 == 0.01
    assert float(str(SHADER_DEFINES["LIGHT_MIN_DIST2"])) == constants.LIGHT_MIN_DIST2


def test_every_sampler_and_image_has_a_unit_from_the_table():
    sampler = re.compile(r"\buniform\s+[iu]?sampler\w*\s+u_(\w+)")
    image = re.compile(r"layout\(([^)]*)\)\s*(?:\w+\s+)*uniform\s+[iu]?image\w*\s+u_(\w+)")
    for name, text in shader_files().items():
        body = code(text)
        for s in sampler.findall(body):
            assert s in TEXTURE_UNITS, f"{name}: sampler u_{s} has no unit in TEXTURE_UNITS"
        for layout, img in image.findall(body):
            assert img in IMAGE_UNITS, f"{name}: image u_{img} has no unit in IMAGE_UNITS"
            assert f"binding = IMAGE_UNIT_{img.upper()}" in layout, f"{name}: u_{img}"


def test_units_are_one_per_name():
    assert len(set(TEXTURE_UNITS.values())) == len(TEXTURE_UNITS)
    assert len(set(IMAGE_UNITS.values())) == len(IMAGE_UNITS)
    assert max(TEXTURE_UNITS.values()) < 80  # GL 4.3's least GL_MAX_COMBINED_TEXTURE_IMAGE_UNITS
    assert max(IMAGE_UNITS.values()) < 8  # and GL_MAX_IMAGE_UNITS
