"""sRGB <-> linear light, written once (IEC 61966-2-1 piecewise curve).

Textures and authored colours are sRGB-encoded; the renderer, the photon tracer and the TCR
pyramid average and shade in linear light. Averaging sRGB values directly darkens every edge
(black/white becomes 128, which displays as ~22% light instead of 50%).
"""

from __future__ import annotations

import numpy as np


def srgb_to_linear(c: np.ndarray | float) -> np.ndarray:
    """sRGB-encoded values (clipped to [0, 1]) to linear light, as float64."""
    c = np.clip(np.asarray(c, np.float64), 0.0, 1.0)
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


def linear_to_srgb(c: np.ndarray) -> np.ndarray:
    """Linear light to sRGB encoding, computed in the input's float type (float32 stays float32).

    Values are not clipped: clip the input to [0, 1] first where that is wanted.
    """
    c = np.asarray(c)
    if not np.issubdtype(c.dtype, np.floating):
        c = c.astype(np.float64)
    return np.where(c <= 0.0031308, c * 12.92, 1.055 * np.power(c, 1.0 / 2.4) - 0.055)


#: Linear value of each 8-bit sRGB code (float64; index with a uint8 array).
SRGB8_TO_LINEAR: np.ndarray = srgb_to_linear(np.arange(256) / 255.0)
SRGB8_TO_LINEAR.flags.writeable = False


def srgb8_to_linear(r: int, g: int, b: int, a: float = 1.0) -> tuple[float, float, float, float]:
    """An sRGB 0..255 colour as linear RGBA floats (alpha passes through).

    Scalar float arithmetic on purpose: numpy's vectorised ``**`` may differ from it in the last
    bit, and the procedural scenes' reference images were made with this one.
    """

    def lin(code: int) -> float:
        v = code / 255.0
        return v / 12.92 if v <= 0.04045 else ((v + 0.055) / 1.055) ** 2.4

    return (lin(r), lin(g), lin(b), a)
