"""Shared fixtures: the headless host, reference-image comparison, deterministic settings."""

from __future__ import annotations

import logging
import os
from pathlib import Path

import numpy as np
import pytest
from hypothesis import settings as hypothesis_settings
from PIL import Image

REFERENCES = Path(__file__).parent / "references"
FAILURES = Path(__file__).parent / "_failures"
SCENES = Path(
    os.environ.get("VRPREVIEW_SCENES", Path(__file__).resolve().parents[2] / "shared" / "scenes")
)


# The reference images assume Mesa's software rasterizer (llvmpipe): force it before any GL
# context exists, so a machine with a GPU (or another EGL vendor first in glvnd's list) renders
# the same pixels. ``pytest_sessionstart`` says once which renderer the session got.
SOFTWARE_GL = {
    "LIBGL_ALWAYS_SOFTWARE": "1",
    "GALLIUM_DRIVER": "llvmpipe",
    "__GLX_VENDOR_LIBRARY_NAME": "mesa",
}
MESA_EGL_VENDOR = Path("/usr/share/glvnd/egl_vendor.d/50_mesa.json")
os.environ.update(SOFTWARE_GL)
# The window's "auto" frame rate follows the display; tests that compare screenshots need
# fixed settings, so the window sees no display refresh (ui/gl_view.py: display_hz).
os.environ.setdefault("VRPREVIEW_DISPLAY_HZ", "0")
if MESA_EGL_VENDOR.exists():
    os.environ["__EGL_VENDOR_LIBRARY_FILENAMES"] = str(MESA_EGL_VENDOR)


# Property tests are deterministic too (the same examples on every run and in CI; no example
# database carried between runs).
hypothesis_settings.register_profile("deterministic", derandomize=True, database=None)
hypothesis_settings.load_profile("deterministic")


def pytest_sessionstart(session: pytest.Session) -> None:
    line = _gl_renderer_line()
    reporter = session.config.pluginmanager.get_plugin("terminalreporter")
    if reporter is not None:  # shown even under -q
        reporter.write_line(line)


def _gl_renderer_line() -> str:
    from render.context import GLUnavailableError, create_headless

    try:
        ctx = create_headless()
    except GLUnavailableError as exc:
        return f"OpenGL: none ({exc})"
    try:
        renderer = ctx.info.get("GL_RENDERER", "?")
    finally:
        ctx.release()
    if "llvmpipe" not in renderer and "softpipe" not in renderer:
        raise pytest.UsageError(
            f"tests need Mesa's software rasterizer for their reference images, got {renderer!r}"
        )
    return f"OpenGL: {renderer} (Mesa software rasterizer forced: LIBGL_ALWAYS_SOFTWARE=1)"


def pytest_configure(config: pytest.Config) -> None:
    # The Qt window needs a 4.3 core context; the format must be set before QApplication exists.
    from PyQt6.QtGui import QSurfaceFormat

    from ui.gl_view import default_format

    QSurfaceFormat.setDefaultFormat(default_format())


def pytest_addoption(parser: pytest.Parser) -> None:
    parser.addoption(
        "--regen-references",
        action="store_true",
        help="rewrite tests/references/*.png from the current renderer",
    )


@pytest.fixture(autouse=True)
def _data_dir(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """User files (screenshots, viewpoints, recordings, preferences) go to the test's tmp folder."""
    monkeypatch.setenv("VRPREVIEW_DATA", str(tmp_path / "data"))
    # The window's preferences (ui/prefs.py) too: each test starts as a first run.
    monkeypatch.setenv("VRPREVIEW_CONFIG", str(tmp_path / "config"))
    # Cached levels of detail (app/lod.py) too: a test sees its own builds.
    monkeypatch.setenv("VRPREVIEW_CACHE", str(tmp_path / "cache"))


@pytest.fixture(autouse=True)
def _no_logged_errors(caplog: pytest.LogCaptureFixture):
    """A test fails if anything logged an error (a render pass failing, say)."""
    caplog.set_level(logging.WARNING)
    yield
    errors = [
        r
        for r in caplog.get_records("call")
        if r.levelno >= logging.ERROR and not getattr(r, "expected", False)
    ]
    assert not errors, "errors were logged: " + "; ".join(r.getMessage() for r in errors)


@pytest.fixture
def compare_reference(request: pytest.FixtureRequest):
    """compare(name, image, max_mean, max_pixel_fraction): against tests/references/name.png.

    The tolerance is explicit per call: ``max_mean`` is the mean absolute difference (0-255) and
    ``max_frac`` the fraction of pixels allowed to differ by more than 16 levels. On a failure the
    actual image and a difference image go to tests/_failures/.
    """
    regen = request.config.getoption("--regen-references")

    def compare(
        name: str, image: np.ndarray, max_mean: float = 1.0, max_frac: float = 0.002
    ) -> None:
        ref_path = REFERENCES / f"{name}.png"
        if regen or not ref_path.exists():
            if not regen:
                pytest.fail(f"no reference {ref_path}; run pytest --regen-references")
            REFERENCES.mkdir(exist_ok=True)
            Image.fromarray(image).save(ref_path)
            return
        ref = np.asarray(Image.open(ref_path).convert("RGB"))
        assert ref.shape == image.shape, f"{name}: size {image.shape} != reference {ref.shape}"
        diff = np.abs(ref.astype(np.int16) - image.astype(np.int16))
        mean = float(diff.mean())
        frac = float((diff.max(axis=2) > 16).mean())
        if mean > max_mean or frac > max_frac:
            FAILURES.mkdir(exist_ok=True)
            Image.fromarray(image).save(FAILURES / f"{name}.actual.png")
            Image.fromarray(np.clip(diff * 4, 0, 255).astype(np.uint8)).save(
                FAILURES / f"{name}.diff.png"
            )
            pytest.fail(
                f"{name}: mean diff {mean:.2f} (max {max_mean}), {frac:.4f} of pixels "
                f"off by >16 (max {max_frac}); see {FAILURES}"
            )

    return compare


@pytest.fixture(scope="session")
def scenes_dir() -> Path:
    if not SCENES.is_dir():
        pytest.fail(
            f"third-party test scenes not found at {SCENES} (expected ../shared/scenes "
            "beside the checkout, or set VRPREVIEW_SCENES)"
        )
    return SCENES


@pytest.fixture(scope="module")
def edge_host():
    """A small host drawing a bright square on a dark wall (tests.test_governor.edge_scene),
    shadows off: sharp edges for the upscalers and the render scale."""
    from app.settings import Settings
    from render.offscreen import OffscreenHost
    from tests.test_governor import H, W, edge_scene

    s = Settings()
    s.set("render.shadows", "off")
    h = OffscreenHost(W, H, s)
    h.set_scene(edge_scene())
    h.set_text_image(None)
    yield h
    assert not h.renderer.errors
    h.close()
