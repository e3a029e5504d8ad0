"""The photon map as data: what photon tracing produces and the gather (CPU and GPU) reads.

A photon is stored where a light path meets a diffuse surface. It carries its flux (linear RGB,
in the renderer's light units: with ``render.brightness`` = 1 the indirect radiance leaving a
surface of diffuse colour rho is ``rho / pi * E`` with ``E = sum(power) / (pi r^2)`` over the
photons within r) and the direction it travelled, stored octahedron-encoded in 2x16 bits so the
GPU record is 32 bytes. Both gathers decode the same bits, so they count the same photons.

GPU record (std430, 32 bytes): ``vec3 position; uint direction; vec3 power; uint extra`` where
``extra`` is free for a structure's own use (the kd-tree keeps its split axis there).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

RECORD_BYTES = 32


def encode_directions(d: np.ndarray) -> np.ndarray:
    """Unit vectors (N, 3) to octahedral snorm 2x16 (as GLSL packSnorm2x16), uint32 (N,)."""
    d = np.asarray(d, np.float64).reshape(-1, 3)
    norm = np.abs(d).sum(axis=1)
    norm[norm <= 0] = 1.0
    p = d[:, :2] / norm[:, None]
    neg = d[:, 2] < 0
    if neg.any():
        x, y = p[neg, 0], p[neg, 1]
        p[neg, 0] = (1.0 - np.abs(y)) * np.where(x >= 0, 1.0, -1.0)
        p[neg, 1] = (1.0 - np.abs(x)) * np.where(y >= 0, 1.0, -1.0)
    q = np.round(np.clip(p, -1.0, 1.0) * 32767.0).astype(np.int64) & 0xFFFF
    return (q[:, 0] | (q[:, 1] << 16)).astype(np.uint32)


def decode_directions(packed: np.ndarray) -> np.ndarray:
    """Inverse of :func:`encode_directions` (as GLSL unpackSnorm2x16 + octahedral decode)."""
    u = np.asarray(packed, np.uint32).astype(np.int64)
    lo = (u & 0xFFFF).astype(np.int16).astype(np.float32)
    hi = (u >> 16).astype(np.int16).astype(np.float32)
    x = np.clip(lo / np.float32(32767.0), -1.0, 1.0)
    y = np.clip(hi / np.float32(32767.0), -1.0, 1.0)
    z = np.float32(1.0) - np.abs(x) - np.abs(y)
    t = np.clip(-z, 0.0, None)
    x = x + np.where(x >= 0, -t, t)
    y = y + np.where(y >= 0, -t, t)
    v = np.stack([x, y, z], axis=1).astype(np.float32)
    n = np.linalg.norm(v, axis=1, keepdims=True)
    n[n <= 0] = 1.0
    return (v / n).astype(np.float32)


@dataclass
class PhotonMap:
    """Photons at diffuse hits, in the order they were traced (deterministic for a seed)."""

    positions: np.ndarray  # (N, 3) float32, world metres
    power: np.ndarray  # (N, 3) float32, linear RGB flux (see the module docstring)
    direction_bits: np.ndarray  # (N,) uint32, travel direction, octahedral snorm 2x16
    emitted: int = 0  # photon paths started from the lights
    seed: int = 0
    notes: list[str] = field(default_factory=list)  # fallbacks taken while tracing
    # What is computed from these photons once and kept with them (app.irradiance_cache).
    derived: dict = field(default_factory=dict, repr=False, compare=False)

    def __post_init__(self) -> None:
        self.positions = np.ascontiguousarray(self.positions, np.float32).reshape(-1, 3)
        self.power = np.ascontiguousarray(self.power, np.float32).reshape(-1, 3)
        self.direction_bits = np.ascontiguousarray(self.direction_bits, np.uint32).reshape(-1)
        n = len(self.positions)
        if len(self.power) != n or len(self.direction_bits) != n:
            raise ValueError("photon arrays differ in length")

    def __len__(self) -> int:
        return int(self.positions.shape[0])

    @property
    def directions(self) -> np.ndarray:
        """Decoded travel directions (N, 3) float32, exactly what the GPU sees."""
        return decode_directions(self.direction_bits)

    def subset(self, index: np.ndarray) -> PhotonMap:
        return PhotonMap(
            self.positions[index],
            self.power[index],
            self.direction_bits[index],
            self.emitted,
            self.seed,
            list(self.notes),
        )

    def records(self, order: np.ndarray | None = None, extra: np.ndarray | None = None) -> bytes:
        """The GPU records (see the module docstring), optionally permuted by ``order``."""
        idx = np.arange(len(self)) if order is None else np.asarray(order, np.int64)
        rec = np.zeros((len(idx), 8), np.float32)
        rec[:, 0:3] = self.positions[idx]
        rec.view(np.uint32)[:, 3] = self.direction_bits[idx]
        rec[:, 4:7] = self.power[idx]
        if extra is not None:
            rec.view(np.uint32)[:, 7] = np.asarray(extra, np.uint32)
        return rec.tobytes()

    @staticmethod
    def empty() -> PhotonMap:
        return PhotonMap(np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0, np.uint32))


def merge(a: PhotonMap, b: PhotonMap) -> PhotonMap:
    """The photons of two maps traced apart (other seeds) for the same scene and lights, as one
    map of all their paths: each map's photon carries its light over its own paths, so its
    power is weighted by its map's share of the paths. A map of no paths adds nothing; the
    notes (the fallbacks the scene needed) are the first map's. Progressive photon refinement
    (``app.indirect``) grows a map this way."""
    total = a.emitted + b.emitted
    if total <= 0:
        return a
    wa, wb = a.emitted / total, b.emitted / total
    return PhotonMap(
        np.concatenate([a.positions, b.positions]),
        np.concatenate([a.power * np.float32(wa), b.power * np.float32(wb)]),
        np.concatenate([a.direction_bits, b.direction_bits]),
        total,
        a.seed,
        list(a.notes),
    )
