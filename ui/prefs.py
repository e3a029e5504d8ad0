"""The window's remembered preferences (geometry, dock, last scene, recent files, first run).

One INI file, ``$VRPREVIEW_CONFIG/vrpreview.ini`` (default ``~/.config/vrpreview``), read
through QSettings. The folder is looked up on every call, not once per process as QSettings'
own default paths are, so each test gets its own file (``tests/conftest.py`` points it at the
test's tmp folder) and a user's real preferences are never touched by a test run.
"""

from __future__ import annotations

import os
from pathlib import Path

from PyQt6.QtCore import QSettings


def config_dir() -> Path:
    """Where the preferences file lives (VRPREVIEW_CONFIG overrides)."""
    base = os.environ.get("VRPREVIEW_CONFIG") or Path.home() / ".config" / "vrpreview"
    return Path(base)


def prefs() -> QSettings:
    """The preferences store; values written through it are saved when it is destroyed."""
    return QSettings(str(config_dir() / "vrpreview.ini"), QSettings.Format.IniFormat)
