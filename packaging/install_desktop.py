"""Install the menu entry, the icon and the PLY file type for this user (``make install-desktop``).

    python packaging/install_desktop.py [--data-home ~/.local/share] [--exec COMMAND]

Copies ``vrpreview.desktop`` to DATA_HOME/applications/, the icons to
DATA_HOME/icons/hicolor/NxN/apps/vrpreview.png and ``vrpreview-mime.xml`` to
DATA_HOME/mime/packages/, then refreshes the MIME and icon caches where those tools exist. The
entry runs ``vrpreview`` from PATH (the wheel's command); when that is missing and the bundle
dist/vrpreview/vrpreview is built, the entry runs the bundle by its absolute path instead.
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
ICON_SIZES = (48, 128, 256)
BUNDLE = ROOT / "dist" / "vrpreview" / "vrpreview"


def default_data_home() -> Path:
    return Path(os.environ.get("XDG_DATA_HOME") or Path.home() / ".local" / "share")


def pick_exec(requested: str | None) -> str:
    """The command the entry runs: the one asked for, ``vrpreview`` on PATH, or the bundle."""
    if requested:
        return requested
    if shutil.which("vrpreview") or not BUNDLE.exists():
        return "vrpreview"
    return str(BUNDLE)


def desktop_entry(command: str) -> str:
    """packaging/vrpreview.desktop with ``command`` in Exec= and TryExec=."""
    lines = []
    for line in (HERE / "vrpreview.desktop").read_text(encoding="utf-8").splitlines():
        if line.startswith("Exec="):
            line = f"Exec={command} %f"
        elif line.startswith("TryExec="):
            line = f"TryExec={command}"
        lines.append(line)
    return "\n".join(lines) + "\n"


def install(data_home: Path, command: str) -> list[Path]:
    """Write the files under ``data_home``; returns them in the order written."""
    written = []
    apps = data_home / "applications"
    apps.mkdir(parents=True, exist_ok=True)
    entry = apps / "vrpreview.desktop"
    entry.write_text(desktop_entry(command), encoding="utf-8")
    written.append(entry)
    for size in ICON_SIZES:
        folder = data_home / "icons" / "hicolor" / f"{size}x{size}" / "apps"
        folder.mkdir(parents=True, exist_ok=True)
        icon = folder / "vrpreview.png"
        shutil.copyfile(ROOT / "assets" / "icons" / f"vrpreview-{size}.png", icon)
        written.append(icon)
    mime = data_home / "mime" / "packages"
    mime.mkdir(parents=True, exist_ok=True)
    shutil.copyfile(HERE / "vrpreview-mime.xml", mime / "vrpreview.xml")
    written.append(mime / "vrpreview.xml")
    return written


def refresh_caches(data_home: Path) -> None:
    """The desktop's caches, where their tools exist (a missing one only delays the icon)."""
    for tool, arg in (
        ("update-mime-database", data_home / "mime"),
        ("update-desktop-database", data_home / "applications"),
        ("gtk-update-icon-cache", data_home / "icons" / "hicolor"),
    ):
        if shutil.which(tool):
            extra = ["-f", "-t"] if tool == "gtk-update-icon-cache" else []
            subprocess.run([tool, *extra, str(arg)], check=False, capture_output=True)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data-home", type=Path, default=None, help="~/.local/share by default")
    parser.add_argument("--exec", dest="command", default=None, help="command the entry runs")
    parser.add_argument("--no-refresh", action="store_true", help="leave the caches alone")
    args = parser.parse_args(argv)
    data_home = (args.data_home or default_data_home()).expanduser()
    command = pick_exec(args.command)
    for path in install(data_home, command):
        print(f"installed {path}")
    if not args.no_refresh:
        refresh_caches(data_home)
    if command == "vrpreview" and not shutil.which("vrpreview"):
        print(
            "note: `vrpreview` is not on PATH yet: install the wheel (pip install "
            "dist/vrpreview-*.whl) or build the bundle (make dist) and run this again",
            file=sys.stderr,
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
