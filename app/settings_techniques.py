"""The settings of the papers' three techniques: adaptive textures (TCR), coarse pixel shading
(CPS) and photon-mapped indirect light; sections of :class:`app.settings.Settings`.
"""

from __future__ import annotations

from dataclasses import dataclass

from app.settings_fields import _opt


@dataclass
class TcrSettings:
    """Adaptive texture mapping (TCR paper): which terms choose each object's pyramid level."""

    enabled: bool = _opt(
        False,
        "Lowers texture detail where a viewer would not notice; off shows every texture at "
        "full detail.",
        label="Adaptive textures",
        paper="TCR paper: texture level per object",
    )
    preset: str = _opt(
        "ergonomics",
        "Which rules choose each object's texture detail: the paper's psychology or "
        "ergonomics set, or your own choice below.",
        label="Rules",
        paper="TCR paper: psychology and ergonomics phases",
        choices=("psychology", "ergonomics", "custom"),
        choice_labels={
            "psychology": "Psychology: distance, gaze, light",
            "ergonomics": "Ergonomics: distance, motion, light",
            "custom": "Custom: the rules ticked below",
        },
    )
    use_d: bool = _opt(
        True,
        "Farther objects get coarser textures, one level per doubling of distance.",
        label="Distance",
        paper="TCR paper: distance term d",
    )
    use_v: bool = _opt(
        True,
        "While you move, every texture is one level coarser.",
        label="Motion",
        paper="TCR paper: viewpoint-motion term v",
    )
    use_g: bool = _opt(
        False,
        "The object you look at steadily gets one level finer.",
        label="Gaze",
        paper="TCR paper: gaze term g",
    )
    use_l: bool = _opt(
        True,
        "In dim light textures get one level coarser per halving of the brightness.",
        label="Dim light",
        paper="TCR paper: brightness term l",
    )
    mode: str = _opt(
        "clamp",
        "How the chosen detail level is drawn: exactly that level, or smoothly with the "
        "finer levels left out.",
        label="Texture filtering",
        paper="TCR paper: sampling one pyramid level",
        choices=("paper", "clamp"),
        choice_labels={
            "paper": "Exactly the chosen level (paper)",
            "clamp": "Smooth (mipmaps from that level)",
        },
    )
    f_m: float = _opt(
        1.0,
        "Textures keep full detail up to twice this distance and lose one level at each "
        "doubling beyond it (at 2, 4, 8 times it).",
        label="Eye-to-screen distance",
        unit="m",
        paper="TCR paper: eye-to-screen distance f",
        lo=1e-6,
        hi=100.0,
        decimals=2,
        step=0.1,
    )
    move_on: float = _opt(
        0.15,
        "You count as moving once faster than this (turning 30° a second counts as 1 m/s).",
        label="Moving above",
        unit="m/s",
        paper="TCR paper: viewpoint moving",
        lo=0.0,
        hi=100.0,
        decimals=2,
        step=0.05,
    )
    move_off: float = _opt(
        0.05,
        "You count as still again once slower than this; the gap keeps textures from flickering.",
        label="Still below",
        unit="m/s",
        paper="TCR paper: viewpoint still",
        lo=0.0,
        hi=100.0,
        decimals=2,
        step=0.05,
    )
    window_s: float = _opt(
        0.15,
        "A change between moving and still must last this long before textures follow.",
        label="Change delay",
        unit="s",
        lo=0.0,
        hi=5.0,
        decimals=2,
        step=0.05,
    )
    level_bias: int = _opt(
        0,
        "Makes every texture this many levels coarser than the rules choose; the frame-rate "
        "control raises it when a frame takes too long.",
        label="Coarser textures by",
        unit="levels",
        paper="TCR paper: texture level per object",
        lo=0,
        hi=8,
        step=1.0,
        hidden=True,  # the frame-rate control's knob; command line and presets otherwise
    )
    tint: bool = _opt(
        False,
        "Colours every object by its texture level, as in the legend below.",
        label="Tint objects by level",
    )


@dataclass
class CpsSettings:
    """Coarse pixel shading against VR sickness (CPS paper, SPEC C) and the mitigation modes."""

    mode: str = _opt(
        "none",
        "How the edges of the view are calmed against VR sickness: not at all, darkened, "
        "blurred, or lit more coarsely (deferred method only).",
        label="Mitigation",
        paper="CPS paper: the mitigation modes",
        choices=("none", "black-mask", "blur-mask", "cps"),
        choice_labels={
            "none": "None",
            "black-mask": "Black mask (darkened edges)",
            "blur-mask": "Blur mask (blurred edges)",
            "cps": "Coarse pixel shading",
        },
    )
    max_level: int = _opt(
        4,
        "The largest square of pixels that may share one lighting result (level 0 is one "
        "pixel, level 5 is 32 by 32 pixels).",
        label="Coarsest block",
        paper="CPS paper: detail level s",
        lo=0,
        hi=5,
        range_text="From 1×1 to 32×32 pixels.",
    )
    fovea_deg: float = _opt(
        10.0,
        "Within this angle of where you look, every pixel is lit in full.",
        label="Sharp area around the gaze",
        unit="°",
        paper="CPS paper: angle from the gaze point",
        lo=0.0,
        hi=180.0,
        decimals=1,
        step=1.0,
    )
    deg_per_level: float = _opt(
        6.0,
        "Beyond the sharp area, blocks double in size every this many degrees.",
        label="Detail falloff",
        unit="° per level",
        paper="CPS paper: detail falls with the angle from the gaze",
        lo=0.1,
        hi=180.0,
        decimals=1,
        step=1.0,
    )
    near_m: float = _opt(
        1.0,
        "Where an edge of the view is this close to a surface, that side may use the "
        "coarsest blocks.",
        label="Coarsest when nearer than",
        unit="m",
        paper="CPS paper: peripheral detail from edge rays",
        lo=0.0,
        hi=1000.0,
        decimals=2,
        step=0.25,
    )
    far_m: float = _opt(
        6.0,
        "Where an edge of the view looks this far or into open space, that side keeps full detail.",
        label="Full detail when farther than",
        unit="m",
        paper="CPS paper: peripheral detail from edge rays",
        lo=0.0,
        hi=1000.0,
        decimals=2,
        step=0.25,
    )
    rays_per_side: int = _opt(
        5,
        "Rays cast along the left, right and bottom edge of each eye to measure how near "
        "the surroundings are.",
        label="Edge test rays",
        unit="per side",
        paper="CPS paper: edge rays",
        lo=1,
        hi=64,
        step=1.0,
    )
    dispatch: str = _opt(
        "multi",
        "How the compute shader's work is split: one pass per detail level, or one pass "
        "over 32 by 32 pixel tiles; the picture is the same.",
        label="Compute passes",
        paper="CPS paper: multi-level against single dispatch",
        choices=("multi", "single"),
        choice_labels={"multi": "One pass per level", "single": "One pass, 32×32 tiles"},
    )
    filter: str = _opt(
        "hierarchical",
        "How coarse blocks are blended into the picture: flat blocks, ordinary bilinear, "
        "or the paper's hierarchical bilinear.",
        label="Block smoothing",
        paper="CPS paper: hierarchical bilinear filter, section 3.2.2",
        choices=("none", "bilinear", "hierarchical"),
        choice_labels={
            "none": "None (flat blocks)",
            "bilinear": "Bilinear",
            "hierarchical": "Hierarchical bilinear (paper)",
        },
    )
    temporal: bool = _opt(
        False,
        "Each frame one eye gets strong reduction and the other weak, swapping every frame, "
        "blended with the frame before.",
        label="Alternate the eyes",
        paper="CPS paper: alternating temporal filter, section 3.2.1",
    )
    reproject: bool = _opt(
        True,
        "Moves the frame before to the current viewpoint before blending, and drops what "
        "was hidden from it.",
        label="Follow head motion",
    )
    history_weight: float = _opt(
        0.7,
        "When the two frames are blended, how much the finer one counts.",
        label="Weight of the finer frame",
        paper="CPS paper: the finer image weighs more",
        lo=0.5,
        hi=1.0,
        decimals=2,
        step=0.05,
    )
    visualize: bool = _opt(
        False,
        "Tints pixels by their block size, as in the legend below, and marks where the "
        "edge rays hit.",
        label="Show detail levels",
        paper="CPS paper: detail visualisation, Figure 2",
    )


@dataclass
class PhotonSettings:
    """Photon-mapped indirect light (SPEC D): traced on the CPU, gathered on the GPU."""

    enabled: str = _opt(
        "scene",
        "Light bounced off walls and furniture, from a photon map: on, off, or only where "
        "the scene asks for it.",
        label="Indirect light",
        paper="Photon paper: photon mapping",
        choices=("scene", "on", "off"),
        choice_labels={"scene": "As the scene asks", "on": "On", "off": "Off"},
    )
    indirect: str = _opt(
        "cache",
        "How each pixel gets its bounced light: looked up from light worked out once when "
        "the photons are traced (fast enough to walk), or collected from the photons around "
        "it every frame (the paper's method: slow, for its tables and the reference pictures).",
        label="Indirect light method",
        paper="Christensen 1999: precomputed irradiance; photon paper: per-pixel gather",
        choices=("cache", "gather"),
        choice_labels={"cache": "Precomputed (fast)", "gather": "Collected per pixel (paper)"},
    )
    photons: int = _opt(
        262144,
        "How many light paths are traced from the lights; more is smoother and slower "
        "(the paper uses 16,384 to 262,144).",
        label="Photons",
        unit="photons",
        paper="Photon paper: photon count",
        lo=0,
        hi=1 << 22,
        step=4096.0,
    )
    refine_photons: int = _opt(
        1 << 20,
        "While you stand still, more light paths are traced in the background, up to this "
        "many, and the bounced light grows smoother (with the precomputed method; walking "
        "pauses it and keeps what is done). At or below the photons above: no more.",
        label="Photons while standing",
        unit="photons",
        lo=0,
        hi=1 << 24,
        step=65536.0,
    )
    radius_m: float = _opt(
        0.3,
        "How far around each point photons are collected; larger is smoother but blurs the light.",
        label="Gather radius",
        unit="m",
        paper="Photon paper: gather radius r",
        lo=1e-3,
        hi=100.0,
        decimals=3,
        step=0.05,
    )
    gather: str = _opt(
        "radius",
        "How the photons near a point are found; all give nearly the same light at "
        "different speeds.",
        label="Photon search",
        paper="Photon paper: hash grid, tree and nearest-photon gathers",
        choices=("radius", "radius-half", "heap", "kdtree", "kdtree-heap", "shared"),
        choice_labels={
            "radius": "Grid, cell = radius (paper default)",
            "radius-half": "Grid, cell = half the radius",
            "heap": "Nearest photons only",
            "kdtree": "Tree search",
            "kdtree-heap": "Tree search, nearest photons only",
            "shared": "Cooperative, shared memory (Algorithm 1)",
        },
    )
    k: int = _opt(
        32,
        "For the searches that keep only the nearest photons: how many each point keeps.",
        label="Nearest photons kept",
        unit="photons",
        paper="Photon paper: k nearest photons",
        lo=1,
        hi=64,
        step=1.0,
    )
    fused: bool = _opt(
        False,
        "Collects photons inside the lighting step, in one pass, instead of in a pass of "
        "its own before it.",
        label="Collect while lighting",
        paper="Photon paper: single scheme, not hybrid",
    )
    stereo_reuse: bool = _opt(
        True,
        "Collects photons for the left eye first and reuses them where the right eye sees "
        "the same points.",
        label="Reuse the left eye for the right",
        paper="Photon paper: stereo reuse, section 3.3",
    )
    reuse_tolerance: float = _opt(
        0.01,
        "How far apart the two eyes' points may be, relative to their distance, and still "
        "count as the same point.",
        label="Reuse tolerance",
        unit="% of distance",
        lo=0.0,
        hi=1.0,
        decimals=1,
        step=0.5,
        scale=100.0,
    )
    max_bounces: int = _opt(
        8,
        "How many times a photon may bounce before it stops.",
        label="Bounces per photon",
        unit="bounces",
        lo=1,
        hi=64,
        step=1.0,
    )
    seed: int = _opt(
        0,
        "Changes the random pattern of the photons; the same number gives the same picture.",
        label="Random seed",
        lo=0,
        hi=2**31 - 1,
        step=1.0,
    )
    show_reuse: bool = _opt(
        False,
        "Paints right-eye pixels reused from the left eye green and newly collected ones red.",
        label="Show reused pixels",
    )
