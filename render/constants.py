"""Constants shared by the Python side of the renderer and its shaders: one source.

``ShaderLibrary`` injects ``SHADER_DEFINES`` as ``#define NAME value`` after ``#version`` into
every program it compiles, so no GLSL file defines these itself (``tests/test_constants.py``
fails if one does). Python code imports the names from here.
"""

from __future__ import annotations

from app.cps import MAX_LEVEL
from app.scene import LIGHT_MIN_DIST2
from app.sky_field import LEAN as SKY_LEAN

# Lights: the uniform block holds this many (std140, three vec4 each: 48 KiB of the 64 KiB
# block limit).
MAX_LIGHTS = 1024
# A lamp's inverse-square falloff 1 / max(d^2, LIGHT_MIN_DIST2) (m2): LIGHT_MIN_DIST2 is
# defined with the scene model (app.scene.lamp_falloff, the CPU side) and injected from here.
# Shadow maps (render/shadows.py): tiles of one depth atlas, SHADOW_ATLAS texels square; a
# point light takes six tiles (cube faces), a spot or the sun one.
MAX_SHADOW_TILES = 64
SHADOW_ATLAS = 4096
# The screen-space shadow mask (render/shadow_mask.py): this many lights' shadow factors per
# sample, 8 bits each in two 32-bit words (shadow_mask.glsl).
SHADOW_MASK_SLOTS = 8
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

# Merged static meshes (render.gpu_scene.GpuGroup): the per-object table's SSBO binding (one
# vec4 per mesh: the TCR tint rgb and its texture level minus the resident base), read by
# geometry.vert.glsl under the OBJECT_TABLE variant. Bindings 0-5 are the photon gather's.
OBJECT_TABLE_BINDING = 6

# Photon gather: record / start textures are 1 << PM_TEX_SHIFT texels wide; work groups of
# PM_GROUP invocations (Algorithm 1 relies on it); heaps of at most PM_MAX_K entries; the
# reuse winner's "no left pixel lands here".
PM_TEX_SHIFT = 12
PM_GROUP = 64
PM_MAX_K = 64
PM_NO_WINNER = 0xFFFFFFFF

# Image units, keyed by the image uniform's name without "u_": the shaders declare
# ``layout(binding = IMAGE_UNIT_<NAME>)``, Python binds with ``render.pass_graph.bind_image``.
# One unit per name, so no two images of any program variant can meet on a unit.
IMAGE_UNITS = {
    "out": 0,  # the compute passes' output image
    "counts": 1,  # light culling: per-tile counts
    "lists": 2,  # light culling: per-tile lists
    "winner": 3,  # photon reuse scatter: the winners (read-write)
    "reuse_winner": 4,  # photon gather: the right eye's winners (read only)
}

# Texture units, keyed by the sampler uniform's name without "u_"; every sampler bind goes
# through ``render.pass_graph.bind_texture`` with this table. One unit per name (GL 4.3
# guarantees 80 combined units), so no two samplers of any program variant share one.
TEXTURE_UNITS = {
    name: unit
    for unit, name in enumerate(
        (
            "albedo",  # a mesh's albedo texture (geometry passes)
            "gb_albedo",
            "gb_normal",
            "gb_depth",
            "levels",
            "atlas",
            "blocks",
            "lit",
            "current",
            "history",
            "tile_counts",
            "tile_lists",
            "indirect",
            "pm_records",
            "pm_starts",
            "left_depth",
            "right_depth",
            "left_result",
            "depth",
            "bounds",
            "ab_reference",  # the presenter's split: the full-quality frame
            "eye_color",
            "text",
            "heat",
            "normal_map",  # material maps (render.gpu_scene.MAPS)
            "mr_map",
            "occlusion_map",
            "emissive_map",
            "ao",  # ambient occlusion (render/ao.py): the lighting's input, the pass's own
            "ao_depth",
            "ao_normal",
            "ao_raw",
            "sky",  # the baked sky (render.sky)
            "gb_sky",  # the G-buffer's sky visibility
            "shadow_atlas",  # the shadow maps' depth atlas (bound once per frame)
            "irradiance_cache",  # the photon map's irradiance cache (render/photons.py)
            "shadow_mask",  # the shadow mask (render/shadow_mask.py)
            "ambient_field",  # the even light by place (render/ambient_field.py)
            "reflect_source",  # the lit picture the reflections read (render/reflections.py)
            "reflect_half",  # the reflections traced at half size
            "sky_field",  # the sky's share by place (render/sky.py)
        )
    )
}


def _glsl(value: object) -> str:
    if isinstance(value, tuple):
        return "vec3(" + ", ".join(repr(float(v)) for v in value) + ")"
    return str(value)


# What every shader sees (values as GLSL text).
SHADER_DEFINES: dict[str, object] = {
    "MAX_LIGHTS": MAX_LIGHTS,
    "LIGHT_MIN_DIST2": repr(float(LIGHT_MIN_DIST2)),
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
    "MAX_SHADOW_TILES": MAX_SHADOW_TILES,
    "SKY_LEAN": repr(float(SKY_LEAN)),
    "OBJECT_TABLE_BINDING": OBJECT_TABLE_BINDING,
    "TEXTURE_UNIT_SHADOW_ATLAS": TEXTURE_UNITS["shadow_atlas"],
    **{f"IMAGE_UNIT_{k.upper()}": v for k, v in IMAGE_UNITS.items()},
}
