"""Both eyes in one geometry pass, or one pass per eye? (Not a test: a script.)

The G-buffer pass draws each eye into its own targets (render.passes.GBufferPass). Issue 15
asked for both eyes in one pass: every draw instanced twice, each instance sent to its eye by
``gl_Layer`` (a two-layer target, GL_ARB_shader_viewport_layer_array) or by a shift in clip
space into its half of a double-wide target (clipped at the middle by ``gl_ClipDistance``).
This draws a scene's triangles in ``--draws`` calls with a G-buffer-like fragment shader (three
targets, a texture fetched per fragment, no depth test: a layered depth target is not in
moderngl) the three ways and prints each one's median time (glFinish included).

Measured here (2 cores, llvmpipe), the living room's triangles, 35 draws, 2 x 269x302 (the
drawn size the governor settles on at 30 fps): 25k triangles (every 16th), per eye 4.7-5.0 ms,
layered 6.3-6.8, double-wide 6.4-6.6; 200k (every 2nd) 37.3-37.5, 43.8-44.6, 40.9-41.6; with 200
draws of the 25k 4.3-4.4, 4.9-5.7 (and so on): one pass is 10-40 % slower, because llvmpipe shades
each instance's vertices on the calling thread as it would a second draw and bins the wider
target no faster. The per-eye passes stay; on a GPU the single pass halves the draw calls and
should win, to be measured where one is lent.

    PYTHONPATH=. python tests/measure_stereo_pass.py SCENE [--every K] [--draws N]
        [--size WxH] [--repeats N]
"""

from __future__ import annotations

import argparse
import math
import statistics
import time

import moderngl
import numpy as np

from app import scenes
from app.loaders import LoadOptions
from app.settings import Settings

VERTEX = """
#version 430
%(extension)s
in vec3 in_position;
uniform mat4 u_vp[2];
uniform int u_eye;
out vec3 v_world;
%(outputs)s
void main() {
    int e = %(eye)s;
    v_world = in_position;
    vec4 p = u_vp[e] * vec4(in_position, 1.0);
%(place)s
    gl_Position = p;
}
"""
FRAGMENT = """
#version 430
in vec3 v_world;
uniform sampler2D u_tex;
layout(location = 0) out vec4 albedo;
layout(location = 1) out vec4 normal;
layout(location = 2) out vec4 sky;
void main() {
    vec3 n = normalize(cross(dFdx(v_world), dFdy(v_world)));
    albedo = texture(u_tex, v_world.xz);
    normal = vec4(n, 0.5);
    sky = vec4(1.0);
}
"""
WAYS = {
    "per eye": {"extension": "", "outputs": "", "eye": "u_eye", "place": ""},
    "layered": {
        "extension": "#extension GL_ARB_shader_viewport_layer_array : require",
        "outputs": "",
        "eye": "gl_InstanceID",
        "place": "    gl_Layer = gl_InstanceID;",
    },
    "double-wide": {
        "extension": "",
        "outputs": "out float gl_ClipDistance[1];",
        "eye": "gl_InstanceID",
        "place": "    float side = e == 0 ? -1.0 : 1.0;\n"
        "    gl_ClipDistance[0] = side * p.x + p.w;\n"
        "    p.x = 0.5 * p.x + 0.5 * side * p.w;",
    },
}
GL_CLIP_DISTANCE0 = 0x3000


def perspective(fov_y: float, aspect: float, near: float, far: float) -> np.ndarray:
    t = 1.0 / math.tan(fov_y / 2.0)
    m = np.zeros((4, 4))
    m[0, 0], m[1, 1] = t / aspect, t
    m[2, 2], m[2, 3], m[3, 2] = (far + near) / (near - far), 2.0 * far * near / (near - far), -1.0
    return m


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("scene")
    ap.add_argument("--every", type=int, default=16, help="keep every K-th triangle")
    ap.add_argument("--draws", type=int, default=35)
    ap.add_argument("--size", default="269x302", help="one eye's target")
    ap.add_argument("--repeats", type=int, default=30)
    args = ap.parse_args()
    w, h = (int(v) for v in args.size.split("x"))
    scene = scenes.resolve(args.scene, LoadOptions.from_settings(Settings().scene))
    tris = np.concatenate([m.positions[np.asarray(m.indices, np.int64)] for m in scene.meshes])
    tris = tris[:: max(1, args.every)].reshape(-1, 3).astype(np.float32)
    ctx = moderngl.create_context(standalone=True, backend="egl", require=430)
    vbo = ctx.buffer(tris.tobytes())
    rng = np.random.default_rng(0)
    tex = ctx.texture((64, 64), 4, rng.integers(0, 255, (64, 64, 4), np.uint8).tobytes())
    tex.build_mipmaps()
    centre = 0.5 * (tris.min(axis=0) + tris.max(axis=0))
    vps = []
    for dx in (-0.032, 0.032):
        view = np.eye(4)
        view[:3, 3] = -(centre + [dx, 0.0, 0.0])
        vps.append(perspective(math.radians(90.0), w / h, 0.05, 200.0) @ view)
    matrices = np.concatenate([m.T.astype(np.float32) for m in vps]).tobytes()

    def targets(size, layers=0):
        def make(components, dtype="f1"):
            if layers:
                return ctx.texture_array((*size, layers), components, dtype=dtype)
            return ctx.texture(size, components, dtype=dtype)

        return ctx.framebuffer([make(4), make(4, "f2"), make(1)])

    fbos = {
        "per eye": [targets((w, h)), targets((w, h))],
        "layered": [targets((w, h), layers=2)],
        "double-wide": [targets((2 * w, h))],
    }
    count = len(tris) // args.draws // 3 * 3
    ctx.disable(moderngl.DEPTH_TEST | moderngl.CULL_FACE)
    print(f"{len(tris) // 3:,} triangles in {args.draws} draws, 2 x {w}x{h}")
    for name, parts in WAYS.items():
        prog = ctx.program(vertex_shader=VERTEX % parts, fragment_shader=FRAGMENT)
        prog["u_vp"].write(matrices)
        vao = ctx.vertex_array(prog, [(vbo, "3f", "in_position")])
        if name == "double-wide":
            ctx.enable_direct(GL_CLIP_DISTANCE0)

        def frame(name=name, prog=prog, vao=vao) -> None:
            for eye, fbo in enumerate(fbos[name]):
                fbo.use()
                fbo.clear()
                if "u_eye" in prog:
                    prog["u_eye"].value = eye
                for k in range(args.draws):
                    tex.use(0)
                    instances = 1 if name == "per eye" else 2
                    vao.render(vertices=count, first=k * count, instances=instances)
            ctx.finish()

        frame()
        times = []
        for _ in range(args.repeats):
            start = time.perf_counter()
            frame()
            times.append(1000.0 * (time.perf_counter() - start))
        if name == "double-wide":
            ctx.disable_direct(GL_CLIP_DISTANCE0)
        print(f"{name:>12}: {statistics.median(times):6.2f} ms")


if __name__ == "__main__":
    main()
