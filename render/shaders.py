"""The one shader loader: GLSL files from ``render/shaders`` as package data.

It checks ``#version``, injects ``#define``s after it (the program's own and, from
``ShaderLibrary``, the shared constants of ``render.constants.SHADER_DEFINES``), resolves
``#include "file"`` (each file once per program), and keeps a map from combined-source line to
(file, line) so a compile error names the file and line the author wrote. Mesa's ``#line``
handling has been unreliable, so the map is ours rather than the driver's. Programs are cached
per context.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from importlib import resources

import moderngl

from render.constants import SHADER_DEFINES

_INCLUDE = re.compile(r'^\s*#\s*include\s+"([^"]+)"\s*$')
_VERSION = re.compile(r"^\s*#\s*version\s+(\d+)")
# Mesa: "0:12(5): error: ..."; NVIDIA: "0(12) : error ..."; both carry the line number.
_LOG_LINE = re.compile(r"^\s*\d+\s*[:(]\s*(\d+)\s*\)?(?:\((\d+)\))?\s*:?")
MIN_VERSION = 430


class ShaderError(RuntimeError):
    """A shader that cannot be read or compiled; the message names file and line."""


@dataclass(frozen=True)
class Source:
    text: str
    lines: tuple[tuple[str, int], ...]  # (file, line) for each line of text

    def where(self, line: int) -> str:
        if 1 <= line <= len(self.lines):
            f, n = self.lines[line - 1]
            return f"{f}:{n}"
        return f"line {line}"


def read_file(name: str) -> str:
    try:
        return (
            resources.files("render").joinpath("shaders").joinpath(name).read_text(encoding="utf-8")
        )
    except (FileNotFoundError, OSError) as exc:
        raise ShaderError(f"shader file not found: render/shaders/{name}") from exc


def assemble(name: str, defines: dict[str, object] | None = None, reader=None) -> Source:
    """Resolve includes and inject defines; return the text and its line map."""
    reader = reader or read_file
    out: list[str] = []
    where: list[tuple[str, int]] = []
    seen: set[str] = set()

    def emit(file: str, stack: tuple[str, ...]) -> None:
        if file in stack:
            raise ShaderError(f"{stack[-1]}: #include cycle through {file}")
        if file in seen:
            return
        seen.add(file)
        for n, line in enumerate(reader(file).splitlines(), start=1):
            m = _INCLUDE.match(line)
            if m:
                try:
                    emit(m.group(1), (*stack, file))
                except ShaderError as exc:
                    if "not found" in str(exc):
                        raise ShaderError(f"{file}:{n}: cannot include '{m.group(1)}'") from exc
                    raise
                continue
            if _VERSION.match(line) and stack:
                raise ShaderError(f"{file}:{n}: #version is allowed only in the top file")
            out.append(line)
            where.append((file, n))

    emit(name, ())
    first = next((i for i, line in enumerate(out) if line.strip()), None)
    m = _VERSION.match(out[first]) if first is not None else None
    if first is None or m is None:
        raise ShaderError(f"{name}:1: the first line must be '#version {MIN_VERSION}' or later")
    if int(m.group(1)) < MIN_VERSION:
        raise ShaderError(
            f"{name}:{where[first][1]}: #version {m.group(1)} is older than "
            f"{MIN_VERSION} (compute shaders and SSBOs need 4.3)"
        )
    injected = [
        f"#define {k} {'' if v is True else v}".rstrip()
        for k, v in sorted((defines or {}).items())
        if v is not False and v is not None
    ]
    out[first + 1 : first + 1] = injected
    where[first + 1 : first + 1] = [("<defines>", i + 1) for i in range(len(injected))]
    return Source("\n".join(out) + "\n", tuple(where))


def explain(log: str, sources: dict[str, Source]) -> str:
    """Rewrite a driver log's line numbers as file:line of the stage that failed."""
    lines = []
    src = next(iter(sources.values())) if len(sources) == 1 else None
    for raw in log.splitlines():
        m = _LOG_LINE.match(raw)
        if m and src is not None:
            col = f" (column {m.group(2)})" if m.group(2) else ""
            lines.append(f"{src.where(int(m.group(1)))}{col}: {raw[m.end() :].strip()}")
        else:
            lines.append(raw)
    return "\n".join(lines)


def with_constants(defines: dict[str, object] | None) -> dict[str, object]:
    """A program's defines plus the shared constants (which a program may not redefine)."""
    own = dict(defines or {})
    clash = sorted(set(own) & set(SHADER_DEFINES))
    if clash:
        names = ", ".join(clash)
        raise ShaderError(f"{names}: shared constants (render/constants.py), not variants")
    return {**SHADER_DEFINES, **own}


class ShaderLibrary:
    """Compiles and caches programs for one moderngl context (with the shared constants)."""

    def __init__(self, ctx: moderngl.Context) -> None:
        self.ctx = ctx
        self._cache: dict[tuple, moderngl.Program | moderngl.ComputeShader] = {}
        # Defines every program that names them gets besides its own (a renderer-wide variant,
        # e.g. the shadow filter; a program of another value is another program). A program
        # whose source does not name one is the same program at any value of it, so it is
        # neither rebuilt nor re-keyed when the variant changes (a shadow mode the governor
        # turns to recompiles the lighting, not the G-buffer's material variants).
        self.variant: dict[str, object] = {}
        # (files, define) -> whether those files (one program's stages) name the define
        self._named: dict[tuple[tuple[str, ...], str], bool] = {}

    def __len__(self) -> int:
        """Programs compiled so far."""
        return len(self._cache)

    def _variant_for(self, *files: str) -> dict[str, object]:
        """The renderer-wide defines that ``files`` (one program's stages) name."""
        out: dict[str, object] = {}
        for k, v in self.variant.items():
            named = self._named.get((files, k))
            if named is None:
                text = "\n".join(assemble(f).text for f in files)
                named = self._named[(files, k)] = bool(re.search(rf"\b{re.escape(k)}\b", text))
            if named:
                out[k] = v
        return out

    def program(
        self, vertex: str, fragment: str, defines: dict[str, object] | None = None
    ) -> moderngl.Program:
        defines = {**self._variant_for(vertex, fragment), **(defines or {})}
        key = ("program", vertex, fragment, tuple(sorted(defines.items())))
        if key not in self._cache:
            vs = assemble(vertex, with_constants(defines))
            fs = assemble(fragment, with_constants(defines))
            try:
                self._cache[key] = self.ctx.program(vertex_shader=vs.text, fragment_shader=fs.text)
            except moderngl.Error as exc:
                text = str(exc)
                # moderngl heads each stage's log with its name; map lines through that stage.
                for stage, name, src in (
                    ("fragment_shader", fragment, fs),
                    ("vertex_shader", vertex, vs),
                ):
                    if f"{stage}\n===" in text:
                        log = text.split("=\n", 1)[-1]
                        raise ShaderError(
                            f"{name} failed to compile:\n{explain(log, {name: src})}"
                        ) from exc
                raise ShaderError(f"linking {vertex} + {fragment} failed:\n{text}") from exc
        return self._cache[key]  # type: ignore[return-value]

    def compute(
        self, name: str, defines: dict[str, object] | None = None
    ) -> moderngl.ComputeShader:
        defines = {**self._variant_for(name), **(defines or {})}
        key = ("compute", name, tuple(sorted(defines.items())))
        if key not in self._cache:
            src = assemble(name, with_constants(defines))
            try:
                self._cache[key] = self.ctx.compute_shader(src.text)
            except moderngl.Error as exc:
                raise ShaderError(
                    f"{name} failed to compile:\n{explain(str(exc), {name: src})}"
                ) from exc
        return self._cache[key]  # type: ignore[return-value]

    def release(self) -> None:
        for obj in self._cache.values():
            obj.release()
        self._cache.clear()
