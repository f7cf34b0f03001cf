"""Pose from four corners (paper §4.B, eq. 6-7): round trips, noise, angle conventions."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from rovis import geometry

DESK = np.array([0.0, 0.0, 1.0, 0.0])  # z = 0, normal up


def _yaw_diff(a: float, b: float) -> float:
    return abs((a - b + 180.0) % 360.0 - 180.0)


@settings(max_examples=200, deadline=None)
@given(yaw=st.floats(0, 360, exclude_max=True), tilt_x=st.floats(-20, 20), tilt_y=st.floats(-20, 20),
       sx=st.floats(0.12, 0.32), sy=st.floats(0.09, 0.25), sz=st.floats(0.008, 0.06),
       cx=st.floats(-1, 1), cy=st.floats(-1, 1))
def test_pose_round_trips_through_corners(yaw, tilt_x, tilt_y, sx, sy, sz, cx, cy):
    R = Rotation.from_euler("xyz", [tilt_x, tilt_y, yaw], degrees=True).as_matrix()
    center = np.array([cx, cy, sz])
    pose = geometry.pose_from_corners(geometry.corners_from_pose(center, R, (sx, sy)), DESK)
    np.testing.assert_allclose(pose.center, center, atol=1e-9)  # nm
    np.testing.assert_allclose(pose.R, R, atol=1e-9)
    np.testing.assert_allclose(pose.size, [sx, sy, sz], atol=1e-9)
    np.testing.assert_allclose(pose.corners, geometry.corners_from_pose(center, R, (sx, sy)), atol=1e-9)
    assert np.linalg.det(pose.R) == pytest.approx(1.0)
    R_back = Rotation.from_euler("ZXZ", np.array(pose.euler_zxz_deg)[[2, 1, 0]], degrees=True)
    # Near Θ = 0 the angles are ill-conditioned (eq. 7 is 0/0): the round trip holds to 1e-6.
    np.testing.assert_allclose(R_back.as_matrix(), R, atol=1e-6)
    np.testing.assert_allclose(Rotation.from_quat(pose.quaternion_xyzw).as_matrix(), R, atol=1e-9)


@settings(max_examples=100, deadline=None)
@given(yaw=st.floats(0, 360, exclude_max=True))
def test_flat_book_yaw_and_psi_cover_the_whole_circle(yaw):
    R = Rotation.from_euler("z", yaw, degrees=True).as_matrix()
    pose = geometry.pose_from_corners(geometry.corners_from_pose([0.4, 0.3, 0.02], R, (0.2, 0.15)), DESK)
    assert 0.0 <= pose.yaw_deg < 360.0
    assert _yaw_diff(pose.yaw_deg, yaw) < 1e-7
    phi, theta, psi = pose.euler_zxz_deg
    assert (phi, theta) == (0.0, 0.0)  # Θ = 0: eq. 7 is 0/0, rovis puts the heading in Ψ
    assert _yaw_diff(psi, yaw) < 1e-7


def test_yaw_samples_span_0_to_360():
    yaws = [geometry.pose_from_corners(geometry.corners_from_pose(
        [0, 0, 0.03], Rotation.from_euler("z", y, degrees=True).as_matrix(), (0.3, 0.2)), DESK).yaw_deg
        for y in np.arange(0.0, 360.0, 7.5)]
    np.testing.assert_allclose(yaws, np.arange(0.0, 360.0, 7.5), atol=1e-9)


def test_noisy_skewed_corners_give_a_proper_rotation_close_to_truth():
    rng = np.random.default_rng(7)
    for _ in range(200):
        R = Rotation.from_euler("xyz", [*rng.uniform(-5, 5, 2), rng.uniform(0, 360)], degrees=True)
        corners = geometry.corners_from_pose(rng.uniform(-0.5, 0.5, 3), R.as_matrix(), (0.25, 0.18))
        corners += rng.normal(0, 0.002, corners.shape)  # 2 mm corner noise: not a rectangle
        pose = geometry.pose_from_corners(corners)
        np.testing.assert_allclose(pose.R.T @ pose.R, np.eye(3), atol=1e-12)
        assert np.linalg.det(pose.R) == pytest.approx(1.0, abs=1e-12)
        angle = np.degrees((R.inv() * Rotation.from_matrix(pose.R)).magnitude())
        assert angle < 2.0


def test_height_comes_from_the_desk_plane_even_when_tilted():
    # A desk tilted 10 degrees about x, a 3 cm book lying on it.
    tilt = Rotation.from_euler("x", 10, degrees=True).as_matrix()
    n = tilt[:, 2]
    desk = np.append(n, -n @ np.array([0.0, 0.0, 0.5]))
    center = np.array([0.0, 0.0, 0.5]) + 0.03 * n
    pose = geometry.pose_from_corners(geometry.corners_from_pose(center, tilt, (0.2, 0.1)), desk)
    assert pose.size[2] == pytest.approx(0.03, abs=1e-9)
    assert pose.yaw_deg == pytest.approx(0.0, abs=1e-7)


def test_no_desk_plane_means_unknown_height():
    pose = geometry.pose_from_corners(geometry.corners_from_pose([0, 0, 1], np.eye(3), (0.2, 0.1)))
    assert np.isnan(pose.size[2])


@pytest.mark.parametrize("corners, message", [
    (np.zeros((4, 3)), "degenerate"),
    (np.array([[0, 0, 0], [1, 0, 0], [2, 0, 0], [3, 0, 0.0]]), "degenerate"),
    (np.full((4, 3), np.nan), "NaN"),
    (np.zeros((3, 3)), r"expected shape \(4, 3\)"),
])
def test_bad_corners_are_refused_with_a_reason(corners, message):
    with pytest.raises(ValueError, match=message):
        geometry.pose_from_corners(corners)


def test_euler_zxz_matches_scipy_away_from_gimbal_lock():
    for q in Rotation.random(200, random_state=3):
        phi, theta, psi = geometry.euler_zxz_deg(q.as_matrix())
        assert 0 <= phi < 360 and 0 <= theta <= 180 and 0 <= psi < 360
        np.testing.assert_allclose(
            Rotation.from_euler("ZXZ", [psi, theta, phi], degrees=True).as_matrix(), q.as_matrix(),
            atol=1e-9)


def test_quaternion_is_xyzw_with_nonnegative_w():
    R = Rotation.from_euler("z", 270, degrees=True).as_matrix()
    q = geometry.quaternion_xyzw(R)
    np.testing.assert_allclose(q, [0, 0, -np.sqrt(0.5), np.sqrt(0.5)], atol=1e-12)


def test_fit_plane_orients_the_normal_up():
    rng = np.random.default_rng(0)
    P = np.column_stack([rng.uniform(-1, 1, (50, 2)), np.full(50, 0.25)])
    np.testing.assert_allclose(geometry.fit_plane(P), [0, 0, 1, -0.25], atol=1e-12)
    np.testing.assert_allclose(geometry.plane_distance([0, 0, 1, -0.25], [[0, 0, 1.0]]), [0.75])


def test_decompose_projection_round_trips(rig):
    K, T = geometry.decompose_projection(-2.5 * rig.Q_R)  # any scale, even negative
    np.testing.assert_allclose(K, rig.K2, atol=1e-9)
    np.testing.assert_allclose(T, rig.T_right_world, atol=1e-12)
