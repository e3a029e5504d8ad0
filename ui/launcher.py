"""The ``vrpreview`` command: the lab's CLI, with the window as its no-command case.

Qt is imported only when the window opens, so ``vrpreview render ...`` and the other headless
commands run without it.
"""

from __future__ import annotations

import sys

from app.lab import cli
from app.paths import CameraPath
from app.settings import Settings


def open_window(scene: str, settings: Settings, path: CameraPath | None) -> int:
    from ui.main_window import run  # Qt from here on

    return int(run(scene, settings, path))


def main(argv: list[str] | None = None) -> int:
    return cli.main(argv, open_window)


if __name__ == "__main__":
    sys.exit(main())
