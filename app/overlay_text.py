"""The statistics text drawn in the view, rendered on the CPU into a small RGBA image.

Both hosts use it (the Qt widget and the headless host), and it is redrawn only when the text
changes (a few times a second), so the renderer just uploads a tiny texture.
"""

from __future__ import annotations

import functools

import numpy as np
from PIL import Image, ImageDraw, ImageFont


@functools.lru_cache(maxsize=1)
def _font() -> ImageFont.ImageFont | ImageFont.FreeTypeFont:
    try:
        return ImageFont.load_default(size=14)
    except TypeError:  # Pillow < 10.1 has no sized default font
        return ImageFont.load_default()


def text_image(lines: list[str], padding: int = 6) -> np.ndarray:
    """Lines of text, white on translucent black; (h, w, 4) uint8, row 0 at the top."""
    font = _font()
    probe = ImageDraw.Draw(Image.new("RGBA", (1, 1)))
    boxes = [probe.textbbox((0, 0), line or " ", font=font) for line in lines] or [(0, 0, 1, 1)]
    line_h = max(b[3] - b[1] for b in boxes) + 3
    # Pillow types the boxes as floats; its fonts measure whole pixels.
    width = int(max(b[2] for b in boxes)) + 2 * padding
    height = int(line_h) * max(1, len(lines)) + 2 * padding
    img = Image.new("RGBA", (width, height), (0, 0, 0, 150))
    draw = ImageDraw.Draw(img)
    for i, line in enumerate(lines):
        draw.text((padding, padding + i * line_h), line, font=font, fill=(255, 255, 255, 255))
    return np.asarray(img, np.uint8)


def with_status(lines: list[str], status: str | None) -> list[str]:
    """The statistics lines plus a status line such as the refinement's "refining 63%"
    (``app.refine.Refinement.status_line``; None: nothing to say)."""
    return [*lines, status] if status else list(lines)
