"""``make dist-check``: the built app renders the showroom as the checkout does.

    python packaging/dist_check.py dist/vrpreview/vrpreview [--size 640x360]

Runs ``COMMAND render --scene showroom`` from an empty folder in a clean environment (only
PATH=/usr/bin:/bin and a fresh HOME: no PYTHONPATH, no venv), renders the same frame with this
checkout, and compares the two PNGs. As root (with ``unshare``) the app runs in a private mount
namespace where every Python install and the checkout are empty folders, so it must bring all
it needs. Prints the figures; exits 1 on a mismatch.
"""

from __future__ import annotations

import argparse
import glob
import os
import shlex
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from PIL import Image

ROOT = Path(__file__).resolve().parent.parent
CLEAN_PATH = "/usr/bin:/bin"
# Same code, same Mesa: the pictures are equal; a little room for another driver's rounding.
MAX_MEAN_DIFF = 0.5


# OpenGL driver choice (Mesa's software rasterizer when the tests force it) passes through: the
# two renders must come from the same driver to be compared.
GL_DRIVER_VARS = (
    "LIBGL_ALWAYS_SOFTWARE",
    "GALLIUM_DRIVER",
    "__GLX_VENDOR_LIBRARY_NAME",
    "__EGL_VENDOR_LIBRARY_FILENAMES",
)


def clean_env(home: Path) -> dict[str, str]:
    """No Python, no checkout: PATH=/usr/bin:/bin, a fresh HOME and the GL driver choice."""
    env = {"PATH": CLEAN_PATH, "HOME": str(home), "LANG": "C.UTF-8"}
    env.update({k: os.environ[k] for k in GL_DRIVER_VARS if k in os.environ})
    return env


def python_and_checkout() -> list[Path]:
    """Folders that hold a Python or this checkout: hidden from the app when it can be."""
    found = {Path(sys.prefix), Path(sys.base_prefix), ROOT}
    for pattern in ("/usr/lib/python3*", "/usr/local/lib/python3*"):
        found.update(Path(p) for p in glob.glob(pattern))
    system = {Path("/"), Path("/usr"), Path("/usr/local")}  # a Debian Python's prefix is /usr
    folders = sorted(p.resolve() for p in found if p.is_dir() and p not in system)
    # A folder inside another hidden one (the venv inside the checkout) is hidden with it;
    # mounting over it after its parent went empty would fail.
    return [p for p in folders if not any(p != q and p.is_relative_to(q) for q in folders)]


def can_isolate() -> bool:
    """Root with ``unshare``: the app can run in a mount namespace without any Python."""
    if os.geteuid() != 0 or not shutil.which("unshare"):
        return False
    probe = subprocess.run(["unshare", "--mount", "true"], capture_output=True)
    return probe.returncode == 0


def isolated(argv: list[str], hide: list[Path]) -> list[str]:
    """``argv`` in a private mount namespace where each folder of ``hide`` is empty."""
    mounts = " && ".join(f"mount -t tmpfs vrpreview-hidden {shlex.quote(str(d))}" for d in hide)
    script = f'mount --make-rprivate / && {mounts} && exec "$@"'
    return ["unshare", "--mount", "sh", "-c", script, "sh", *argv]


def render_outside(
    command: str, size: str, folder: Path, isolate: bool = False
) -> tuple[np.ndarray, float, str]:
    """``command render`` from the empty ``folder``; the picture, the seconds and the output.

    With ``isolate`` the Python installs and the checkout are hidden (see ``isolated``); an app
    inside one of them is first copied into ``folder``."""
    home = folder / "home"
    work = folder / "work"
    home.mkdir(parents=True)
    work.mkdir()
    argv = [command, "render", "--scene", "showroom", "--size", size, "--out", "x.png"]
    if isolate:
        hide = python_and_checkout()
        app = Path(command).resolve()
        if any(app.is_relative_to(d) for d in hide):
            shutil.copytree(app.parent, folder / "app", symlinks=True)
            argv[0] = str(folder / "app" / app.name)
        argv = isolated(argv, hide)
    start = time.perf_counter()
    proc = subprocess.run(
        argv, cwd=work, env=clean_env(home), capture_output=True, text=True, timeout=300
    )
    seconds = time.perf_counter() - start
    output = proc.stdout + proc.stderr
    if proc.returncode != 0:
        raise RuntimeError(f"{command} render failed ({proc.returncode}):\n{output}")
    return np.asarray(Image.open(work / "x.png").convert("RGB")), seconds, output


def render_in_tree(size: str) -> np.ndarray:
    """The same frame from this checkout (headless EGL, default settings)."""
    if str(ROOT) not in sys.path:
        sys.path.insert(0, str(ROOT))
    from app.frame import parse_size
    from app.lab.bench import render_frame
    from app.settings import Settings

    with tempfile.TemporaryDirectory() as tmp:
        return render_frame("showroom", Path(tmp) / "x.png", parse_size(size), 0, Settings())


def folder_mb(path: Path) -> float:
    return (
        sum(p.stat().st_size for p in path.rglob("*") if p.is_file() and not p.is_symlink()) / 1e6
    )


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("command", help="the built app, e.g. dist/vrpreview/vrpreview")
    parser.add_argument("--size", default="640x360", help="whole side-by-side view, WxH")
    args = parser.parse_args(argv)
    command = Path(args.command).resolve()
    isolate = can_isolate()
    with tempfile.TemporaryDirectory() as tmp:
        outside, seconds, output = render_outside(str(command), args.size, Path(tmp), isolate)
    inside = render_in_tree(args.size)
    print(f"bundle: {command.parent} ({folder_mb(command.parent):.0f} MB)")
    print(f"render from an empty folder, clean environment: {seconds:.1f} s")
    if isolate:
        hidden = ", ".join(str(p) for p in python_and_checkout())
        print(f"with no Python and no checkout in sight (hidden: {hidden})")
    else:
        print("(not root or no unshare: Python installs and the checkout stayed visible)")
    if "embree unavailable" in output:
        print("the bundle fell back to numpy ray casting: embreex is missing from it")
        return 1
    if outside.shape != inside.shape:
        print(f"different sizes: bundle {outside.shape}, checkout {inside.shape}")
        return 1
    diff = np.abs(outside.astype(int) - inside.astype(int))
    print(f"against the checkout's render: mean difference {diff.mean():.3f}, max {diff.max()}")
    if diff.mean() > MAX_MEAN_DIFF or outside.std() < 1.0:
        print("dist-check FAILED: the bundle's picture differs from the checkout's")
        return 1
    print("dist-check passed")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
