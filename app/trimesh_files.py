"""OBJ and PLY files (and anything else trimesh reads), as trimesh's scene.

Before trimesh sees an OBJ or PLY file it is checked and, where that is safe, repaired:

* text that is not UTF-8 (Windows exporters write cp1252/Latin-1 names and comments) is decoded
  as cp1252, falling back to Latin-1, for the OBJ, its MTL files and a PLY header; file names the
  OBJ or MTL refer to are found whether they are stored on disk UTF-8 or Latin-1 encoded;
* an OBJ vertex line with fewer than three numbers becomes a NaN vertex, so the face indices
  after it still point where the author meant and :meth:`Scene.sanitized` drops (and reports)
  the triangles that use it;
* a PLY header is read first: element counts that the data cannot hold (a truncated file, or a
  1 KB file claiming 2^31 vertices) or that would need more than ``max_memory_mb`` are refused
  before anything is allocated, and so is an OBJ too big for the limit;
* a binary PLY whose data is in the other byte order than its header says is read in the order
  that gives valid faces (with a warning); faces whose indices point past the vertices are
  dropped with a warning.
"""

from __future__ import annotations

import io
import logging
import os
import re
from pathlib import Path
from typing import Any

import numpy as np

from app.errors import SceneLoadError

log = logging.getLogger(__name__)

# In-memory bytes per byte of OBJ text, a rough upper bound for trimesh's parser.
_OBJ_MEMORY_PER_BYTE = 10

_PLY_SIZES = {
    "char": 1,
    "uchar": 1,
    "int8": 1,
    "uint8": 1,
    "short": 2,
    "ushort": 2,
    "int16": 2,
    "uint16": 2,
    "int": 4,
    "uint": 4,
    "int32": 4,
    "uint32": 4,
    "float": 4,
    "float32": 4,
    "double": 8,
    "float64": 8,
}
_PLY_FORMATS = ("ascii", "binary_little_endian", "binary_big_endian")
_BLANK_LINE = re.compile(rb"^[ \t\r]*\n", re.MULTILINE)
# An OBJ vertex line with fewer than three fields after the 'v'.
_SHORT_VERTEX = re.compile(r"^([ \t]*)v(?:[ \t]+[^ \t\r\n]+){0,2}[ \t\r]*$", re.MULTILINE)


def trimesh_load(path: Path, max_memory_mb: int = 8192, warnings: list[str] | None = None) -> Any:
    """trimesh's scene, with every parser failure turned into a message for the user.

    ``process=False`` keeps the data as authored: trimesh would otherwise merge vertices and
    silently drop NaN ones, and :meth:`Scene.sanitized` is where repairs are made and reported.
    Repairs made here are appended to ``warnings`` (and logged).
    """
    notes: list[str] = []
    try:
        return _load(path, max_memory_mb, notes)
    finally:
        for note in notes:
            log.warning("%s: %s", path.name, note)
        if warnings is not None:
            warnings.extend(notes)


def _load(path: Path, max_memory_mb: int, notes: list[str]) -> Any:
    import trimesh

    ext = path.suffix.lower()
    try:
        if ext == ".obj":
            data = _obj_bytes(path, _read_bytes(path), max_memory_mb, notes)
            try:
                scene = _parse(trimesh, io.BytesIO(data), "obj", path)
            except IndexError:
                # trimesh indexes its arrays with the face indices as written: drop the faces
                # that point past the vertices (or texture coordinates, normals) and read again.
                data = _obj_without_bad_faces(data.decode("utf-8"), notes).encode("utf-8")
                scene = _parse(trimesh, io.BytesIO(data), "obj", path)
        elif ext == ".ply":
            raw = _read_bytes(path)
            fmt, data = _checked_ply(path, raw, max_memory_mb)
            scene = _parse(trimesh, io.BytesIO(data), "ply", path)
            if fmt != "ascii" and _bad_face_count(scene):
                scene = _try_other_byte_order(trimesh, path, fmt, data, scene, notes)
        else:
            scene = trimesh.load_scene(str(path), process=False)
    except SceneLoadError:
        raise
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
        if ext == ".ply" and isinstance(exc, ValueError):
            detail = f"its data does not match the properties its header declares: {detail}"
        if len(detail) > 200:
            detail = detail[:200] + "..."
        raise SceneLoadError(
            f"Cannot read '{path.name}': the file is damaged or not a valid "
            f"{ext.lstrip('.').upper()} file ({detail})."
        ) from exc
    _drop_bad_faces(scene, notes)
    return scene


def _parse(trimesh: Any, data: io.BytesIO, file_type: str, path: Path) -> Any:
    return trimesh.load_scene(
        data,
        file_type=file_type,
        resolver=_resolver(str(path)),
        process=False,
        metadata={"file_name": _text(path.name), "file_path": _text(str(path))},
    )


def _text(name: str) -> str:
    """A file name that encodes as UTF-8: trimesh hashes the names it gives meshes.

    A name whose bytes on disk are not UTF-8 reaches Python with surrogate escapes; those bytes
    are read as cp1252/Latin-1 (Windows names in a zip) instead.
    """
    try:
        name.encode("utf-8")
        return name
    except UnicodeEncodeError:
        return _decode(os.fsencode(name))[0]


def _read_bytes(path: Path) -> bytes:
    try:
        return path.read_bytes()
    except OSError as exc:
        raise SceneLoadError(f"Cannot read '{path.name}': {exc.strerror or exc}.") from exc


def _decode(data: bytes) -> tuple[str, bool]:
    """The text, and whether it was UTF-8 (else cp1252, or Latin-1 where cp1252 has holes)."""
    try:
        return data.decode("utf-8-sig"), True
    except UnicodeDecodeError:
        pass
    try:
        return data.decode("cp1252"), False
    except UnicodeDecodeError:
        return data.decode("latin-1"), False


def _as_utf8(data: bytes) -> bytes:
    text, utf8 = _decode(data)
    return data if utf8 else text.encode("utf-8")


# --------------------------------------------------------------------------------------------
# OBJ
# --------------------------------------------------------------------------------------------


def _obj_bytes(path: Path, data: bytes, max_memory_mb: int, notes: list[str]) -> bytes:
    need_mb = len(data) * _OBJ_MEMORY_PER_BYTE / 2**20
    if need_mb > max_memory_mb:
        raise SceneLoadError(
            f"Cannot read '{path.name}': at {len(data) / 2**20:.0f} MB of text it would need "
            f"about {need_mb:.0f} MB to read, over the {max_memory_mb} MB limit "
            "(scene.max_memory_mb)."
        )
    if data[:2] in (b"\xff\xfe", b"\xfe\xff"):
        try:
            data = data.decode("utf-16").encode("utf-8")
        except UnicodeDecodeError:
            pass
    text, utf8 = _decode(data)
    if not utf8:
        notes.append("the file is not UTF-8 text: read it as Windows-1252 (Latin-1)")
    if b"\0" in data:
        raise SceneLoadError(
            f"Cannot read '{path.name}': it is not an OBJ file (it holds binary data, not text)."
        )
    if "\r" in text and "\n" not in text:  # classic Mac OS line ends
        text, utf8 = text.replace("\r", "\n"), False
    short = [m for m in _SHORT_VERTEX.finditer(text)]
    if short:
        first = text.count("\n", 0, short[0].start()) + 1
        notes.append(
            f"{len(short)} vertex line{'s have' if len(short) != 1 else ' has'} fewer than 3 "
            f"coordinates (first on line {first}): the triangles using "
            f"{'them' if len(short) != 1 else 'it'} are dropped"
        )
        text = _SHORT_VERTEX.sub(r"\1v nan nan nan", text)
    elif utf8:
        return data
    return text.encode("utf-8")


def _obj_without_bad_faces(text: str, notes: list[str]) -> str:
    """``text`` without the face lines whose indices point outside the file's lists.

    A positive index counts from the start of the file, a negative one back from the line it is
    on; an out-of-range texture-coordinate or normal index drops only that part of the face.
    """
    lines = text.split("\n")
    totals = {"v": 0, "vt": 0, "vn": 0}
    for line in lines:
        head = line.split(None, 1)[:1]
        if head and head[0] in totals:
            totals[head[0]] += 1
    seen = {"v": 0, "vt": 0, "vn": 0}
    dropped = stripped = 0
    out = []

    def ok(token: str, kind: str) -> bool:
        try:
            i = int(token)
        except ValueError:
            return False
        return 1 <= i <= totals[kind] if i > 0 else (i < 0 and -i <= seen[kind])

    for line in lines:
        parts = line.split()
        if parts and parts[0] in seen:
            seen[parts[0]] += 1
        elif parts and parts[0] == "f":
            refs = [p.split("/") for p in parts[1:]]
            if not all(r[0] and ok(r[0], "v") for r in refs):
                dropped += 1
                continue
            uv_ok = all(len(r) > 1 and r[1] and ok(r[1], "vt") for r in refs)
            n_ok = all(len(r) > 2 and r[2] and ok(r[2], "vn") for r in refs)
            if not (uv_ok and n_ok) and any(len(r) > 1 for r in refs):
                stripped += 1
                line = "f " + " ".join(
                    "/".join(
                        (r[0], r[1] if uv_ok else "", r[2] if n_ok and len(r) > 2 else "")
                    ).rstrip("/")
                    for r in refs
                )
        out.append(line)
    if dropped:
        notes.append(
            f"dropped {dropped} face{'s' if dropped != 1 else ''} whose vertex indices point "
            "past the file's vertices"
        )
    if stripped:
        notes.append(
            f"{stripped} face{'s' if stripped != 1 else ''} point past the file's texture "
            "coordinates or normals: read without them"
        )
    return "\n".join(out)


def _resolver(source: str) -> Any:
    """trimesh's file resolver for the files an OBJ names (MTL files, textures).

    It stays inside the model's folder like trimesh's own, finds a name whose bytes on disk are
    Latin-1 rather than UTF-8, and hands MTL files over as UTF-8.
    """
    from trimesh.resolvers import FilePathResolver

    class Resolver(FilePathResolver):
        def namespaced(self, namespace: str) -> Any:
            return Resolver(os.path.join(self.parent, namespace, ""))

        def get(self, name: str) -> bytes:
            try:
                data = super().get(name)
            except FileNotFoundError:
                legacy = _legacy_name(name)
                if legacy is None:
                    raise
                data = super().get(legacy)
            if name.strip().lower().endswith(".mtl"):
                data = _as_utf8(bytes(data))
            return bytes(data)

    resolver = Resolver(source)
    resolver.file_name = _text(resolver.file_name)  # OBJ meshes are named after the file
    return resolver


def _legacy_name(name: str) -> str | None:
    """``name`` as the file system spells it when its bytes are cp1252/Latin-1, not UTF-8."""
    for codec in ("cp1252", "latin-1"):
        try:
            legacy = os.fsdecode(name.encode(codec))
        except UnicodeEncodeError:
            continue
        return None if legacy == name else legacy
    return None


# --------------------------------------------------------------------------------------------
# PLY
# --------------------------------------------------------------------------------------------


def _checked_ply(path: Path, data: bytes, max_memory_mb: int) -> tuple[str, bytes]:
    """The PLY's format and its bytes with a UTF-8 header, once its counts are plausible."""
    end = data.find(b"end_header")
    if not data.startswith(b"ply") or end < 0:
        raise SceneLoadError(
            f"Cannot read '{path.name}': it is not a PLY file "
            "(the 'ply' header or its 'end_header' line is missing)."
        )
    nl = data.find(b"\n", end)
    body_start = len(data) if nl < 0 else nl + 1
    header_bytes = data[:body_start]
    header, _ = _decode(header_bytes)
    fmt = ""
    elements: list[tuple[str, int, int, int]] = []  # name, count, min bytes, memory bytes
    for line in header.splitlines():
        parts = line.split()
        if not parts:
            continue
        if parts[0] == "format" and len(parts) >= 2:
            fmt = parts[1]
        elif parts[0] == "element" and len(parts) >= 3:
            try:
                count = int(parts[2])
            except ValueError:
                raise SceneLoadError(
                    f"Cannot read '{path.name}': its header has an element count that is "
                    f"not a number ('{line.strip()[:60]}')."
                ) from None
            if count < 0:
                raise SceneLoadError(
                    f"Cannot read '{path.name}': its header declares {count} {parts[1]} "
                    "elements (a negative count)."
                )
            elements.append((parts[1], count, 0, 0))
        elif parts[0] == "property" and elements:
            name, count, least, memory = elements[-1]
            if len(parts) >= 5 and parts[1] == "list":
                for kind in parts[2:4]:
                    if kind not in _PLY_SIZES:
                        raise SceneLoadError(
                            f"Cannot read '{path.name}': its header gives list property "
                            f"'{parts[-1]}' the type '{kind}', which is not a PLY type."
                        )
                n = _PLY_SIZES.get(parts[2], 0)
                item = _PLY_SIZES.get(parts[3], 0)
                least, memory = least + n, memory + n + 3 * item
            elif len(parts) >= 2:
                if parts[1] not in _PLY_SIZES:
                    raise SceneLoadError(
                        f"Cannot read '{path.name}': its header gives property "
                        f"'{parts[-1]}' the type '{parts[1]}', which is not a PLY type."
                    )
                size = _PLY_SIZES[parts[1]]
                least, memory = least + size, memory + size
            elements[-1] = (name, count, least, memory)
    if fmt not in _PLY_FORMATS:
        raise SceneLoadError(
            f"Cannot read '{path.name}': its PLY format '{fmt or '(none)'}' is not one of "
            f"{', '.join(_PLY_FORMATS)}."
        )
    declared = ", ".join(_counted(count, name) for name, count, *_ in elements)
    body = len(data) - body_start
    if fmt == "ascii":
        total = sum(count for _, count, _, _ in elements)
        lines = _ply_data_lines(data, body_start)
        if total != lines:
            raise SceneLoadError(
                f"Cannot read '{path.name}': its header declares {declared}, but the file has "
                f"{'only ' if lines < total else ''}{lines} data line{'s' if lines != 1 else ''} "
                f"({'it is truncated or ' if lines < total else ''}its counts are wrong)."
            )
    else:
        least = sum(count * size for _, count, size, _ in elements)
        if least > body:
            raise SceneLoadError(
                f"Cannot read '{path.name}': its header declares {declared}, which needs at "
                f"least {least} bytes of data, but the file holds only {body} (it is truncated "
                "or its counts are wrong)."
            )
    need = sum(count * memory for _, count, _, memory in elements)
    if need > max_memory_mb * 2**20:
        raise SceneLoadError(
            f"Cannot read '{path.name}': its header declares {declared}, which would need "
            f"about {need / 2**20:.0f} MB, over the {max_memory_mb} MB limit "
            "(scene.max_memory_mb)."
        )
    utf8_header = header.encode("utf-8")
    if utf8_header != header_bytes:
        data = utf8_header + data[body_start:]
    return fmt, data


def _ply_data_lines(data: bytes, start: int) -> int:
    """Non-blank lines after the header (an ASCII PLY has one element per line)."""
    lines = data.count(b"\n", start)
    tail = data[data.rfind(b"\n", start) + 1 :] if lines else data[start:]
    if tail.strip():
        lines += 1  # a last line without its line end
    return lines - sum(1 for _ in _BLANK_LINE.finditer(data, start))


def _counted(count: int, name: str) -> str:
    if count == 1:
        return f"1 {name}"
    return f"{count} {'vertices' if name == 'vertex' else name + 's'}"


def _try_other_byte_order(
    trimesh: Any, path: Path, fmt: str, data: bytes, scene: Any, notes: list[str]
) -> Any:
    """The scene read in the other byte order, if that gives valid faces and ``scene`` not."""
    other = "binary_big_endian" if fmt == "binary_little_endian" else "binary_little_endian"
    swapped = data.replace(f"format {fmt}".encode(), f"format {other}".encode(), 1)
    try:
        alt = _parse(trimesh, io.BytesIO(swapped), "ply", path)
    except Exception:  # noqa: BLE001 - the other order is only a guess
        return scene
    if _bad_face_count(alt) or not _has_faces(alt) or not _finite(alt):
        return scene
    notes.append(
        f"the header says {fmt.replace('_', '-')} but the data is "
        f"{other.replace('_', '-')}: read it in that byte order"
    )
    return alt


def _geometries(scene: Any) -> list[Any]:
    return [g for g in getattr(scene, "geometry", {}).values() if hasattr(g, "faces")]


def _has_faces(scene: Any) -> bool:
    return any(len(g.faces) for g in _geometries(scene))


def _finite(scene: Any) -> bool:
    return all(np.isfinite(np.asarray(g.vertices, np.float64)).all() for g in _geometries(scene))


def _bad_faces(geom: Any) -> np.ndarray:
    faces = np.asarray(geom.faces)
    if faces.size == 0:
        return np.zeros(len(faces), dtype=bool)
    n = len(geom.vertices)
    return np.asarray(((faces < 0) | (faces >= n)).any(axis=1))


def _bad_face_count(scene: Any) -> int:
    return int(sum(_bad_faces(g).sum() for g in _geometries(scene)))


def _drop_bad_faces(scene: Any, notes: list[str]) -> None:
    """Drop faces whose indices point outside their mesh's vertices (and say so)."""
    dropped = 0
    for geom in _geometries(scene):
        bad = _bad_faces(geom)
        if bad.any():
            dropped += int(bad.sum())
            geom.update_faces(~bad)
    if dropped:
        notes.append(
            f"dropped {dropped} face{'s' if dropped != 1 else ''} whose vertex indices point "
            "past the file's vertices"
        )
