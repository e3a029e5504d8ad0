"""The ``vrpreview`` command: the lab's CLI, with the window as its no-command case.

Qt is imported only when the window opens, so ``vrpreview render ...`` and the other headless
commands run without it.
"""

from __future__ import annotations

import sys
from pathlib import Path

from app.lab import cli
from app.paths import CameraPath
from app.settings import Settings


def open_window(scene: str | None, settings: Settings, path: CameraPath | None) -> int:
    from ui.main_window import run  # Qt from here on

    return int(run(scene, settings, path))


def open_survey(protocol: str, folder: Path, participant: str | None, size: str) -> int:
    """``vrpreview survey run``: the study's session runner in the window."""
    from ui.survey_runner import run_standalone  # Qt from here on

    return int(run_standalone(protocol, folder, participant, size))


def main(argv: list[str] | None = None) -> int:
    return cli.main(argv, open_window, open_survey)


if __name__ == "__main__":
    sys.exit(main())
