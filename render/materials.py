"""A material as the shaders take it: which variant of material.glsl it needs (its maps, its
alpha mode) and its factors as uniform writes packed once per program."""

from __future__ import annotations

from typing import TYPE_CHECKING

import moderngl
import numpy as np

if TYPE_CHECKING:
    from render.gpu_scene import GpuGroup, GpuMesh


def material_defines(mesh: GpuMesh | GpuGroup) -> dict[str, object]:
    """The material.glsl variant for one mesh: which maps it samples, its alpha mode."""
    maps = mesh.maps or {}
    mode = mesh.material.alpha_mode
    extra = {
        "HAS_TANGENTS": mesh.tangents and "normal_map" in maps,
        "HAS_MR_MAP": "mr_map" in maps,
        "HAS_OCCLUSION_MAP": "occlusion_map" in maps,
        "HAS_EMISSIVE_MAP": "emissive_map" in maps,
        "ALPHA_MASK": mode == "MASK",
        "ALPHA_BLEND": mode == "BLEND",
        "UNLIT": mesh.material.unlit,
    }
    # Only the features it has: a plain material is the variant the renderer warms up.
    return {"HAS_TEXTURE": mesh.texture is not None, **{k: True for k, v in extra.items() if v}}


def alpha_mask_defines(mesh: GpuMesh | GpuGroup) -> dict[str, object]:
    """The variant for a depth-only pass (ids, shadow maps) with ``alpha_mask.glsl``: only a
    MASK material needs its base colour texture there."""
    if mesh.material.alpha_mode != "MASK":
        return {}
    return {"ALPHA_MASK": True, "HAS_TEXTURE": mesh.texture is not None}


def factor_writes(
    prog: moderngl.Program, mat, emissive_gain: float = 1.0
) -> list[tuple[moderngl.Uniform, bytes]]:
    """The material factors ``prog``'s variant reads, as (uniform, float32 bytes) pairs; the
    glow times ``emissive_gain`` (an unlit material at the scene's light: ``GpuScene``)."""
    values = {
        "u_base_color": mat.base_color,
        "u_roughness": mat.roughness,
        "u_metallic": mat.metallic,
        "u_emissive": [e * emissive_gain for e in mat.emissive],
        "u_normal_scale": mat.normal_scale,
        "u_occlusion_strength": mat.occlusion_strength,
        "u_alpha_cutoff": mat.alpha_cutoff,
    }
    out = []
    for name, value in values.items():
        member = prog.get(name, None)
        if isinstance(member, moderngl.Uniform):
            out.append((member, np.asarray(value, np.float32).tobytes()))
    return out
