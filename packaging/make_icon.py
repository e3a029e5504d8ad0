"""Draw the application icon: a headset whose two lenses look into a furnished room.

    python packaging/make_icon.py            # writes assets/icons/vrpreview-{48,128,256}.png

Drawn at 1024 px and scaled down (Lanczos), so the small sizes are smooth; the same Pillow
gives the same bytes, and tests/test_packaging.py checks the committed files against it.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from PIL import Image, ImageDraw, ImageFilter

SIZES = (48, 128, 256)
ROOT = Path(__file__).resolve().parent.parent
OUT = ROOT / "assets" / "icons"
S = 1024  # drawing size

TILE_TOP = (38, 70, 112)
TILE_BOTTOM = (18, 34, 60)
BODY = (236, 239, 243)
BODY_SHADE = (196, 203, 212)
STRAP = (120, 132, 150)
WALL = (226, 208, 176)
WALL_SIDE = (200, 180, 146)
CEILING = (246, 240, 228)
FLOOR = (150, 92, 52)
RUG = (176, 40, 44)
PAINTING = (46, 96, 160)
FRAME = (196, 160, 72)


def _vertical_gradient(size: int, top: tuple[int, int, int], bottom: tuple[int, int, int]):
    grad = Image.new("RGB", (1, size))
    for y in range(size):
        t = y / (size - 1)
        grad.putpixel((0, y), tuple(round(a + (b - a) * t) for a, b in zip(top, bottom)))
    return grad.resize((size, size))


def _room(w: int, h: int) -> Image.Image:
    """One lens' view: a room corner in perspective, a rug and a painting on the back wall."""
    img = Image.new("RGB", (w, h), WALL)
    d = ImageDraw.Draw(img)
    # The back wall is the rectangle in the middle; the others run out to the lens' edge.
    bx0, by0, bx1, by1 = w * 0.28, h * 0.26, w * 0.78, h * 0.64
    d.polygon([(0, 0), (w, 0), (bx1, by0), (bx0, by0)], fill=CEILING)
    d.polygon([(0, 0), (bx0, by0), (bx0, by1), (0, h)], fill=WALL_SIDE)
    d.polygon([(0, h), (bx0, by1), (bx1, by1), (w, h)], fill=FLOOR)
    d.polygon(
        [(w * 0.18, h * 0.92), (w * 0.34, h * 0.72), (w * 0.74, h * 0.72), (w * 0.86, h * 0.92)],
        fill=RUG,
    )
    px0, py0, px1, py1 = w * 0.44, h * 0.34, w * 0.66, h * 0.50
    d.rectangle((px0 - w * 0.02, py0 - h * 0.02, px1 + w * 0.02, py1 + h * 0.02), fill=FRAME)
    d.rectangle((px0, py0, px1, py1), fill=PAINTING)
    d.ellipse((w * 0.56, h * 0.37, w * 0.62, h * 0.43), fill=(246, 214, 96))  # a sun
    return img


def draw(size: int = S) -> Image.Image:
    """The icon at ``size`` px (RGBA, transparent outside the rounded tile)."""
    icon = Image.new("RGBA", (S, S), (0, 0, 0, 0))
    tile_mask = Image.new("L", (S, S), 0)
    ImageDraw.Draw(tile_mask).rounded_rectangle((24, 24, S - 24, S - 24), radius=200, fill=255)
    icon.paste(_vertical_gradient(S, TILE_TOP, TILE_BOTTOM), (0, 0), tile_mask)

    d = ImageDraw.Draw(icon)
    # The strap behind the headset, then a soft shadow under the body.
    d.rounded_rectangle((70, 430, S - 70, 560), radius=60, fill=STRAP)
    shadow = Image.new("L", (S, S), 0)
    ImageDraw.Draw(shadow).rounded_rectangle((150, 330, S - 150, 760), radius=170, fill=150)
    shadow = shadow.filter(ImageFilter.GaussianBlur(28))
    icon.paste((8, 16, 30, 255), (0, 26), shadow)
    d.rounded_rectangle((150, 300, S - 150, 730), radius=170, fill=BODY)
    d.rounded_rectangle((150, 610, S - 150, 730), radius=120, fill=BODY_SHADE)
    d.rounded_rectangle((150, 300, S - 150, 680), radius=170, fill=BODY)
    d.pieslice((430, 600, 594, 800), 180, 360, fill=TILE_BOTTOM)  # the nose cut-out

    # Two lenses, each a circular window into the same room (left and right views shifted).
    r = 150
    for cx, shift in ((350, -18), (S - 350, 18)):
        box = (cx - r, 500 - r, cx + r, 500 + r)
        d.ellipse((box[0] - 22, box[1] - 22, box[2] + 22, box[3] + 22), fill=(40, 46, 58))
        view = _room(2 * r + 60, 2 * r).crop((30 + shift, 0, 30 + shift + 2 * r, 2 * r))
        lens = Image.new("L", (2 * r, 2 * r), 0)
        ImageDraw.Draw(lens).ellipse((0, 0, 2 * r - 1, 2 * r - 1), fill=255)
        icon.paste(view, box[:2], lens)
        # A glint on the glass.
        d.arc((box[0] + 34, box[1] + 34, box[2] - 34, box[3] - 34), 200, 250, fill=BODY, width=14)
    return icon if size == S else icon.resize((size, size), Image.Resampling.LANCZOS)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=OUT, help="folder for the PNG files")
    args = parser.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    big = draw()
    for size in SIZES:
        path = args.out / f"vrpreview-{size}.png"
        (big if size == S else big.resize((size, size), Image.Resampling.LANCZOS)).save(path)
        print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
