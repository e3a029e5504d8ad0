import math

import numpy as np
import pytest

from app.camera import StereoCamera, disparity_px, orientation
from app.settings import StereoSettings


def project(eye, point):
    clip = eye.projection @ eye.view @ np.append(point, 1.0)
    ndc = clip[:3] / clip[3]
    return (ndc[0] + 1) / 2 * eye.width, (1 - ndc[1]) / 2 * eye.height, ndc[2]


def test_orientation_conventions():
    r, u, f = orientation(0, 0)
    np.testing.assert_allclose(f, [0, 0, -1], atol=1e-12)
    np.testing.assert_allclose(r, [1, 0, 0], atol=1e-12)
    np.testing.assert_allclose(u, [0, 1, 0], atol=1e-12)
    _, _, f = orientation(90, 0)
    np.testing.assert_allclose(f, [-1, 0, 0], atol=1e-12)  # positive yaw turns left


def test_off_axis_frusta_are_parallel_and_shifted_towards_each_other():
    cam = StereoCamera(StereoSettings(ipd_mm=64, convergence_m=2.0))
    left, right = cam.eyes(640, 720)
    np.testing.assert_allclose(right.position - left.position, [0.064, 0, 0], atol=1e-12)
    np.testing.assert_allclose(left.view[:3, :3], right.view[:3, :3])  # parallel eyes
    assert left.projection[0, 2] > 0 > right.projection[0, 2]  # asymmetric frusta
    # A point on the convergence plane lands on the same pixel in both eyes.
    xl, yl, _ = project(left, np.array([0.0, 1.6, -2.0]))
    xr, yr, _ = project(right, np.array([0.0, 1.6, -2.0]))
    assert xl == pytest.approx(xr, abs=1e-6) and yl == pytest.approx(yr, abs=1e-6)


@pytest.mark.parametrize("depth", [0.5, 1.0, 2.0, 5.0, 50.0])
def test_disparity_matches_the_analytic_value(depth):
    s = StereoSettings(ipd_mm=64, convergence_m=2.0, fov_deg=95)
    cam = StereoCamera(s)
    cam.set_pose([0, 1.6, 0], 0, 0)
    left, right = cam.eyes(640, 720)
    p = np.array([0.0, 1.6, -depth])
    xl = project(left, p)[0]
    xr = project(right, p)[0]
    assert xl - xr == pytest.approx(disparity_px(depth, 640, 720, s), rel=1e-9, abs=1e-9)
    # Near points are crossed (left image further right), far ones uncrossed.
    assert (xl - xr > 0) == (depth < 2.0) or depth == 2.0


def test_field_of_view_is_headset_like():
    cam = StereoCamera()
    assert 90 <= cam.settings.fov_deg <= 100
    left = cam.eyes(640, 720)[0]
    top = 1.0 / left.projection[1, 1]
    assert math.degrees(2 * math.atan(top)) == pytest.approx(cam.settings.fov_deg)


@pytest.mark.parametrize("value", [math.nan, math.inf, -math.inf, 1e300])
def test_extreme_poses_give_finite_matrices(value):
    cam = StereoCamera(StereoSettings(near_m=1e-4, far_m=1e5))
    cam.set_pose([value, value, value], value, value)
    for eye in cam.eyes(1, 1):
        assert np.isfinite(eye.view).all() and np.isfinite(eye.projection).all()
        assert np.isfinite(eye.inverse_view_projection).all()
        assert np.isfinite(eye.ray(value, value)).all()


def test_gaze_ray_meets_both_eye_rays_on_the_convergence_plane() -> None:
    s = StereoSettings(ipd_mm=64.0, convergence_m=2.0)
    cam = StereoCamera(s)
    cam.set_pose((1.0, 1.6, -3.0), 30.0, 10.0)
    for u, v in ((0.5, 0.5), (0.2, 0.7), (0.9, 0.1)):
        origin, d = cam.gaze_ray(u, v, 640, 720)
        np.testing.assert_allclose(origin, cam.position)
        _, _, fwd = orientation(cam.yaw_deg, cam.pitch_deg)
        t = 2.0 / float(d @ fwd)
        target = origin + d * t  # on the convergence plane (2 m ahead along the view axis)
        for eye in cam.eyes(640, 720):
            r = eye.ray(u, v)
            te = float((target - eye.position) @ fwd) / float(r @ fwd)
            np.testing.assert_allclose(eye.position + r * te, target, atol=1e-9)
    # Straight ahead at the centre: a far object on the axis is hit, whatever the IPD.
    cam.set_pose((0.0, 1.6, 0.0), 0.0, 0.0)
    np.testing.assert_allclose(cam.gaze_ray(0.5, 0.5, 640, 720)[1], [0, 0, -1], atol=1e-12)
