"""glTF buffers and accessors, decoded with numpy and validated before anything is allocated.

A glTF file describes its binary data (counts, offsets, strides) in JSON that nothing vouches
for: a 1 KB file can claim a billion vertices. Every accessor is checked against its buffer view
and every buffer view against its buffer before numpy touches the bytes, so a bad file is a
:class:`GltfDataError` with a plain sentence, and reading is one strided ``np.ndarray`` view plus
one conversion per accessor (no per-vertex Python).

Buffers come from the GLB's BIN chunk, ``data:`` URIs or files next to the scene. URIs are
percent-decoded, and only files inside the scene's folder are read: ``../``, absolute paths and
any scheme (``file:``, ``http:``) are refused with a warning, and the data they held is
:class:`BufferUnavailable` (the primitives that need it are dropped, not the whole file).
"""

from __future__ import annotations

import base64
import binascii
import re
from pathlib import Path
from typing import Any, TypeGuard
from urllib.parse import unquote, unquote_to_bytes

import numpy as np

COMPONENT_DTYPES: dict[int, np.dtype[Any]] = {
    5120: np.dtype("<i1"),
    5121: np.dtype("<u1"),
    5122: np.dtype("<i2"),
    5123: np.dtype("<u2"),
    5125: np.dtype("<u4"),
    5126: np.dtype("<f4"),
}
TYPE_COMPONENTS = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT2": 4, "MAT3": 9, "MAT4": 16}
# Far beyond any real model (2^31 elements of an accessor); larger claims are damage or attack.
MAX_COUNT = 2**31 - 1

# Buffer data: bytes read from a file or URI, or a view into the GLB file (never copied).
Blob = bytes | memoryview


class GltfDataError(Exception):
    """The file's binary layout is broken; the message completes "Cannot read 'x': ..."."""


class BufferUnavailable(Exception):
    """A buffer's data could not be had (missing file, refused URI); the message says which."""


def is_int(value: Any) -> TypeGuard[int]:
    """A JSON integer (not a bool, which Python counts as one)."""
    return isinstance(value, int) and not isinstance(value, bool)


def component_dtype(value: Any) -> np.dtype[Any] | None:
    """The numpy dtype of a glTF componentType, None for anything else (lists included)."""
    return COMPONENT_DTYPES.get(value) if is_int(value) else None


def type_components(value: Any) -> int | None:
    """Components per element of a glTF accessor type ("VEC3": 3), None for anything else."""
    return TYPE_COMPONENTS.get(value) if isinstance(value, str) else None


def as_list(value: Any) -> list[Any]:
    """``value`` when it is a JSON array, else empty: the JSON's shapes are not trusted."""
    return value if isinstance(value, list) else []


def as_dict(value: Any) -> dict[str, Any]:
    """``value`` when it is a JSON object, else empty."""
    return value if isinstance(value, dict) else {}


class UriResolver:
    """Reads what a URI names, inside ``folder`` only; refusals and failures are warnings."""

    _SCHEME = re.compile(r"^[A-Za-z][A-Za-z0-9+.-]*:")

    def __init__(self, folder: Path, warnings: list[str]) -> None:
        self.folder = folder
        self.warnings = warnings

    def read(self, uri: str, what: str) -> bytes | None:
        """The bytes ``uri`` names, or None (with a warning naming ``what`` and the URI)."""
        if uri.startswith("data:"):
            return self._data_uri(uri, what)
        shown = uri if len(uri) <= 240 else uri[:237] + "..."
        decoded = unquote(uri)
        if (
            self._SCHEME.match(decoded)
            or decoded.startswith(("/", "\\"))
            or Path(decoded).is_absolute()
        ):
            self.warnings.append(
                f"{what} '{shown}' is not a file next to the scene (absolute path or URL), not read"
            )
            return None
        try:
            base = self.folder.resolve()
            target = (base / decoded).resolve()
            target.relative_to(base)
        except (ValueError, OSError):
            self.warnings.append(f"{what} '{shown}' is outside the scene's folder, not read")
            return None
        try:
            return target.read_bytes()
        except OSError as exc:
            reason = "is missing" if isinstance(exc, FileNotFoundError) else "cannot be read"
            self.warnings.append(f"{what} '{decoded}' {reason}")
            return None

    def _data_uri(self, uri: str, what: str) -> bytes | None:
        head, sep, payload = uri.partition(",")
        try:
            if not sep:
                raise ValueError("no comma")
            if head.endswith(";base64"):
                return base64.b64decode(payload, validate=True)
            return unquote_to_bytes(payload)
        except (ValueError, binascii.Error):
            self.warnings.append(f"{what}: its data: URI ({head[:40]}) is malformed, not read")
            return None


class Buffers:
    """Buffer bytes by index, loaded on first use (a refused or missing one once warned)."""

    def __init__(self, doc: dict[str, Any], glb_bin: Blob | None, resolver: UriResolver) -> None:
        self.doc = doc
        self.glb_bin = glb_bin
        self.resolver = resolver
        self._cache: dict[int, Blob | None] = {}
        self._reasons: dict[int, str] = {}

    def get(self, index: Any) -> Blob:
        buffers = as_list(self.doc.get("buffers"))
        if (
            not is_int(index)
            or not 0 <= index < len(buffers)
            or not isinstance(buffers[index], dict)
        ):
            raise GltfDataError(f"a buffer view refers to buffer {index}, which does not exist")
        if index not in self._cache:
            self._cache[index] = self._load(index, buffers[index])
        data = self._cache[index]
        if data is None:
            raise BufferUnavailable(self._reasons[index])
        return data

    def _load(self, index: int, spec: dict[str, Any]) -> Blob | None:
        uri = spec.get("uri")
        if uri is None:
            if index == 0 and self.glb_bin is not None:
                return self.glb_bin
            self._reasons[index] = f"buffer {index} has no data (no uri and no GLB BIN chunk)"
            return None
        before = len(self.resolver.warnings)
        data = self.resolver.read(str(uri), f"buffer {index}")
        if data is None:
            added = self.resolver.warnings[before:]
            self._reasons[index] = added[-1] if added else f"buffer {index} cannot be read"
            return None
        return data


class Accessors:
    """Decodes accessors (dense and sparse) into numpy arrays, each validated first."""

    def __init__(self, doc: dict[str, Any], buffers: Buffers) -> None:
        self.doc = doc
        self.buffers = buffers
        self.accessors = as_list(doc.get("accessors"))
        self.views = as_list(doc.get("bufferViews"))
        self._decoded: dict[int, bytes] = {}  # EXT_meshopt_compression views, decoded once
        self.meshopt_required = "EXT_meshopt_compression" in as_list(doc.get("extensionsRequired"))

    # ---- what an accessor claims, checked ---------------------------------------------

    def spec(self, index: Any) -> dict[str, Any]:
        if not is_int(index) or not 0 <= index < len(self.accessors):
            raise GltfDataError(f"accessor {index} does not exist")
        acc = self.accessors[index]
        if not isinstance(acc, dict):
            raise GltfDataError(f"accessor {index} is not an object")
        return acc

    def layout(self, index: Any) -> tuple[int, np.dtype[Any], int]:
        """(count, component dtype, components per element) of a valid accessor."""
        acc = self.spec(index)
        count = acc.get("count")
        if not is_int(count) or count < 0 or count > MAX_COUNT:
            raise GltfDataError(f"accessor {index} has an impossible count ({count!r})")
        dtype = component_dtype(acc.get("componentType"))
        if dtype is None:
            raise GltfDataError(
                f"accessor {index} has an unknown componentType ({acc.get('componentType')!r})"
            )
        ncomp = type_components(acc.get("type"))
        if ncomp is None:
            raise GltfDataError(f"accessor {index} has an unknown type ({acc.get('type')!r})")
        return count, dtype, ncomp

    def count(self, index: Any) -> int:
        return self.layout(index)[0]

    def element_type(self, index: Any) -> str:
        return str(self.spec(index).get("type"))

    # ---- reading -------------------------------------------------------------------------

    def read(self, index: Any) -> np.ndarray:
        """(count, components) in the accessor's own component type (sparse applied)."""
        count, dtype, ncomp = self.layout(index)
        acc = self.spec(index)
        view = acc.get("bufferView")
        if view is None:
            data = np.zeros((count, ncomp), dtype)
        else:
            data = self._strided(
                f"accessor {index}", view, acc.get("byteOffset", 0), count, dtype, ncomp
            ).copy()
        sparse = acc.get("sparse")
        if sparse is not None:
            self._apply_sparse(index, data, sparse, dtype, ncomp)
        return data

    def read_float(self, index: Any) -> np.ndarray:
        """(count, components) float64, normalized integers mapped to [0, 1] or [-1, 1]."""
        raw = self.read(index)
        return to_float(raw, bool(self.spec(index).get("normalized", False)))

    def _strided(
        self, what: str, view_index: Any, offset: Any, count: int, dtype: np.dtype[Any], ncomp: int
    ) -> np.ndarray:
        """A read-only view of ``count`` elements, after checking they lie inside the view."""
        view, data, view_start, view_len = self._view(what, view_index)
        if not is_int(offset) or offset < 0:
            raise GltfDataError(f"{what} has an invalid byteOffset ({offset!r})")
        elem = dtype.itemsize * ncomp
        stride = view.get("byteStride")
        if stride is None:
            stride = elem
        elif not is_int(stride) or stride < elem or stride > 252 or stride % dtype.itemsize:
            # glTF asks for multiples of 4; only misalignment to the component size is refused.
            raise GltfDataError(
                f"{what} uses buffer view {view_index} with byteStride {stride!r}, which does "
                f"not fit its {elem}-byte elements"
            )
        if offset % dtype.itemsize:
            raise GltfDataError(f"{what} is not aligned to its component size")
        if count == 0:
            return np.zeros((0, ncomp), dtype)
        needed = offset + stride * (count - 1) + elem
        if needed > view_len:
            raise GltfDataError(f"{what} reads past the end of buffer view {view_index}")
        return np.ndarray(
            (count, ncomp),
            dtype,
            buffer=data,
            offset=view_start + offset,
            strides=(stride, dtype.itemsize),
        )

    def _view(self, what: str, view_index: Any) -> tuple[dict[str, Any], Blob, int, int]:
        if not is_int(view_index) or not 0 <= view_index < len(self.views):
            raise GltfDataError(f"{what} refers to buffer view {view_index}, which does not exist")
        view = self.views[view_index]
        if not isinstance(view, dict):
            raise GltfDataError(f"buffer view {view_index} is not an object")
        packed = as_dict(as_dict(view.get("extensions")).get("EXT_meshopt_compression"))
        if packed:
            decoded = self._meshopt(view_index, packed)
            if decoded is not None:
                return view, decoded, 0, len(decoded)
        start = view.get("byteOffset", 0)
        length = view.get("byteLength")
        if not is_int(start) or start < 0 or not is_int(length) or length < 0:
            raise GltfDataError(f"buffer view {view_index} has an invalid byteOffset or byteLength")
        data = self.buffers.get(view.get("buffer"))
        if start + length > len(data):
            raise GltfDataError(
                f"buffer view {view_index} reaches past the end of buffer {view.get('buffer')} "
                f"({start + length} bytes needed, {len(data)} there)"
            )
        return view, data, start, length

    def _meshopt(self, index: int, ext: dict[str, Any]) -> bytes | None:
        """An EXT_meshopt_compression view decoded by meshoptimizer (gltfpack's and
        glTF-Transform's compression), or None to read the view's own (fallback) data where
        the file does not require the extension and its compressed data cannot be decoded."""
        if index in self._decoded:
            return self._decoded[index]
        try:
            data = _meshopt_decode(self.buffers, ext)
        except (GltfDataError, BufferUnavailable, RuntimeError, ValueError, TypeError) as exc:
            if not self.meshopt_required:
                return None  # the uncompressed fallback serves
            raise GltfDataError(
                f"buffer view {index}: its meshopt-compressed data cannot be decoded ({exc})"
            ) from exc
        self._decoded[index] = data
        return data

    def view_bytes(self, view_index: Any, what: str) -> Blob:
        """The raw bytes of a buffer view (Draco payloads, embedded images)."""
        _, data, start, length = self._view(what, view_index)
        return data[start : start + length]

    def _apply_sparse(
        self, index: int, data: np.ndarray, sparse: Any, dtype: np.dtype[Any], ncomp: int
    ) -> None:
        what = f"accessor {index} (sparse)"
        if not isinstance(sparse, dict):
            raise GltfDataError(f"{what} is not an object")
        n = sparse.get("count")
        idx_spec = sparse.get("indices")
        val_spec = sparse.get("values")
        if not is_int(n) or n < 0 or n > len(data):
            raise GltfDataError(f"{what} has an impossible count ({n!r})")
        if not isinstance(idx_spec, dict) or not isinstance(val_spec, dict):
            raise GltfDataError(f"{what} lacks its indices or values")
        idx_dtype = component_dtype(idx_spec.get("componentType"))
        if idx_dtype is None or idx_dtype.kind != "u":
            raise GltfDataError(f"{what} has indices of an invalid componentType")
        where = self._strided(
            what, idx_spec.get("bufferView"), idx_spec.get("byteOffset", 0), n, idx_dtype, 1
        )[:, 0].astype(np.int64)
        values = self._strided(
            what, val_spec.get("bufferView"), val_spec.get("byteOffset", 0), n, dtype, ncomp
        )
        if n and int(where.max()) >= len(data):
            raise GltfDataError(f"{what} replaces elements past its count")
        data[where] = values


_MESHOPT_FILTERS = {"OCTAHEDRAL": "oct", "QUATERNION": "quat", "EXPONENTIAL": "exp"}


def _meshopt_decode(buffers: Buffers, ext: dict[str, Any]) -> bytes:
    """The bytes of one EXT_meshopt_compression view: ``count`` elements of ``byteStride``."""
    import meshoptimizer  # the library the levels of detail use (app.lod)

    fields = [ext.get("count"), ext.get("byteStride"), ext.get("byteOffset", 0)]
    fields.append(ext.get("byteLength"))
    if not all(is_int(v) and v >= 0 for v in fields):
        raise GltfDataError("invalid count, byteStride, byteOffset or byteLength")
    count, stride, offset, length = (int(v) for v in fields)
    mode = ext.get("mode")
    # meshopt packs a few times at best: a count far past its bytes is a broken or hostile file
    # (checked before anything is allocated, as the accessors are)
    if not 0 < stride <= 256 or count * stride > min(MAX_COUNT, 256 * (length + 256)):
        raise GltfDataError(f"impossible count ({count}) or byteStride ({stride})")
    source = buffers.get(ext.get("buffer"))
    if offset + length > len(source):
        raise GltfDataError("the compressed data reaches past the end of its buffer")
    payload = np.frombuffer(source, np.uint8, count=length, offset=offset)
    if mode == "ATTRIBUTES":
        out = meshoptimizer.decode_vertex_buffer(count, stride, payload)
        name = _MESHOPT_FILTERS.get(str(ext.get("filter", "NONE")))
        if name is not None:
            out = getattr(meshoptimizer, f"decode_filter_{name}")(out, count, stride)
    elif mode == "TRIANGLES":
        out = meshoptimizer.decode_index_buffer(count, stride, payload)
    elif mode == "INDICES":
        out = meshoptimizer.decode_index_sequence(count, stride, payload)
    else:
        raise GltfDataError(f"unknown mode {mode!r:.20}")
    data = np.ascontiguousarray(out).tobytes()[: count * stride]
    if len(data) != count * stride:
        raise GltfDataError("the decoded data is shorter than its count says")
    return data


def to_float(raw: np.ndarray, normalized: bool) -> np.ndarray:
    """float64; normalized integers per glTF: unsigned c / max, signed max(c / max, -1)."""
    with np.errstate(invalid="ignore", over="ignore"):  # NaN/Inf stay; Scene.sanitized repairs
        out = raw.astype(np.float64)
    if normalized and raw.dtype.kind in "iu":
        out /= float(np.iinfo(raw.dtype).max)
        if raw.dtype.kind == "i":
            np.maximum(out, -1.0, out=out)
    return out
