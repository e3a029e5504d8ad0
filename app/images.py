"""Texture images: header checks before decoding, downscaling at load, and RGBA8 out.

A scene file names its images; what they hold is not trusted. Pillow opens lazily, so the pixel
count is checked from the header before anything is decoded (a 1 KB PNG can claim 100000 x 100000
pixels), and images larger than ``scene.max_texture_px`` are reduced while decoding (JPEG's
``draft`` mode decodes at 1/2, 1/4 or 1/8 size directly), so a 12000 x 12000 photo never takes
gigabytes. Every failure is a warning for the caller to show and a missing texture, never an
exception: the material keeps its colour.
"""

from __future__ import annotations

import io
import warnings as pywarnings
from dataclasses import dataclass

import numpy as np
from PIL import Image

# Set explicitly rather than relying on Pillow's default (which changes between versions): a
# 16384 x 16384 texture, the largest a GPU takes, plus headroom. Anything larger is refused.
MAX_IMAGE_PIXELS = int(1.5 * 16384 * 16384)
Image.MAX_IMAGE_PIXELS = MAX_IMAGE_PIXELS


@dataclass(frozen=True)
class DecodedImage:
    """RGBA8 pixels (row 0 at the top) and a note when they were downscaled at load."""

    rgba: np.ndarray
    note: str | None = None


class ImageError(Exception):
    """An image that cannot become a texture; the message says why, for a warning."""


def image_size(data: bytes | memoryview) -> tuple[int, int] | None:
    """Width and height from the image header, or None when it is not a readable image."""
    try:
        with pywarnings.catch_warnings():
            pywarnings.simplefilter("ignore")
            with Image.open(io.BytesIO(data)) as im:
                return int(im.size[0]), int(im.size[1])
    except Exception:  # noqa: BLE001 - Pillow raises anything on damaged headers
        return None


def fitted_size(size: tuple[int, int], max_px: int) -> tuple[int, int]:
    """``size`` shrunk (never grown) so its longest side is at most ``max_px``."""
    w, h = size
    longest = max(w, h, 1)
    if longest <= max_px or max_px <= 0:
        return w, h
    scale = max_px / longest
    return max(1, round(w * scale)), max(1, round(h * scale))


def decode_image(data: bytes | memoryview, max_px: int) -> DecodedImage:
    """The image as RGBA8 no larger than ``max_px`` on its longest side.

    Raises :class:`ImageError` (with a reason fit for a warning) for anything undecodable or
    over :data:`MAX_IMAGE_PIXELS`.
    """
    Image.MAX_IMAGE_PIXELS = MAX_IMAGE_PIXELS  # someone else may have changed the global
    try:
        with pywarnings.catch_warnings():
            # Pillow warns (not raises) between 1x and 2x the limit: that is a refusal too.
            pywarnings.simplefilter("error", Image.DecompressionBombWarning)
            with Image.open(io.BytesIO(data)) as im:
                return _decode_open(im, max_px)
    except ImageError:
        raise
    except (Image.DecompressionBombError, Image.DecompressionBombWarning) as exc:
        raise ImageError(f"it is too large to decode safely ({exc})") from exc
    except Exception as exc:  # noqa: BLE001 - Pillow decodes lazily and raises anything
        detail = str(exc).strip() or type(exc).__name__
        raise ImageError(f"it could not be decoded ({detail[:200]})") from exc


def _decode_open(im: Image.Image, max_px: int) -> DecodedImage:
    w, h = im.size
    if w <= 0 or h <= 0:
        raise ImageError("it has no pixels")
    if w * h > MAX_IMAGE_PIXELS:
        raise ImageError(
            f"it is too large to decode safely ({w} x {h} pixels, "
            f"more than {MAX_IMAGE_PIXELS} pixels)"
        )
    target = fitted_size((w, h), max_px)
    note = None
    if target != (w, h):
        if im.format == "JPEG":
            im.draft("RGB", target)  # decode at a power-of-two reduction, at least `target`
        im = im.resize(target, Image.Resampling.BILINEAR, reducing_gap=2.0)
        note = f"downscaled from {w} x {h} to {target[0]} x {target[1]} (scene.max_texture_px)"
    else:
        im.load()
    return DecodedImage(image_to_rgba(im), note)


def image_to_rgba(image: Image.Image) -> np.ndarray:
    """HxWx4 uint8, row 0 = top; 16-bit and float images are scaled, not clipped.

    Palette images keep their transparency, grey+alpha and CMYK become RGBA like any other.
    """
    mode = image.mode
    if mode in ("I;16", "I;16B", "I;16L", "I", "F"):
        arr = np.asarray(image, np.float64)
        hi = 65535.0 if mode.startswith("I;16") else max(float(np.nanmax(arr)), 1.0)
        if mode == "F":
            hi = 1.0
        grey = (np.clip(np.nan_to_num(arr / hi), 0.0, 1.0) * 255.0 + 0.5).astype(np.uint8)
        rgba = np.stack([grey, grey, grey, np.full_like(grey, 255)], axis=2)
    elif mode == "CMYK":
        rgba = np.asarray(image.convert("RGB").convert("RGBA"), np.uint8)
    else:
        if mode == "P" and "transparency" in image.info:
            image = image.convert("PA")
        rgba = np.asarray(image.convert("RGBA"), np.uint8)
    return np.ascontiguousarray(rgba)


def rgba_channel_means(rgba: np.ndarray) -> tuple[float, float, float]:
    """Mean R, G, B in [0, 1] of an RGBA8 image, taken from a 64 x 64 thumbnail (cheap)."""
    small = Image.fromarray(np.ascontiguousarray(rgba[:, :, :3]), "RGB")
    small.thumbnail((64, 64))
    m = (np.asarray(small, np.float64) / 255.0).reshape(-1, 3).mean(axis=0)
    return float(m[0]), float(m[1]), float(m[2])
