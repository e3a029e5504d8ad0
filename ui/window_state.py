"""How the window lays out the eyes and what it remembers between runs.

The eyes keep a headset's shape: a headset's eye is about 0.9 as wide as it is tall (Valve
Index and HTC Vive: 1440x1600 and 1080x1200) and at most square (Pico 4: 2160x2160). A view
whose halves are narrower than 0.8 or wider than 1.0 is letterboxed (black bars above and
below, or beside): each eye is as large as fits at the nearest of those shapes, and the pair
sits in the middle. A 16:9 view splits into two 0.89 halves, so full screen fills the screen.

What the window remembers goes through :func:`ui.prefs.prefs` (one INI file): its geometry and
dock layout, the last scene, the recent files (newest first, 10 at most) and the folder of the
last file opened.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

from ui.prefs import prefs

EYE_ASPECT_MIN = 0.8  # eye width / height, narrowest shown without bars
EYE_ASPECT_MAX = 1.0  # widest
RECENT_MAX = 10


@dataclass(frozen=True)
class EyeLayout:
    """Where the two eyes sit in the view, in device pixels from the view's top-left."""

    view_width: int
    view_height: int
    x: int  # left edge of the left eye
    y: int  # top edge of both eyes
    eye_width: int
    eye_height: int

    @property
    def gl_origin(self) -> tuple[int, int]:
        """The pair's lower-left corner in OpenGL's window coordinates (y from the bottom)."""
        return self.x, self.view_height - self.y - self.eye_height

    def eye_rect(self, eye: int) -> tuple[int, int, int, int]:
        """(x, y, width, height) of eye 0 (left) or 1 (right), y from the top."""
        return self.x + eye * self.eye_width, self.y, self.eye_width, self.eye_height

    def pair_rect(self) -> tuple[int, int, int, int]:
        """(x, y, width, height) of both eyes together, y from the top."""
        return self.x, self.y, 2 * self.eye_width, self.eye_height

    def to_eye(self, x: float, y: float) -> tuple[float, float]:
        """A view pixel (device pixels, from the top-left) as (u, v) inside the eye it is over:
        0..1 across and down the eye; a point on a bar counts as the nearest edge."""
        if not (math.isfinite(x) and math.isfinite(y)):
            return 0.5, 0.5
        ex = x - self.x
        if ex >= self.eye_width:
            ex -= self.eye_width
        u = ex / self.eye_width
        v = (y - self.y) / self.eye_height
        return min(1.0, max(0.0, u)), min(1.0, max(0.0, v))

    def from_eye(self, eye: int, u: float, v: float) -> tuple[float, float]:
        """The view pixel (device pixels, from the top-left) at (u, v) of eye 0 or 1."""
        return self.x + (eye + u) * self.eye_width, self.y + v * self.eye_height


def eye_layout(
    view_width: int,
    view_height: int,
    aspect_min: float = EYE_ASPECT_MIN,
    aspect_max: float = EYE_ASPECT_MAX,
) -> EyeLayout:
    """The eyes' place in a view of ``view_width`` x ``view_height`` device pixels."""
    vw, vh = max(2, int(view_width)), max(1, int(view_height))
    eye_w, eye_h = vw // 2, vh
    if eye_w > aspect_max * eye_h:  # too wide: bars beside
        eye_w = max(1, int(aspect_max * eye_h))
    elif eye_w < aspect_min * eye_h:  # too tall: bars above and below
        eye_h = max(1, min(vh, int(eye_w / aspect_min)))
    return EyeLayout(vw, vh, (vw - 2 * eye_w) // 2, (vh - eye_h) // 2, eye_w, eye_h)


# -- remembered between runs -------------------------------------------------------------------
def recent_files() -> list[str]:
    """The model files opened last, newest first."""
    value = prefs().value("files/recent", [])
    if isinstance(value, str):  # QSettings gives a one-entry list back as a plain string
        value = [value]
    if not isinstance(value, list):  # a hand-edited file: nothing we can use
        return []
    return [str(v) for v in value if v and Path(str(v)).is_absolute()][:RECENT_MAX]


def remember_opened(name_or_path: str) -> None:
    """A scene loaded: the last scene; a file also goes first in the recent files, and its
    folder is where File > Open starts next time."""
    p = prefs()
    p.setValue("files/last_scene", name_or_path)
    path = Path(name_or_path)
    if path.suffix and path.is_file():
        full = str(path.resolve())
        recent = [full] + [f for f in recent_files() if f != full]
        p.setValue("files/recent", recent[:RECENT_MAX])
        p.setValue("files/last_folder", str(path.resolve().parent))


def forget_recent(name_or_path: str) -> None:
    """Take a file (gone or unreadable) off the recent files."""
    full = str(Path(name_or_path).resolve())
    prefs().setValue("files/recent", [f for f in recent_files() if f not in (full, name_or_path)])


def last_scene(default: str = "showroom") -> str:
    """The scene loaded last (``default`` on a first run, or when its file is gone)."""
    value = str(prefs().value("files/last_scene", "") or "")
    if not value or (Path(value).suffix and not Path(value).is_file()):
        return default
    return value


def last_folder() -> str:
    """Where File > Open starts: the folder of the last file opened (the home folder first)."""
    value = str(prefs().value("files/last_folder", "") or "")
    return value if value and Path(value).is_dir() else str(Path.home())
