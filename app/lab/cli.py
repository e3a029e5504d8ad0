"""``vrpreview``: headless ``render`` / ``bench`` / ``demo`` / ``experiments`` / ``study`` /
``report`` runs, or (without a command) the window through the ``open_window`` callback.

The lab never imports ``ui``: the ``vrpreview`` console script is :func:`ui.launcher.main`, which
passes a callback that loads the window only when it is wanted.
"""

from __future__ import annotations

import argparse
import logging
import math
import os
import sys
from collections.abc import Callable
from pathlib import Path

from app.frame import parse_size
from app.paths import CameraPath
from app.settings import Settings, SettingsError
from app.survey.cli import OpenRunner
from app.survey.cli import add_parser as add_survey_parser
from app.survey.cli import run as run_survey

EXIT_USAGE = 2
# Opens the window: (scene or None for the last one, settings, path or None) -> exit status.
OpenWindow = Callable[[str | None, Settings, CameraPath | None], int]


def _common(
    p: argparse.ArgumentParser, scene_required: bool = False, default: str | None = "showroom"
) -> None:
    p.add_argument(
        "--scene",
        default=None if scene_required else default,
        required=scene_required,
        help="built-in scene (showroom, showroom-8, showroom-100, showroom-gi, texture-test, "
        "tcr-cube, corridor) or a model file (.gltf .glb .obj .ply)",
    )
    p.add_argument(
        "--set",
        dest="assignments",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="change a setting, e.g. --set stereo.ipd_mm=60 (repeatable)",
    )
    p.add_argument("--preset", help="settings preset saved from the window (JSON)")
    p.add_argument(
        "--path",
        help="camera+gaze path (JSON file, or a built-in: "
        "showroom_walkthrough, showroom_stop, tcr_cube_distance, tcr_cube_orbit, "
        "tcr_cube_gaze) instead of the scene's default",
    )


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="vrpreview",
        description="Stereo VR preview for interiors.",
        epilog="Without a command the window opens (or, with no display, the headless demo runs). "
        "`vrpreview MODEL` (a file, as the desktop entry passes it) is `vrpreview --scene MODEL`.",
    )
    _common(parser, default=None)  # the window: the last scene (the showroom on a first run)
    parser.add_argument("--list-settings", action="store_true", help="print every setting key")
    sub = parser.add_subparsers(dest="command")
    r = sub.add_parser("render", help="render one stereo frame of the path to a PNG")
    _common(r, scene_required=True)
    r.add_argument("--out", required=True, help="PNG file to write")
    r.add_argument("--size", default="1280x720", help="whole side-by-side view, WxH")
    r.add_argument("--frame", type=int, default=0, help="frame N of the path (1/60 s steps)")
    b = sub.add_parser("bench", help="replay the path headless and write timings as JSON")
    _common(b, scene_required=True)
    b.add_argument("--out", required=True, help="JSON file to write")
    b.add_argument("--size", default="1280x720", help="whole side-by-side view, WxH")
    b.add_argument("--frames", type=int, default=120, help="frames to time (0: the whole path)")
    b.add_argument("--warmup", type=int, default=5, help="frames rendered before timing")
    b.add_argument(
        "--settle",
        type=int,
        default=0,
        help="frames walked before the warm-up, untimed (the frame-rate governor settles)",
    )
    b.add_argument(
        "--compare-every",
        type=int,
        default=0,
        metavar="K",
        help="every K-th frame, measure PSNR/SSIM/FLIP against full quality",
    )
    b.add_argument(
        "--stride",
        type=int,
        default=1,
        metavar="K",
        help="time every K-th frame of the path only (a long walk in fewer frames)",
    )
    ex = sub.add_parser("experiments", help="run a paper's benchmark set and print its tables")
    ex.add_argument(
        "which",
        choices=("tcr", "cps", "photons"),
        help="tcr: texture LOD; cps: coarse shading; photons: photon mapping",
    )
    ex.add_argument("--out", default=None, help="folder for the JSON files (out/bench-WHICH)")
    ex.add_argument("--only", default=None, help="only the runs whose name contains this")
    st = sub.add_parser(
        "study",
        help="speed/accuracy study: a settings matrix against full "
        "quality; results.json/.csv, report.md, pareto.png",
    )
    st.add_argument(
        "which",
        choices=("cps", "tcr", "photons", "governor"),
        help="cps: corridor; tcr and photons: showroom; governor: its error table "
        "(governor_errors.json) and the governor against fixed presets at equal frame time",
    )
    st.add_argument("--out", default=None, help="folder (out/study-WHICH); resumes if present")
    st.add_argument("--size", default="1280x720", help="whole side-by-side view, WxH")
    rep = sub.add_parser("report", help="benchmark JSON files as one markdown table")
    rep.add_argument("files", nargs="+", help="JSON files written by vrpreview bench")
    rep.add_argument(
        "--group",
        action="append",
        default=[],
        metavar="KEY",
        help="also list fps per group: by_state, by_gazed_level, by_gazed_distance_m (repeatable)",
    )
    lb = sub.add_parser(
        "load-bench", help="load time, first frame and peak memory of model files (a table)"
    )
    lb.add_argument("files", nargs="*", help="model files (.gltf .glb .obj .ply)")
    lb.add_argument("--size", default="1280x720", help="whole side-by-side view, WxH")
    lb.add_argument(
        "--synthetic",
        type=int,
        default=0,
        metavar="N",
        help="also a generated room of about N triangles (e.g. 1000000)",
    )
    lb.add_argument("--out", default="out/load-bench.json", help="JSON file to write")
    d = sub.add_parser("demo", help="walk the default path headless: screenshots + summary")
    _common(d)
    d.add_argument("--out-dir", default="out", help="folder for screenshots and summary.json")
    d.add_argument("--size", default="1280x720", help="whole side-by-side view, WxH")
    add_survey_parser(sub)
    from app.lab import reference_compare

    reference_compare.add_parsers(sub, _common)
    return parser


def _settings(args: argparse.Namespace) -> Settings:
    settings = Settings.load(args.preset) if args.preset else Settings()
    settings.apply(args.assignments)
    return settings


# The main parser's options that take a value: what follows them is no file argument.
_VALUE_OPTIONS = ("--scene", "--set", "--preset", "--path")


def file_as_scene(argv: list[str], parser: argparse.ArgumentParser) -> list[str]:
    """``vrpreview FILE`` (the desktop entry's ``Exec=vrpreview %f``) as ``--scene FILE``.

    The first argument that is neither an option, an option's value nor a command, and looks
    like a file (it exists, or has a suffix or a folder), becomes the scene; anything else is
    left to argparse, which names the commands for a mistyped one."""
    commands: set[str] = set()
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            commands.update(action.choices)
    i = 0
    while i < len(argv):
        arg = argv[i]
        if arg in _VALUE_OPTIONS:
            i += 2
            continue
        if arg.startswith("-"):
            i += 1
            continue
        looks_like_file = Path(arg).suffix or os.sep in arg or os.path.exists(arg)
        if arg in commands or not looks_like_file:
            break
        return [*argv[:i], "--scene", arg, *argv[i + 1 :]]
    return list(argv)


def has_display() -> bool:
    return bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))


def main(
    argv: list[str] | None = None,
    open_window: OpenWindow | None = None,
    open_survey: OpenRunner | None = None,
) -> int:
    """Run the command in ``argv``; without one, ``open_window`` opens the window (no display
    or no ``open_window``: the headless walkthrough runs instead)."""
    logging.basicConfig(level=logging.INFO, format="%(levelname)s %(name)s: %(message)s")
    parser = build_parser()
    args = parser.parse_args(file_as_scene(sys.argv[1:] if argv is None else argv, parser))
    from app.loaders import SceneLoadError
    from app.paths import PathError
    from app.scenes import resolve_path
    from render.context import GLUnavailableError
    from render.shaders import ShaderError

    try:
        settings = _settings(args)
        if args.list_settings:
            for key in settings.keys():
                meta = settings.describe(key)
                print(f"{key} = {settings.get(key)!r}  # {meta.get('help', '')}")
            return 0
        path = resolve_path(args.path) if args.path else None
        return _run(args, settings, path, open_window, open_survey)
    except (
        SettingsError,
        SceneLoadError,
        PathError,
        GLUnavailableError,
        ShaderError,
        ValueError,
        OSError,
    ) as exc:
        print(f"vrpreview: error: {exc}", file=sys.stderr)
        return EXIT_USAGE


def _run(
    args: argparse.Namespace,
    settings: Settings,
    path: CameraPath | None,
    open_window: OpenWindow | None,
    open_survey: OpenRunner | None = None,
) -> int:
    from app.lab import bench

    if args.command == "survey":
        return run_survey(args, open_survey)
    if args.command in ("reference", "reference-compare"):
        from app.lab import reference_compare

        return reference_compare.run_command(args, settings)
    if args.command == "experiments":
        from app.lab.experiments import run_all

        print(run_all(args.which, args.out or f"out/bench-{args.which}", args.only))
        return 0
    if args.command == "study":
        from app.lab.study import RunProgress, run_study

        out = args.out or f"out/study-{args.which}"
        with RunProgress() as progress:
            if args.which == "governor":
                from app.lab.governor_study import run_governor_study

                rows = run_governor_study(out, args.size, progress)
            else:
                rows = run_study(args.which, out, args.size, progress)
        print(f"{len(rows)} runs; results.json, results.csv, report.md and pareto.png in {out}/")
        return 0
    if args.command == "report":
        from app.lab.report import report

        print(report(args.files, tuple(args.group)))
        return 0
    if args.command == "load-bench":
        from app.fileio import atomic_write_json
        from app.lab import load_bench

        parse_size(args.size)
        out = Path(args.out)
        rows = load_bench.run(args.files, args.size, args.synthetic, str(out.parent))
        atomic_write_json(out, {"rows": rows})
        print(load_bench.table(rows))
        print(f"wrote {out}")
        return 1 if any("error" in r for r in rows) else 0
    if args.command == "render":
        size = parse_size(args.size)
        bench.render_frame(args.scene, args.out, size, args.frame, settings, path)
        print(f"wrote {args.out}")
        return 0
    if args.command == "bench":
        size = parse_size(args.size)
        with bench.FrameProgress("bench") as progress:
            result = bench.bench(
                args.scene,
                size,
                args.frames,
                settings,
                args.warmup,
                path,
                progress,
                args.compare_every,
                args.stride,
                settle=args.settle,
            )
        from app.lab.results import write_json

        write_json(args.out, result)
        passes = ", ".join(f"{k} {v.median_ms:.1f}" for k, v in result.passes.items())
        print(
            f"{result.scene['name']} {args.size}: {result.fps_median:.1f} fps, "
            f"frame {result.frame_ms.median:.1f} ms median; passes (ms) {passes}"
        )
        print(f"textures resident: {result.texture_resident_bytes / 1e6:.2f} MB (median)")
        err = result.error_vs_full_quality
        if err and err.frame.frames:
            f, g = err.frame, err.gazed_object
            print(
                f"error vs full quality: frame PSNR {f.psnr_db:.1f} dB, SSIM "
                f"{f.ssim:.3f}, FLIP {f.flip:.3f}; gazed object "
                f"{g.psnr_db if g.frames else math.nan:.1f} dB, SSIM {g.ssim:.3f}"
            )
        print(f"wrote {args.out}")
        return 1 if result.errors else 0
    if args.command == "demo" or open_window is None or not has_display():
        if args.command != "demo":
            why = (
                "no display found (DISPLAY/WAYLAND_DISPLAY unset)"
                if not has_display()
                else "no window here (the `vrpreview` command, ui.launcher, opens it)"
            )
            print(
                f"vrpreview: {why}: running the default walkthrough headless instead; "
                "screenshots and a frame-time summary go to out/",
                file=sys.stderr,
            )
        out_dir = Path(getattr(args, "out_dir", "out"))
        size = parse_size(getattr(args, "size", "1280x720"))
        with bench.FrameProgress("walkthrough") as progress:
            summary = bench.demo(
                args.scene or "showroom", out_dir, size, settings, progress=progress
            )
        print(
            f"{summary['frames']} frames, {summary['fps_median']:.1f} fps median; "
            f"{len(summary['screenshots'])} screenshots and summary.json in {out_dir}/"
        )
        return 0
    return int(open_window(args.scene, settings, path))


if __name__ == "__main__":
    sys.exit(main())
