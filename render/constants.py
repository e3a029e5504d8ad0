"""Constants shared by the Python side of the renderer and its shaders: one source.

``ShaderLibrary`` injects ``SHADER_DEFINES`` as ``#define NAME value`` after ``#version`` into
every program it compiles, so no GLSL file defines these itself (``tests/test_constants.py``
fails if one does). Python code imports the names from here.
"""

from __future__ import annotations

from app.cps import MAX_LEVEL

# Lights: the uniform block holds this many (std140: 32 KiB of the 64 KiB block limit).
MAX_LIGHTS = 1024
# Tiled light culling: tile edge in pixels, list length per tile, and the count that marks an
# overflowing tile ("evaluate every light").
LIGHT_TILE = 16
MAX_PER_TILE = 128
ALL_LIGHTS = 65535

# Coarse pixel shading: detail levels 0..MAX_LEVEL (app/cps.py) and the visualisation legend
# (paper Fig. 2): finest unpainted, then blue, cyan, green, yellow, red.
CPS_LEVELS = MAX_LEVEL + 1
CPS_LEVEL_COLOURS = (
    (1.0, 1.0, 1.0),
    (0.15, 0.35, 1.0),
    (0.0, 0.9, 0.9),
    (0.1, 0.85, 0.1),
    (1.0, 0.95, 0.0),
    (1.0, 0.1, 0.1),
)
# Level legend for the TCR tint (Python only, a uniform): level 0 unpainted, then blue, cyan,
# green, yellow, orange, red.
LEVEL_TINTS = (
    (1.0, 1.0, 1.0),
    (0.15, 0.35, 1.0),
    (0.0, 0.9, 0.9),
    (0.1, 0.85, 0.1),
    (1.0, 0.95, 0.0),
    (1.0, 0.55, 0.0),
    (1.0, 0.1, 0.1),
)

# Photon gather: record / start textures are 1 << PM_TEX_SHIFT texels wide; work groups of
# PM_GROUP invocations (Algorithm 1 relies on it); heaps of at most PM_MAX_K entries; the
# reuse winner's "no left pixel lands here".
PM_TEX_SHIFT = 12
PM_GROUP = 64
PM_MAX_K = 64
PM_NO_WINNER = 0xFFFFFFFF

# Image units, keyed by the image uniform's name without "u_": the shaders declare
# ``layout(binding = IMAGE_UNIT_<NAME>)``, Python binds with ``render.resources.bind_image``.
IMAGE_UNITS = {
    "out": 0,  # the compute passes' output image
    "counts": 1,  # light culling: per-tile counts
    "lists": 2,  # light culling: per-tile lists
    "reuse_winner": 1,  # photon gather: the right eye's winners (read only)
    "winner": 3,  # photon reuse scatter: the winners (read-write)
}

# Texture units, keyed by the sampler uniform's name without "u_"; every sampler bind goes
# through ``render.resources.bind_texture`` with this table. A program's samplers must not
# share a unit (tests/test_constants.py checks each shader's samplers against it).
TEXTURE_UNITS = {
    "albedo": 0,  # a mesh's albedo texture (geometry passes)
    "eye_color": 0,
    "text": 0,
    "heat": 0,
    "gb_albedo": 1,
    "left_depth": 1,
    "gb_normal": 2,
    "right_depth": 2,
    "gb_depth": 3,
    "depth": 3,
    "bounds": 3,
    "levels": 4,
    "atlas": 5,
    "blocks": 5,
    "lit": 5,
    "current": 5,
    "left_result": 5,
    "history": 6,
    "tile_counts": 6,
    "tile_lists": 7,
    "indirect": 8,
    "pm_records": 8,
    "pm_starts": 9,
}


def _glsl(value: object) -> str:
    if isinstance(value, tuple):
        return "vec3(" + ", ".join(repr(float(v)) for v in value) + ")"
    return str(value)


# What every shader sees (values as GLSL text).
SHADER_DEFINES: dict[str, object] = {
    "MAX_LIGHTS": MAX_LIGHTS,
    "LIGHT_TILE": LIGHT_TILE,
    "MAX_PER_TILE": MAX_PER_TILE,
    "ALL_LIGHTS": f"{ALL_LIGHTS}u",
    "CPS_LEVELS": CPS_LEVELS,
    "CPS_MAX_LEVEL": MAX_LEVEL,
    "CPS_LEVEL_COLOURS": ", ".join(_glsl(c) for c in CPS_LEVEL_COLOURS),
    "PM_TEX_SHIFT": PM_TEX_SHIFT,
    "PM_GROUP": f"{PM_GROUP}u",
    "PM_MAX_K": PM_MAX_K,
    "PM_NO_WINNER": f"0x{PM_NO_WINNER:X}u",
    **{f"IMAGE_UNIT_{k.upper()}": v for k, v in IMAGE_UNITS.items()},
}
