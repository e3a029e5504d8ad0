"""Which shader programs the governor's knobs can turn to, so the renderer can compile them
before a walk needs them (``render.renderer.Renderer.warm_variants``): a program's first frame
compiles it, 0.3-1 s on llvmpipe with a cold shader cache, a stall in the walk."""

from __future__ import annotations

from typing import Any

from app.settings import Settings

#: The knob keys whose values choose shader programs (the rest are uniforms or index ranges),
#: each with what it chooses (:func:`program_variants`).
PROGRAM_KEYS = {
    "render.shadows": "lighting",
    "cps.mode": "coarse",
    "render.scale": "scale",
    "render.upscaler": "upscaler",
}


def program_key(settings: Settings) -> tuple:
    """What of a frame's settings picks the programs the governor's knobs change (with the
    path and the texture levels' mode they apply to): two frames of one key draw the same."""
    t = settings.tcr
    return (settings.render.path, t.enabled, t.mode, t.tint, *_program_class(settings, {}))


def _program_class(user: Settings, step: dict[str, Any]) -> tuple:
    """What of ``step`` (over the user's values) picks programs: the shadow mode, CPS on or
    off, drawn at full size or enlarged, the upscaler."""

    def value(key: str) -> Any:
        return step[key] if key in step else user.get(key)

    return (
        value("render.shadows"),
        value("cps.mode") == "cps",
        float(value("render.scale")) < 1.0,
        value("render.upscaler"),
    )


def program_variants(
    user: Settings, knob_steps: list[list[dict[str, Any]]]
) -> list[dict[str, Any]]:
    """Overrides that between them draw every shader program reachable by ``knob_steps``
    (each knob's steps below ``user``'s values, ``Governor._knobs``).

    Shadows and coarse lighting choose the lighting's programs together, so every pair of
    their values is one override; the render scale and the upscaler choose the present
    pass's alone, so their values ride along those, in turn. The user's own values (``{}``)
    are the frame drawn anyway and are left out."""
    reach: dict[str, list[dict[str, Any]]] = {}
    for steps in knob_steps:
        for step in steps:
            keys = [k for k in step if k in PROGRAM_KEYS]
            if not keys:
                continue
            options = reach.setdefault(PROGRAM_KEYS[keys[0]], [{}])
            if _program_class(user, step) not in [_program_class(user, o) for o in options]:
                options.append(dict(step))
    lighting = [{**a, **b} for a in reach.get("lighting", [{}]) for b in reach.get("coarse", [{}])]
    present = [{**a, **b} for a in reach.get("scale", [{}]) for b in reach.get("upscaler", [{}])]
    out: list[dict[str, Any]] = []
    for i in range(max(len(lighting), len(present))):
        combo = {**lighting[i % len(lighting)], **present[i % len(present)]}
        if combo and combo not in out:
            out.append(combo)
    return out
