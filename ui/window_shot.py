"""The README's picture of the window: ``python -m ui.window_shot [PNG] [--size WxH]``.

Opens the window as a first run would (preferences in a temporary folder), in evaluation mode
on the showroom, draws a few frames and saves the whole window (menus, view, panels,
evaluation bar) as a PNG. Needs a display: under Xvfb,
``xvfb-run -a -s "-screen 0 1920x1080x24" python -m ui.window_shot docs/window-1366x768.png``.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

from PyQt6.QtWidgets import QApplication

from app.frame import parse_size
from app.settings import Settings

DEFAULT_OUT = "docs/window-1366x768.png"


def shoot(out: str | Path, size: tuple[int, int] = (1366, 768), scene: str = "showroom"):
    """Save the window at ``size`` in evaluation mode on ``scene`` (a QApplication must exist:
    ``ui.main_window.create_app``); returns the window, still open, for a caller that wants to
    look further."""
    from ui.main_window import MainWindow

    window = MainWindow(Settings())
    window.resize_to(*size)
    window.show()
    window.load(scene)
    window.wait_for_load()
    window.keys_overlay.dismiss()  # the picture shows the window in use, not its first run
    window.view.setFocus()
    for _ in range(6):  # a few frames; the statistics text and the bar refresh at 4 Hz
        QApplication.processEvents()
        window.eval_bar.refresh()
        window.view.repaint()
        time.sleep(0.26)
    Path(out).parent.mkdir(parents=True, exist_ok=True)
    if not window.grab().save(str(out), "PNG"):
        raise OSError(f"cannot write {out}")
    return window


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m ui.window_shot", description=__doc__)
    parser.add_argument("out", nargs="?", default=DEFAULT_OUT, help="PNG file to write")
    parser.add_argument("--size", default="1366x768", help="the window's size, WxH")
    parser.add_argument("--scene", default="showroom", help="built-in scene or model file")
    args = parser.parse_args(argv)
    from ui.main_window import create_app

    app = create_app()
    with tempfile.TemporaryDirectory() as config:
        os.environ["VRPREVIEW_CONFIG"] = config  # a first run: no remembered layout
        window = shoot(args.out, parse_size(args.size), args.scene)
        window.close()
        app.processEvents()
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
