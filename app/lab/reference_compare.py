"""``vrpreview reference-compare``: our frame against the Cycles reference, feature by feature.

The reference itself (the export, the Cycles job, its cache, the display transform both sides
share) is :mod:`app.lab.cycles_reference`; here our left eye is drawn for the settings with
each feature on and off (:func:`our_frames`) and FLIP'd against it (:func:`compare`), and both
commands (``reference``, ``reference-compare``) are hooked into app/lab/cli.py.
"""

from __future__ import annotations

import sys
from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

from app import metrics
from app.camera import StereoCamera
from app.fileio import atomic_write_json, atomic_write_png
from app.lab.cycles_reference import (
    CyclesError,
    ToneCurve,
    bpy_version,
    export,
    fixed_exposure,
    parse_view,
    present,
    render,
    tone_curve,
)
from app.scene import Scene, Viewpoint
from app.settings import Settings, SettingsError


# -- our frame and the comparison --------------------------------------------------------------
@dataclass
class OurFrame:
    """Our left eye: what the present pass showed, the linear HDR it showed, and the display
    transform it used (the reference goes through the same)."""

    image: np.ndarray  # (H, W, 3) uint8 sRGB
    hdr: np.ndarray  # (H, W, 3) float32 cd/m2
    exposure: float
    curve: ToneCurve

    def shown(self, radiance: np.ndarray) -> np.ndarray:
        return present(radiance, self.exposure, self.curve)


@dataclass(frozen=True)
class Feature:
    """A feature as settings overrides: its frame with ``on`` against one with ``off``."""

    name: str
    label: str
    on: dict[str, Any]
    off: dict[str, Any]
    # The feature changes the scene, not only our picture of it (the sky lights the room):
    # both frames are compared with the reference rendered with ``on``.
    changes_reference: bool = False


# Features other branches bring (render.shadows, AO, normal maps, ...) are listed here by
# their keys; keys this build's Settings does not know are skipped with a note, so the table
# works before and after they merge. Add a row to add a feature.
FEATURES: tuple[Feature, ...] = (
    Feature("shadows", "Shadows", {"render.shadows": "soft"}, {"render.shadows": "off"}),
    Feature("sky", "Sun and sky", {"sky.enabled": True}, {"sky.enabled": False}, True),
    Feature("ao", "Ambient occlusion", {"render.ao": "screen"}, {"render.ao": "off"}),
    Feature("ao_baked", "Ambient occlusion, baked", {"render.ao": "baked"}, {"render.ao": "off"}),
    Feature(
        "normal_maps", "Normal maps", {"render.normal_maps": True}, {"render.normal_maps": False}
    ),
    Feature("indirect", "Indirect light", {"photons.enabled": "on"}, {"photons.enabled": "off"}),
    Feature(
        "ambient", "Ambient light", {}, {"render.ambient": 0.0, "render.ambient_estimate": False}
    ),
    Feature(
        "ambient_estimate",
        "Ambient from the lamps (not fixed)",
        {"render.ambient_estimate": True},
        {"render.ambient_estimate": False},
    ),
    Feature(
        "ambient_by_place",
        "Even light by place (not one level)",
        {"render.ambient_by_place": True},
        {"render.ambient_by_place": False},
    ),
    Feature("cps", "Coarse pixel shading", {"cps.mode": "cps"}, {"cps.mode": "none"}),
    Feature(
        "reflections",
        "Reflections on glossy surfaces",
        {"render.reflections": "screen"},
        {"render.reflections": "off"},
    ),
)


def with_overrides(settings: Settings, overrides: dict[str, Any]) -> Settings:
    out = settings.copy()
    for key, value in overrides.items():
        out.set(key, value)
    return out


def usable(feature: Feature, settings: Settings) -> str | None:
    """None if both sides of ``feature`` apply to ``settings``, else why not."""
    try:
        with_overrides(settings, feature.on)
        with_overrides(settings, feature.off)
    except SettingsError as exc:
        return f"skipped: {exc}".split(" (known:")[0]
    return None


SETTLE_FRAMES = 3  # frames drawn per variant in a comparison, the last one kept
AO_BAKE_WAIT_S = 300.0  # the baked occlusion (render.ao=baked) is waited for, as the sky


def our_frames(
    scene: Scene,
    view: Viewpoint,
    size: tuple[int, int],
    variants: dict[str, Settings],
    still: bool = False,
) -> dict[str, OurFrame]:
    """Our left eye at ``size`` for each settings variant.

    One host and one session draw them all, as the window does: the session ticks once at
    the view (gaze at the centre, texture levels, the coarse-shading caps) and the settings
    are changed in place between frames, as the panels change them. Each variant's picture is
    the settled one, as a user sees it after a moment at the view: the sky's visibility baked
    (it lights the room through the windows only once baked), every shadow map drawn (the
    per-frame budget of shadow redraws lifted), the baked occlusion done, the automatic
    exposure metered afresh, and the last of ``SETTLE_FRAMES`` frames. ``still``: the picture
    the window shows once the viewer has stood there a while, refined (``render.refine`` on:
    jittered samples averaged until every pixel has ``render.refine_samples``; the photon map
    grown to ``photons.refine_photons``)."""
    from app.paths import FIXED_DT
    from app.refine import needed
    from app.session import Session
    from render.offscreen import OffscreenHost  # GL only when a comparison runs

    out: dict[str, OurFrame] = {}
    if not variants:
        return out
    live = next(iter(variants.values())).copy()
    session = Session(live)
    session.set_scene(scene)
    with OffscreenHost(2 * size[0], size[1], live) as host:
        host.grow_photons = still  # the photon map grown as it grows while one stands
        host.set_scene(scene)
        host.set_text_image(None)
        for name, settings in variants.items():
            for key in settings.keys():
                if live.get(key) != settings.get(key):
                    live.set(key, settings.get(key))
            live.set("render.shadow_updates_per_frame", 64)  # every shadow map at once
            if still:
                live.set("render.refine", "on")
            if live.sky.enabled and host.renderer.gpu_scene is not None:
                with host.ctx:
                    host.renderer.daylight.wait_for_visibility(host.renderer.gpu_scene)
            if live.render.ao == "baked" and host.renderer.gpu_scene is not None:
                host.draw(session.frame_input(*size))  # the first draw starts the bake
                bake = host.renderer.gpu_scene.ao_bake
                if bake is not None:  # the settling frames then upload it
                    bake.wait(AO_BAKE_WAIT_S)
            # Metered afresh (automatic exposure): a variant is seen as by an eye adapted to
            # it, not still adapting from the variant before (which made the order matter).
            host.renderer.meter_afresh()
            frames = needed(live.render.refine_samples) + 2 if still else SETTLE_FRAMES
            for _ in range(frames):
                session.walker.place(view.position, view.yaw_deg, view.pitch_deg)
                session.eye_size = size
                session.tick(FIXED_DT)
                img = host.draw(session.frame_input(*size))
            # the exposure the present pass applied (metered, with the exposure branch)
            scale = float(getattr(host.renderer, "_exposure_scale", 1.0))
            out[name] = OurFrame(
                img[:, : size[0]].copy(),
                host.read_hdr(0)[:, :, :3].copy(),
                scale * live.render.exposure,
                tone_curve(live),
            )
    return out


@dataclass
class FeatureRow:
    name: str
    label: str
    flip_on: float | None = None
    flip_off: float | None = None
    note: str = ""

    @property
    def helps(self) -> bool | None:
        if self.flip_on is None or self.flip_off is None:
            return None
        return self.flip_on < self.flip_off


@dataclass
class Comparison:
    scene: str
    view: dict[str, Any]
    size: tuple[int, int]
    samples: int
    reference: str  # the cached reference's folder
    flip_defaults: float
    mean_luminance_ours: float
    mean_luminance_reference: float
    features: list[FeatureRow]
    still: bool = False  # our frames refined, as the window shows a view once still

    def to_dict(self) -> dict[str, Any]:
        d = asdict(self)
        for row, f in zip(d["features"], self.features):
            row["helps"] = f.helps
        return d

    def table(self) -> str:
        lines = [
            f"{self.scene} {self.size[0]}x{self.size[1]}, {self.samples} samples"
            f"{', ours refined (still)' if self.still else ''}: FLIP "
            f"{self.flip_defaults:.3f} with the current settings (mean luminance ours "
            f"{self.mean_luminance_ours:.2f}, reference {self.mean_luminance_reference:.2f} "
            "cd/m2)",
            "| Feature | FLIP on | FLIP off | On is closer |",
            "|---|---|---|---|",
        ]
        for r in self.features:
            if r.helps is None:
                lines.append(f"| {r.label} | | | {r.note} |")
            else:
                lines.append(
                    f"| {r.label} | {r.flip_on:.3f} | {r.flip_off:.3f} | "
                    f"{'yes' if r.helps else 'no'} |"
                )
        return "\n".join(lines)


def without_gaze_ring(size: tuple[int, int], radius_px: float = 10.0) -> np.ndarray:
    """Every pixel but the gaze ring our overlay draws at the view's centre (the gaze of a
    frame with no mouse), which the reference has no counterpart of."""
    y, x = np.mgrid[0 : size[1], 0 : size[0]]
    return np.hypot(x + 0.5 - size[0] / 2, y + 0.5 - size[1] / 2) > radius_px


def ppd_of(settings: Settings, size: tuple[int, int]) -> float:
    cam = StereoCamera(settings.stereo)
    return metrics.pixels_per_degree(size[0], cam.horizontal_fov_deg(*size))


def luminance(rgb: np.ndarray) -> np.ndarray:
    return rgb[..., 0] * 0.2126 + rgb[..., 1] * 0.7152 + rgb[..., 2] * 0.0722


def compare(
    scene_name: str,
    scene: Scene,
    settings: Settings,
    view: Viewpoint,
    size: tuple[int, int],
    samples: int,
    features: list[str] | None = None,
    cache: Path | None = None,
    note: Callable[[str], None] | None = None,
    max_bounces: int | None = None,
    still: bool = False,
) -> Comparison:
    """FLIP of our frame against the Cycles reference, with the settings as given and with
    each feature on and off."""
    chosen = [f for f in FEATURES if features is None or f.name in features]
    unknown = set(features or []) - {f.name for f in FEATURES}
    if unknown:
        raise ValueError(
            f"unknown feature {', '.join(sorted(unknown))} "
            f"(known: {', '.join(f.name for f in FEATURES)})"
        )
    ref = render(export(scene, settings, view, size, samples, max_bounces), cache, note)
    variants: dict[str, Settings] = {"defaults": settings}
    rows = []
    for f in chosen:
        why = usable(f, settings)
        label = f"{f.label} (reference with it on)" if f.changes_reference else f.label
        rows.append(FeatureRow(f.name, label, note=why or ""))
        if why is None:
            variants[f"{f.name}:on"] = with_overrides(settings, f.on)
            variants[f"{f.name}:off"] = with_overrides(settings, f.off)
    frames = our_frames(scene, view, size, variants, still)
    ppd = ppd_of(settings, size)

    keep = without_gaze_ring(size)
    references = {ref.digest: ref.radiance}

    def reference_for(overrides: dict[str, Any]) -> np.ndarray:
        job = export(scene, with_overrides(settings, overrides), view, size, samples, max_bounces)
        digest = job.digest(bpy_version())
        if digest not in references:
            references[digest] = render(job, cache, note).radiance
        return references[digest]

    def flip_of(name: str, radiance: np.ndarray = ref.radiance) -> float:
        ours = frames[name]  # the reference shown with our frame's exposure and curve
        return metrics.flip(ours.shown(radiance), ours.image, ppd, keep)

    for f, row in zip(chosen, rows):
        if not row.note:
            target = reference_for(f.on) if f.changes_reference else ref.radiance
            row.flip_on = flip_of(f"{row.name}:on", target)
            row.flip_off = flip_of(f"{row.name}:off", target)
    pos = view.position
    return Comparison(
        scene=scene_name,
        view={
            "position": [float(v) for v in pos],
            "yaw_deg": view.yaw_deg,
            "pitch_deg": view.pitch_deg,
        },
        size=size,
        samples=samples,
        reference=str(ref.folder),
        flip_defaults=flip_of("defaults"),
        mean_luminance_ours=float(luminance(frames["defaults"].hdr).mean()),
        mean_luminance_reference=float(luminance(ref.radiance).mean()),
        features=rows,
        still=still,
    )


# -- the commands ----------------------------------------------------------------------------------
COMMANDS = ("reference", "reference-compare")


def add_parsers(sub: Any, common: Callable[..., None]) -> None:
    """``vrpreview reference`` and ``vrpreview reference-compare`` (hooked in app/lab/cli.py)."""
    for name, text in (
        ("reference", "path-trace one view with Blender Cycles (cached): EXR/NPY + PNG"),
        (
            "reference-compare",
            "FLIP of our frame against the Cycles reference, each feature on and off",
        ),
    ):
        p = sub.add_parser(name, help=text)
        common(p, scene_required=True)
        p.add_argument("--view", default="spawn", help="spawn, or x,y,z,yaw,pitch (m, degrees)")
        p.add_argument("--size", default="640x720", help="one eye, WxH (the left eye)")
        p.add_argument("--samples", type=int, default=64, help="Cycles samples per pixel")
        p.add_argument("--out", default=None, help="PNG (reference) or JSON (compare) to write")
        p.add_argument(
            "--reference-bounces",
            type=int,
            default=None,
            help="Cycles' bounces (default: all; 0: the direct light alone)",
        )
        if name == "reference-compare":
            p.add_argument(
                "--still",
                action="store_true",
                help="our frames refined, as the window shows a view once you stand still "
                "(jittered samples averaged); default: the frame drawn while walking",
            )
            p.add_argument(
                "--features",
                default=None,
                help=f"comma-separated, of: {', '.join(f.name for f in FEATURES)} (all)",
            )


def run_command(args: Any, settings: Settings) -> int:
    from app import scenes
    from app.frame import parse_size
    from app.loaders import LoadOptions

    size = parse_size(args.size)
    if args.samples < 1:
        raise ValueError("--samples must be at least 1")
    scene = scenes.resolve(args.scene, LoadOptions.from_settings(settings.scene))
    view = parse_view(args.view, scene)

    def note(text: str) -> None:
        print(text, file=sys.stderr)

    try:
        if args.command == "reference":
            ref = render(
                export(scene, settings, view, size, args.samples, args.reference_bounces),
                note=note,
            )
            if args.out:
                shown = present(ref.radiance, fixed_exposure(settings), tone_curve(settings))
                atomic_write_png(args.out, shown)
                print(f"wrote {args.out}")
            how = "from the cache" if ref.cached else f"rendered in {ref.render_s:.0f} s"
            print(f"reference {ref.digest} ({how}): {ref.folder}")
            return 0
        features = args.features.split(",") if args.features else None
        result = compare(
            Path(args.scene).stem,
            scene,
            settings,
            view,
            size,
            args.samples,
            features,
            note=note,
            max_bounces=args.reference_bounces,
            still=args.still,
        )
    except CyclesError as exc:
        print(f"vrpreview: error: {exc}", file=sys.stderr)
        return 2
    print(result.table())
    if args.out:
        atomic_write_json(args.out, result.to_dict())
        print(f"wrote {args.out}")
    return 0
