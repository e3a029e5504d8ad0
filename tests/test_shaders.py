import pytest

from render import shaders
from render.context import GLUnavailableError, check
from render.shaders import ShaderError, ShaderLibrary, assemble


def fake_reader(files):
    def read(name):
        if name not in files:
            raise ShaderError(f"shader file not found: render/shaders/{name}")
        return files[name]

    return read


def test_includes_once_defines_after_version_and_line_map():
    files = {
        "top.glsl": '#version 430\n#include "a.glsl"\n#include "b.glsl"\nvoid main() {}\n',
        "a.glsl": '#include "b.glsl"\nfloat a;\n',
        "b.glsl": "float b;\n",
    }
    src = assemble("top.glsl", {"FOO": 3, "BAR": True, "OFF": False}, fake_reader(files))
    lines = src.text.splitlines()
    assert lines[0] == "#version 430"
    assert lines[1:3] == ["#define BAR", "#define FOO 3"]
    assert src.text.count("float b;") == 1  # included once although reached twice
    assert src.where(lines.index("float a;") + 1) == "a.glsl:2"
    assert src.where(lines.index("void main() {}") + 1) == "top.glsl:4"


@pytest.mark.parametrize(
    "files, message",
    [
        ({"top.glsl": "void main() {}\n"}, "top.glsl:1: the first line must be"),
        ({"top.glsl": "#version 330\nvoid main() {}\n"}, "older than 430"),
        ({"top.glsl": '#version 430\n#include "gone.glsl"\n'}, "top.glsl:2: cannot include"),
        (
            {"top.glsl": '#version 430\n#include "a.glsl"\n', "a.glsl": '#include "top.glsl"\n'},
            "cycle",
        ),
    ],
)
def test_loader_errors_name_file_and_line(files, message):
    with pytest.raises(ShaderError, match=message):
        assemble("top.glsl", None, fake_reader(files))


def test_compile_error_names_the_included_file_and_line(monkeypatch):
    from render.context import create_headless

    files = {
        "v.glsl": "#version 430\nvoid main() { gl_Position = vec4(0.0); }\n",
        "f.glsl": '#version 430\n#include "lib.glsl"\nout vec4 c;\n'
        "void main() { c = vec4(helper()); }\n",
        "lib.glsl": "// a helper\nfloat helper() { return missing_value; }\n",
    }
    monkeypatch.setattr(shaders, "read_file", fake_reader(files))
    ctx = create_headless()
    with ctx:
        lib = ShaderLibrary(ctx)
        with pytest.raises(ShaderError, match=r"lib\.glsl:2 \(column \d+\): error"):
            lib.program("v.glsl", "f.glsl")
    ctx.release()


def test_every_shipped_shader_compiles():
    from render.context import create_headless

    ctx = create_headless()
    with ctx:
        lib = ShaderLibrary(ctx)
        for frag in ("gbuffer.frag.glsl", "forward.frag.glsl"):
            for textured in (False, True):
                lib.program("geometry.vert.glsl", frag, {"HAS_TEXTURE": textured})
        for frag in ("lighting.frag.glsl", "present.frag.glsl", "overlay.frag.glsl"):
            lib.program("fullscreen.vert.glsl", frag)
        lib.compute("lighting.comp.glsl")
        lib.release()
    ctx.release()


def test_old_opengl_is_refused_with_what_is_missing():
    class OldContext:
        version_code = 330
        info = {"GL_RENDERER": "Ancient GPU", "GL_VERSION": "3.3"}

    with pytest.raises(GLUnavailableError, match=r"OpenGL 4\.3.*Ancient GPU offers only 3\.3"):
        check(OldContext())  # type: ignore[arg-type]


def test_a_renderer_wide_define_rebuilds_only_the_programs_that_name_it():
    from render.context import create_headless

    ctx = create_headless()
    with ctx:
        lib = ShaderLibrary(ctx)
        lib.variant["SHADOW_FILTER"] = 2
        gbuffer = lib.program("geometry.vert.glsl", "gbuffer.frag.glsl")
        lit = lib.program("fullscreen.vert.glsl", "lighting.frag.glsl")
        lib.variant["SHADOW_FILTER"] = 1  # the governor's hard shadows
        assert lib.program("geometry.vert.glsl", "gbuffer.frag.glsl") is gbuffer
        hard = lib.program("fullscreen.vert.glsl", "lighting.frag.glsl")
        assert hard is not lit  # the lighting samples the shadows: another program
        lib.variant["SHADOW_FILTER"] = 2
        assert lib.program("fullscreen.vert.glsl", "lighting.frag.glsl") is lit
        assert len(lib) == 3
        lib.release()
    ctx.release()
