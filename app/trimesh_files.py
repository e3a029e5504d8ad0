"""OBJ and PLY files (and anything else trimesh reads), as trimesh's scene."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from app.errors import SceneLoadError


def trimesh_load(path: Path) -> Any:
    """trimesh's scene, with every parser failure turned into a message for the user.

    ``process=False`` keeps the data as authored: trimesh would otherwise merge vertices and
    silently drop NaN ones, and :meth:`Scene.sanitized` is where repairs are made and reported.
    """
    import trimesh

    try:
        return trimesh.load_scene(str(path), process=False)
    except FileNotFoundError as exc:
        missing = Path(exc.filename).name if exc.filename else str(exc)
        raise SceneLoadError(
            f"Cannot read '{path.name}': a file it needs is missing ({missing})."
        ) from exc
    except MemoryError as exc:
        raise SceneLoadError(
            f"Cannot read '{path.name}': it is too large for the available memory."
        ) from exc
    except Exception as exc:  # noqa: BLE001 - parsers raise anything on damaged input
        detail = str(exc).strip() or type(exc).__name__
        if isinstance(exc, (ImportError, UnicodeDecodeError)):
            # trimesh reaches for an optional text-encoding detector on undecodable bytes.
            detail = "its content is not readable text"
        if len(detail) > 200:
            detail = detail[:200] + "..."
        raise SceneLoadError(
            f"Cannot read '{path.name}': the file is damaged or not a valid "
            f"{path.suffix.lower().lstrip('.').upper()} file ({detail})."
        ) from exc
