"""The GPU photon gather (render.photon_gather) against the CPU reference (app.lab.photon_ref).

Every variant must give the reference's E within 1e-3 relative. Float32 on the GPU against
float64 on the CPU can only disagree for a photon at distance ~r or with dot(N, dir) ~ 0, so
the data sets drop photons that sit on such an edge for any query point (``_robust``): what
is compared is then the algorithm, not the last bit of a rounding.
"""

from __future__ import annotations

import math

import moderngl
import numpy as np
import pytest
from scipy.spatial import cKDTree

from app.hashgrid import HashGrid
from app.lab.photon_ref import estimate_knn, estimate_radius
from app.photon_map import PhotonMap, encode_directions
from render.context import create_headless
from render.photon_gather import (
    NO_WINNER,
    STRUCTURE_OF,
    VARIANTS,
    GpuPhotonMap,
    PhotonGather,
)
from render.shaders import ShaderLibrary

R = 0.1
K = 16
GRID_VARIANTS = ("radius", "heap", "shared")  # the ones that read a cell-r grid


@pytest.fixture(scope="module")
def gl():
    """One headless context for the module, current while its tests run."""
    ctx = create_headless()
    with ctx:
        shaders = ShaderLibrary(ctx)
        gather = PhotonGather(ctx, shaders)
        yield ctx, gather
        gather.release()
        shaders.release()
    ctx.release()


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _robust(
    photons: PhotonMap, points: np.ndarray, normals: np.ndarray, r: float, eps: float = 1e-4
) -> PhotonMap:
    """``photons`` without those at distance ~r from a point or with dot(N, dir) ~ 0 for a
    point within r (valid points only)."""
    ok = np.isfinite(points).all(axis=1) & np.isfinite(normals).all(axis=1)
    pts, nrm = np.asarray(points, np.float64)[ok], np.asarray(normals, np.float64)[ok]
    if len(photons) == 0 or len(pts) == 0:
        return photons
    pos = photons.positions.astype(np.float64)
    pairs = cKDTree(pts).sparse_distance_matrix(cKDTree(pos), r * (1 + eps), output_type="ndarray")
    i, j = pairs["i"], pairs["j"]
    d2 = ((pts[i] - pos[j]) ** 2).sum(axis=1)
    facing = (nrm[i] * photons.directions.astype(np.float64)[j]).sum(axis=1)
    bad = (np.abs(d2 - r * r) < eps * r * r) | ((d2 < r * r) & (np.abs(facing) < eps))
    keep = np.ones(len(photons), bool)
    keep[j[bad]] = False
    return photons.subset(np.flatnonzero(keep))


def _photons(rng: np.random.Generator, n: int, lo=0.0, hi=1.0) -> PhotonMap:
    """Photons spread in a box and on two planes inside it, random directions and powers."""
    pos = rng.uniform(lo, hi, (n, 3))
    third = n // 3
    pos[:third, 1] = 0.25  # a floor
    pos[third : 2 * third, 2] = 0.6  # a wall
    dirs = _unit(rng.normal(size=(n, 3)))
    power = rng.uniform(0.2, 1.0, (n, 3)) * np.array([1.0, 0.5, 2.0])
    return PhotonMap(pos, power, encode_directions(dirs))


def _points(rng: np.random.Generator, m: int) -> tuple[np.ndarray, np.ndarray]:
    pts = rng.uniform(0.0, 1.0, (m, 3))
    pts[: m // 4, 1] = 0.25
    nrm = _unit(rng.normal(size=(m, 3)))
    return pts.astype(np.float32), nrm.astype(np.float32)


@pytest.fixture(scope="module")
def data():
    rng = np.random.default_rng(7)
    pts, nrm = _points(rng, 3000)
    photons = _robust(_photons(rng, 12000), pts, nrm, R)
    return photons, pts, nrm


def _close(gpu: np.ndarray, ref: np.ndarray) -> None:
    scale = float(np.abs(ref).mean()) or 1.0
    bad = ~np.isclose(gpu, ref, rtol=1e-3, atol=1e-6 * scale)
    assert not bad.any(), (
        f"{int(bad.any(axis=1).sum())} of {len(ref)} points differ, e.g. "
        f"{gpu[bad.any(axis=1)][:3]} vs {ref[bad.any(axis=1)][:3]}"
    )


def _knn_brute(
    photons: PhotonMap, pts: np.ndarray, nrm: np.ndarray, r: float, k: int
) -> tuple[np.ndarray, np.ndarray]:
    """The k-nearest estimate by a full sort per point, and which points are unambiguous (the
    k-th and (k+1)-th counted distances not within rounding of each other)."""
    pos = photons.positions.astype(np.float64)
    dirs = photons.directions.astype(np.float64)
    power = photons.power.astype(np.float64)
    out = np.zeros((len(pts), 3))
    clear = np.ones(len(pts), bool)
    for i, (p, n) in enumerate(zip(pts.astype(np.float64), nrm.astype(np.float64))):
        d2 = ((pos - p) ** 2).sum(axis=1)
        idx = np.flatnonzero((d2 < r * r) & (dirs @ n < 0.0))
        idx = idx[np.argsort(d2[idx], kind="stable")]
        if len(idx) >= k and d2[idx[k - 1]] > 0.0:
            out[i] = power[idx[:k]].sum(axis=0) / (math.pi * d2[idx[k - 1]])
            if len(idx) > k and d2[idx[k]] - d2[idx[k - 1]] < 1e-5 * r * r:
                clear[i] = False
        else:
            out[i] = power[idx].sum(axis=0) / (math.pi * r * r)
    return out, clear


# -- the estimate at points ----------------------------------------------------------------------


@pytest.mark.parametrize("variant", VARIANTS)
def test_variant_matches_reference(gl, data, variant):
    ctx, gather = gl
    photons, pts, nrm = data
    gmap = GpuPhotonMap(ctx, photons, R, STRUCTURE_OF[variant])
    try:
        gpu = gather.gather_points(gmap, pts, nrm, variant, k=K)
    finally:
        gmap.release()
    if "heap" in variant:
        ref = estimate_knn(photons, pts, nrm, R, K)
    else:
        ref = estimate_radius(photons, pts, nrm, R)
    assert (ref > 0).any(axis=1).mean() > 0.9  # the points do see photons
    _close(gpu, ref)


@pytest.mark.parametrize("variant", ["heap", "kdtree-heap"])
@pytest.mark.parametrize("k", [1, 5, 64])
def test_heap_equals_full_sort(gl, data, variant, k):
    ctx, gather = gl
    photons, pts, nrm = data
    pts, nrm = pts[:600], nrm[:600]
    gmap = GpuPhotonMap(ctx, photons, R, STRUCTURE_OF[variant])
    try:
        gpu = gather.gather_points(gmap, pts, nrm, variant, k=k)
    finally:
        gmap.release()
    ref, clear = _knn_brute(photons, pts, nrm, R, k)
    assert clear.mean() > 0.95
    _close(gpu[clear], ref[clear])
    # The heap shrinks the radius: it differs from the plain radius estimate where it filled.
    if k == 5:
        assert not np.allclose(ref, estimate_radius(photons, pts, nrm, R), rtol=1e-3)


def test_heap_full_at_distance_zero_falls_back(gl):
    """k photons exactly at P (r_k = 0): all counted photons over pi r^2, like the reference."""
    ctx, gather = gl
    p = np.array([[0.5, 0.5, 0.5]], np.float32)
    n = np.array([[0.0, 0.0, 1.0]], np.float32)
    pos = np.array([[0.5, 0.5, 0.5]] * 3 + [[0.52, 0.5, 0.5], [0.5, 0.45, 0.5]])
    dirs = np.tile([0.0, 0.0, -1.0], (5, 1))
    photons = PhotonMap(
        pos, np.arange(1, 16, dtype=np.float64).reshape(5, 3), encode_directions(dirs)
    )
    ref = estimate_knn(photons, p, n, R, 3)
    for variant in ("heap", "kdtree-heap"):
        gmap = GpuPhotonMap(ctx, photons, R, STRUCTURE_OF[variant])
        try:
            gpu = gather.gather_points(gmap, p, n, variant, k=3)
        finally:
            gmap.release()
        _close(gpu, ref)


@pytest.mark.parametrize("variant", VARIANTS)
def test_no_photons_and_one_photon(gl, variant):
    ctx, gather = gl
    pts = np.array(
        [[0.5, 0.5, 0.5], [0.55, 0.5, 0.5], [0.7, 0.5, 0.5], [0.5, 0.5, 0.52]], np.float32
    )
    nrm = np.array([[0, 0, 1], [0, 0, 1], [0, 0, 1], [0, 0, -1]], np.float32)
    gmap = GpuPhotonMap(ctx, PhotonMap.empty(), R, STRUCTURE_OF[variant])
    try:
        assert gmap.photon_count == 0
        assert not gather.gather_points(gmap, pts, nrm, variant, k=K).any()
    finally:
        gmap.release()
    one = PhotonMap(
        np.array([[0.5, 0.5, 0.5]]),
        np.array([[1.0, 2.0, 3.0]]),
        encode_directions(np.array([[0.0, 0.0, -1.0]])),
    )
    gmap = GpuPhotonMap(ctx, one, R, STRUCTURE_OF[variant])
    try:
        gpu = gather.gather_points(gmap, pts, nrm, variant, k=K)
    finally:
        gmap.release()
    e = np.array([1.0, 2.0, 3.0]) / (math.pi * R * R)
    # Within r and arriving against N: counts; 0.2 away: outside r; facing the other way: not.
    np.testing.assert_allclose(gpu, [e, e, [0, 0, 0], [0, 0, 0]], rtol=1e-5)


@pytest.mark.parametrize("variant", VARIANTS)
def test_points_outside_and_not_finite(gl, data, variant):
    ctx, gather = gl
    photons, _, _ = data
    inf, nan = np.inf, np.nan
    pts = np.array(
        [
            [5.0, 0.5, 0.5],
            [-3.0, -3.0, -3.0],
            [1e30, 0.5, 0.5],
            [-1e30, 1e30, 0.0],
            [nan, 0.5, 0.5],
            [0.5, inf, 0.5],
            [0.5, 0.5, 0.5],
            [0.5, 0.25, 0.5],
            [1.0 + R * 0.999, 0.5, 0.5],
        ],
        np.float32,
    )
    nrm = np.tile(np.array([0.0, 0.0, 1.0], np.float32), (len(pts), 1))
    nrm[6] = [nan, 0.0, 1.0]
    nrm[7] = [0.0, -inf, 0.0]
    gmap = GpuPhotonMap(ctx, photons, R, STRUCTURE_OF[variant])
    try:
        gpu = gather.gather_points(gmap, pts, nrm, variant, k=K)
    finally:
        gmap.release()
    assert np.isfinite(gpu).all()
    assert not gpu[:8].any()
    ref = (
        estimate_knn(photons, pts, nrm, R, K)
        if "heap" in variant
        else estimate_radius(photons, pts, nrm, R)
    )
    _close(gpu, ref)  # the last point, just outside the photons' box, still sees some


def test_radius_half_equals_radius(gl, data):
    ctx, gather = gl
    photons, pts, nrm = data
    full = GpuPhotonMap(ctx, photons, R, "grid")
    half = GpuPhotonMap(ctx, photons, R, "grid-half")
    try:
        assert (full.reach, half.reach) == (1, 2)
        a = gather.gather_points(full, pts, nrm, "radius")
        b = gather.gather_points(half, pts, nrm, "radius-half")
        c = gather.gather_points(half, pts, nrm, "shared")  # Algorithm 1 on the r/2 grid
    finally:
        full.release()
        half.release()
    np.testing.assert_allclose(b, a, rtol=1e-5, atol=1e-6 * a.mean())
    np.testing.assert_allclose(c, a, rtol=1e-5, atol=1e-6 * a.mean())


def _clustered(
    rng: np.random.Generator, grid: HashGrid, groups: int
) -> tuple[np.ndarray, np.ndarray]:
    """``groups`` runs of 64 points, each run inside one grid cell."""
    cells = rng.integers(grid.reach + 1, np.array(grid.dims) - grid.reach - 1, (groups, 3))
    inner = rng.uniform(0.05, 0.95, (groups, 64, 3))
    pts = grid.origin + (cells[:, None, :] + inner) * grid.cell
    nrm = _unit(rng.normal(size=(groups, 64, 3)))
    return pts.reshape(-1, 3).astype(np.float32), nrm.reshape(-1, 3).astype(np.float32)


def test_shared_equals_radius_clustered_and_mixed(gl, data):
    ctx, gather = gl
    rng = np.random.default_rng(11)
    photons, mixed_pts, mixed_nrm = data
    grid = HashGrid.build(photons.positions, R)
    pts, nrm = _clustered(rng, grid, 24)
    c = grid.hash(grid.cell_coords(pts)).reshape(-1, 64)
    assert (c == c[:, :1]).all()  # every group of 64 in one cell: the shared-memory path
    # A clustered group with invalid points (they still help load) and a ragged tail.
    pts[64:80] = np.nan
    pts = np.concatenate([pts, mixed_pts[:1000], pts[:37]])
    nrm = np.concatenate([nrm, mixed_nrm[:1000], nrm[:37]])
    photons = _robust(photons, pts, nrm, R)
    gmap = GpuPhotonMap(ctx, photons, R, "grid")
    try:
        shared = gather.gather_points(gmap, pts, nrm, "shared")
        radius = gather.gather_points(gmap, pts, nrm, "radius")
        heap = gather.gather_points(gmap, pts, nrm, "heap", k=K)
    finally:
        gmap.release()
    np.testing.assert_allclose(shared, radius, rtol=1e-5, atol=1e-6 * radius.mean())
    assert not shared[64:80].any()
    _close(shared, estimate_radius(photons, pts, nrm, R))
    _close(heap, estimate_knn(photons, pts, nrm, R, K))


@pytest.mark.parametrize("variant", ["radius", "radius-half", "shared", "kdtree"])
def test_counters_equal_numpy(gl, data, variant):
    ctx, gather = gl
    photons, pts, nrm = data
    pts = pts.copy()
    pts[:5] = [[9.0, 9.0, 9.0]] * 5  # outside: counted as points, nothing visited
    gmap = GpuPhotonMap(ctx, photons, R, STRUCTURE_OF[variant])
    try:
        gather.reset_counters()
        gather.gather_points(gmap, pts, nrm, variant, count=True)
        gather.gather_points(gmap, pts[:100], nrm[:100], variant)  # not counted
        got = gather.counters()
    finally:
        gmap.release()
    assert got["gathered"] == len(pts) and got["reused"] == 0
    if gmap.grid is not None:
        visited, within = gmap.grid.visit_stats(pts)
        assert got["visited"] == int(visited.sum())
    else:  # the kd-tree visits every photon within r, and fewer than all
        d2 = ((pts[:, None, :].astype(np.float64) - photons.positions[None]) ** 2).sum(axis=2)
        within = (d2 < R * R).sum(axis=1)
        assert int(within.sum()) < got["visited"] < len(photons) * len(pts) / 10
    assert got["within"] == int(within.sum())


def test_bad_arguments(gl, data):
    ctx, gather = gl
    photons, pts, nrm = data
    with pytest.raises(ValueError):
        GpuPhotonMap(ctx, photons, 0.0)
    with pytest.raises(ValueError):
        GpuPhotonMap(ctx, photons, R, "octree")
    gmap = GpuPhotonMap(ctx, photons, R, "grid")
    try:
        with pytest.raises(ValueError):
            gather.gather_points(gmap, pts, nrm, "kdtree")
        with pytest.raises(ValueError):
            gather.gather_points(gmap, pts, nrm, "radius-half")
        with pytest.raises(ValueError):
            gather.gather_points(gmap, pts, nrm, "heap", k=65)
        with pytest.raises(ValueError):
            gather.gather_points(gmap, pts, nrm, "nearest")
        assert gather.gather_points(gmap, pts[:0], nrm[:0]).shape == (0, 3)
    finally:
        gmap.release()


# -- the G-buffer entry --------------------------------------------------------------------------


def _perspective(fov_deg: float, aspect: float, near: float, far: float) -> np.ndarray:
    f = 1.0 / math.tan(math.radians(fov_deg) / 2.0)
    return np.array(
        [
            [f / aspect, 0, 0, 0],
            [0, f, 0, 0],
            [0, 0, (far + near) / (near - far), 2 * far * near / (near - far)],
            [0, 0, -1, 0],
        ],
        np.float64,
    )


class GBuffer:
    """A synthetic eye: a camera at (0.5, 0.55, 1.6) looking down -z at a floor (y = 0.25) and a
    back wall (z = 0.6, |x - 0.5| < 0.35); elsewhere background. Depth goes in an R32F texture
    (the entry reads only .r) so the test knows exactly what the GPU reconstructs."""

    def __init__(
        self,
        ctx: moderngl.Context,
        w: int,
        h: int,
        eye=(0.5, 0.55, 1.6),
        wall_z: float = 0.6,
        fov: float = 50.0,
    ) -> None:
        self.size = (w, h)
        proj = _perspective(fov, w / h, 0.1, 10.0)
        view = np.eye(4)
        view[:3, 3] = -np.asarray(eye)
        vp = proj @ view
        self.inv_vp = np.linalg.inv(vp)
        ys, xs = np.mgrid[0:h, 0:w]  # row 0 = bottom (GL texture rows)
        ndc = np.stack([(xs + 0.5) / w * 2 - 1, (ys + 0.5) / h * 2 - 1], axis=-1)
        far = self._unproject(ndc, np.ones((h, w)))
        o = np.asarray(eye, np.float64)
        d = far - o
        t_floor = np.where(d[..., 1] < 0, (0.25 - o[1]) / np.minimum(d[..., 1], -1e-12), np.inf)
        t_wall = np.where(d[..., 2] < 0, (wall_z - o[2]) / np.minimum(d[..., 2], -1e-12), np.inf)
        x_wall = o[0] + t_wall * d[..., 0]
        y_wall = o[1] + t_wall * d[..., 1]
        t_wall = np.where((np.abs(x_wall - 0.5) < 0.35) & (y_wall > 0.25), t_wall, np.inf)
        t = np.minimum(t_floor, t_wall)
        hit = np.isfinite(t)
        world = o + np.where(hit, t, 1.0)[..., None] * d
        clip = np.concatenate([world, np.ones((h, w, 1))], axis=-1) @ vp.T
        z = clip[..., 2] / clip[..., 3] * 0.5 + 0.5
        hit &= z < 0.999  # beyond the far plane is background too
        depth = np.where(hit, z, 1.0).astype(np.float32)
        normal = np.where((t_wall <= t_floor)[..., None], [0.0, 0.0, 1.0], [0.0, 1.0, 0.0])
        normal = normal + np.random.default_rng(3).normal(0, 0.2, normal.shape)  # bumpy
        normal = normal.astype(np.float16)
        self.hit = hit
        # What the GPU computes: P from the float32 depth, N = the half normal, normalised.
        self.points = self._unproject(ndc, depth.astype(np.float64) * 2 - 1)
        self.normals = _unit(normal.astype(np.float64))
        self.depth = ctx.texture((w, h), 1, depth.tobytes(), dtype="f4")
        rgba = np.concatenate([normal, np.full((h, w, 1), 0.5, np.float16)], axis=-1)
        self.normal = ctx.texture((w, h), 4, rgba.tobytes(), dtype="f2")
        for tex in (self.depth, self.normal):
            tex.filter = (moderngl.NEAREST, moderngl.NEAREST)

    def _unproject(self, ndc: np.ndarray, z: np.ndarray) -> np.ndarray:
        v = np.concatenate([ndc, z[..., None], np.ones(z.shape + (1,))], axis=-1) @ self.inv_vp.T
        return v[..., :3] / v[..., 3:]

    def query(self) -> tuple[np.ndarray, np.ndarray]:
        """Points and normals of the hit pixels, row-major from the bottom row."""
        return self.points[self.hit], self.normals[self.hit]

    def release(self) -> None:
        self.depth.release()
        self.normal.release()


def _out_texture(
    ctx: moderngl.Context, size: tuple[int, int], fill: float = -7.0
) -> moderngl.Texture:
    tex = ctx.texture(
        size, 4, np.full(size[0] * size[1] * 4, fill, np.float32).tobytes(), dtype="f4"
    )
    tex.filter = (moderngl.NEAREST, moderngl.NEAREST)
    return tex


def _read(tex: moderngl.Texture) -> np.ndarray:
    return np.frombuffer(tex.read(), np.float32).reshape(tex.size[1], tex.size[0], 4).copy()


@pytest.fixture(scope="module")
def eye(gl):
    ctx, _ = gl
    g = GBuffer(ctx, 60, 52)  # not a multiple of 8: the last groups straddle the edge
    yield g
    g.release()


@pytest.fixture(scope="module")
def eye_photons(eye):
    rng = np.random.default_rng(5)
    photons = _photons(rng, 9000)
    return _robust(photons, *eye.query(), R)


def _gather_image(gl, gmap, variant, eye, out_size=None, **kw) -> np.ndarray:
    ctx, gather = gl
    out = _out_texture(ctx, out_size or eye.size)
    try:
        gather.gather_image(
            gmap,
            variant,
            depth=eye.depth,
            normal=eye.normal,
            inv_view_projection=eye.inv_vp,
            size=eye.size,
            out=out,
            **kw,
        )
        return _read(out)
    finally:
        out.release()


@pytest.mark.parametrize("variant", VARIANTS)
def test_image_matches_reference(gl, eye, eye_photons, variant):
    ctx, _ = gl
    gmap = GpuPhotonMap(ctx, eye_photons, R, STRUCTURE_OF[variant])
    try:
        # A larger target: nothing may be written outside u_size.
        img = _gather_image(gl, gmap, variant, eye, out_size=(64, 56), k=K)
    finally:
        gmap.release()
    w, h = eye.size
    assert (img[h:] == -7.0).all() and (img[:, w:] == -7.0).all()
    img = img[:h, :w]
    assert (img[~eye.hit] == 0.0).all()  # background: vec4(0)
    assert (img[eye.hit, 3] == 1.0).all()
    pts, nrm = eye.query()
    got = img[eye.hit, :3]
    if "heap" in variant:
        ref = estimate_knn(eye_photons, pts, nrm, R, K)
        # Where the k-th and (k+1)-th nearest are within rounding of each other, the GPU's
        # float32 hit point may keep the other one.
        _, clear = _knn_brute(eye_photons, pts, nrm, R, K)
        assert clear.mean() > 0.98
        got, ref = got[clear], ref[clear]
    else:
        ref = estimate_radius(eye_photons, pts, nrm, R)
    assert (ref > 0).any(axis=1).mean() > 0.9
    _close(got, ref)


def test_image_shared_with_whole_tiles_in_one_cell(gl):
    """A close-up (narrow field of view): many 8x8 tiles land in a single cell."""
    ctx, _ = gl
    eye = GBuffer(ctx, 48, 40, eye=(0.5, 0.5, 0.95), wall_z=0.6, fov=8.0)
    try:
        rng = np.random.default_rng(9)
        photons = _robust(_photons(rng, 9000), *eye.query(), R)
        grid = HashGrid.build(photons.positions, R)
        cells = grid.hash(grid.cell_coords(eye.points.reshape(-1, 3))).reshape(40, 48)
        tiles = cells.reshape(5, 8, 6, 8).transpose(0, 2, 1, 3).reshape(30, 64)
        one = (tiles == tiles[:, :1]).all(axis=1) & eye.hit.reshape(5, 8, 6, 8).transpose(
            0, 2, 1, 3
        ).reshape(30, 64).all(axis=1)
        assert 5 <= one.sum() < 30  # both paths of Algorithm 1 run
        gmap = GpuPhotonMap(ctx, photons, R, "grid")
        try:
            shared = _gather_image(gl, gmap, "shared", eye)
            radius = _gather_image(gl, gmap, "radius", eye)
        finally:
            gmap.release()
        np.testing.assert_allclose(shared, radius, rtol=1e-5, atol=1e-7)
        _close(shared[eye.hit, :3], estimate_radius(photons, *eye.query(), R))
    finally:
        eye.release()


def _level_texture(ctx: moderngl.Context, levels: np.ndarray) -> moderngl.Texture:
    h, w = levels.shape
    tex = ctx.texture((w, h), 1, levels.astype(np.uint8).tobytes(), dtype="u1")
    tex.filter = (moderngl.NEAREST, moderngl.NEAREST)
    return tex


@pytest.mark.parametrize("variant", ["radius", "shared"])
def test_block_rate_writes_only_sample_pixels(gl, eye, eye_photons, variant):
    ctx, _ = gl
    w, h = eye.size
    rng = np.random.default_rng(2)
    half = rng.integers(0, 4, ((h + 1) // 2, (w + 1) // 2))  # levels 0..3 at half resolution
    half[:6, :6] = 3
    half[-4:, -4:] = 2  # blocks cut by the image edge
    levels = _level_texture(ctx, half)
    gmap = GpuPhotonMap(ctx, eye_photons, R, "grid")
    try:
        img = _gather_image(
            gl, gmap, variant, eye, out_size=(64, 56), block_rate=True, levels=levels
        )
    finally:
        gmap.release()
        levels.release()
    assert (img[h:] == -7.0).all() and (img[:, w:] == -7.0).all()
    img = img[:h, :w]
    ys, xs = np.mgrid[0:h, 0:w]
    s = half[ys >> 1, xs >> 1]
    ox, oy = xs & ~((1 << s) - 1), ys & ~((1 << s) - 1)
    sample = (xs == np.minimum(ox + ((1 << s) >> 1), w - 1)) & (
        ys == np.minimum(oy + ((1 << s) >> 1), h - 1)
    )
    written = (img != -7.0).any(axis=2)
    assert (written == sample).all()
    assert (img[sample & ~eye.hit] == 0.0).all()
    take = sample & eye.hit
    ref = estimate_radius(eye_photons, eye.points[take], eye.normals[take], R)
    assert (img[take, 3] == 1.0).all()
    _close(img[take, :3], ref)


@pytest.mark.parametrize("variant", ["radius", "shared", "kdtree"])
def test_reuse_copies_left_result_where_a_winner_is_set(gl, eye, eye_photons, variant):
    ctx, gather = gl
    w, h = eye.size
    rng = np.random.default_rng(4)
    winner = np.full((h, w), NO_WINNER, np.uint32)
    chosen = rng.random((h, w)) < 0.4
    winner[chosen] = rng.integers(0, w * h, int(chosen.sum()))
    bogus = (rng.random((h, w)) < 0.05) & ~chosen  # an index past the image: ignored
    winner[bogus] = w * h + 5
    left = rng.uniform(0.0, 3.0, (h, w, 4)).astype(np.float32)
    win_tex = ctx.texture((w, h), 1, winner.tobytes(), dtype="u4")
    left_tex = ctx.texture((w, h), 4, left.tobytes(), dtype="f4")
    for tex in (win_tex, left_tex):
        tex.filter = (moderngl.NEAREST, moderngl.NEAREST)
    gmap = GpuPhotonMap(ctx, eye_photons, R, STRUCTURE_OF[variant])
    try:
        gather.reset_counters()
        img = _gather_image(
            gl, gmap, variant, eye, out_size=(64, 56), reuse=(win_tex, left_tex), count=True
        )
        counts = gather.counters()
    finally:
        gmap.release()
        win_tex.release()
        left_tex.release()
    assert (img[h:] == -7.0).all() and (img[:, w:] == -7.0).all()
    img = img[:h, :w]
    reused = chosen & eye.hit
    src = winner[reused]
    np.testing.assert_array_equal(img[reused, :3], left.reshape(-1, 4)[src, :3])
    assert (img[reused, 3] == 2.0).all()
    assert (img[~eye.hit] == 0.0).all()
    gathered = eye.hit & ~chosen
    assert (img[gathered, 3] == 1.0).all()
    ref = estimate_radius(eye_photons, eye.points[gathered], eye.normals[gathered], R)
    _close(img[gathered, :3], ref)
    assert counts["reused"] == int(reused.sum())
    assert counts["gathered"] == int(gathered.sum())
    assert counts["within"] > 0


def test_image_with_no_photons(gl, eye):
    ctx, _ = gl
    gmap = GpuPhotonMap(ctx, PhotonMap.empty(), R, "grid")
    try:
        img = _gather_image(gl, gmap, "shared", eye)
    finally:
        gmap.release()
    assert not img[..., :3].any()
    assert (img[eye.hit, 3] == 1.0).all() and (img[~eye.hit, 3] == 0.0).all()


@pytest.mark.parametrize("variant", ["radius", "heap", "kdtree-heap", "shared"])
def test_ssbo_source_equals_texture_source(gl, data, variant):
    """The records read from the SSBOs (the slow path on llvmpipe) give the same estimate."""
    ctx, gather = gl
    photons, pts, nrm = data
    ssbo = PhotonGather(ctx, gather.shaders, source="ssbo")
    gmap = GpuPhotonMap(ctx, photons, R, STRUCTURE_OF[variant])
    try:
        a = gather.gather_points(gmap, pts[:500], nrm[:500], variant, k=K)
        b = ssbo.gather_points(gmap, pts[:500], nrm[:500], variant, k=K)
    finally:
        gmap.release()
        ssbo.release()
    np.testing.assert_array_equal(a, b)
