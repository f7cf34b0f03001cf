"""Triangulation (eq. 3-5): exactness, equivalence to SVD least squares, optimal method."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from rovis import geometry


def _project(Q: np.ndarray, P: np.ndarray) -> np.ndarray:
    h = P @ Q[:, :3].T + Q[:, 3]
    return h[:, :2] / h[:, 2:]


def _desk_points(n: int, rng: np.random.Generator) -> np.ndarray:
    return rng.uniform([0.0, 0.0, 0.0], [0.9, 0.7, 0.3], size=(n, 3))  # workspace, metres


def test_dlt_is_exact_without_noise(rig):
    P = _desk_points(5000, np.random.default_rng(1))
    P_hat = geometry.triangulate(rig.Q_L, rig.Q_R, _project(rig.Q_L, P), _project(rig.Q_R, P))
    assert np.abs(P_hat - P).max() < 1e-9  # 1 nm


def test_rig_triangulates_raw_distorted_pixels(rig):
    P = _desk_points(500, np.random.default_rng(2))
    P_hat = rig.triangulate(rig.project(P, "left"), rig.project(P, "right"))
    assert np.abs(P_hat - P).max() < 1e-9


def test_dlt_equals_svd_least_squares_of_eq5(rig):
    rng = np.random.default_rng(3)
    P = _desk_points(20, rng)
    p_L = _project(rig.Q_L, P) + rng.normal(0, 1.0, (20, 2))
    p_R = _project(rig.Q_R, P) + rng.normal(0, 1.0, (20, 2))
    P_hat = geometry.triangulate_dlt(rig.Q_L, rig.Q_R, p_L, p_R)
    for i in range(20):
        A = np.stack([p_L[i, 0] * rig.Q_L[2] - rig.Q_L[0], p_L[i, 1] * rig.Q_L[2] - rig.Q_L[1],
                      p_R[i, 0] * rig.Q_R[2] - rig.Q_R[0], p_R[i, 1] * rig.Q_R[2] - rig.Q_R[1]])
        X = np.linalg.lstsq(A[:, :3], -A[:, 3], rcond=None)[0]  # SVD-based
        np.testing.assert_allclose(P_hat[i], X, atol=1e-10)


@pytest.mark.parametrize("seed", range(5))
@pytest.mark.parametrize("sigma_px", [0.3, 1.0, 3.0])
def test_optimal_never_worse_than_dlt_in_reprojection_error(rig, seed, sigma_px):
    # The optimal method minimises the image distance to the observed points; it must do so
    # for every point. In 3D error against truth it is not better (a maximum-likelihood
    # estimate in the image is not a minimum-error estimate in space): they agree within 2%.
    rng = np.random.default_rng(seed)
    P = _desk_points(4000, rng)
    p_L = _project(rig.Q_L, P) + rng.normal(0, sigma_px, (len(P), 2))
    p_R = _project(rig.Q_R, P) + rng.normal(0, sigma_px, (len(P), 2))

    def reprojection_sq(X):
        return (np.sum((_project(rig.Q_L, X) - p_L) ** 2, axis=1)
                + np.sum((_project(rig.Q_R, X) - p_R) ** 2, axis=1))

    X_dlt = geometry.triangulate(rig.Q_L, rig.Q_R, p_L, p_R, method="dlt")
    X_opt = geometry.triangulate(rig.Q_L, rig.Q_R, p_L, p_R, method="optimal")
    assert np.all(reprojection_sq(X_opt) <= reprojection_sq(X_dlt) * (1 + 1e-9) + 1e-12)
    assert reprojection_sq(X_opt).mean() <= reprojection_sq(X_dlt).mean()
    err_dlt = np.linalg.norm(X_dlt - P, axis=1).mean()
    err_opt = np.linalg.norm(X_opt - P, axis=1).mean()
    assert err_opt == pytest.approx(err_dlt, rel=0.02)


def test_correct_matches_meets_epipolar_constraint_like_opencv(rig):
    rng = np.random.default_rng(4)
    P = _desk_points(300, rng)
    p_L = _project(rig.Q_L, P) + rng.normal(0, 2.0, (300, 2))
    p_R = _project(rig.Q_R, P) + rng.normal(0, 2.0, (300, 2))
    F = geometry.fundamental_from_projections(rig.Q_L, rig.Q_R)
    a, b = geometry.correct_matches(F, p_L, p_R)
    h = np.ones((300, 1))
    residual = np.einsum("ni,ij,nj->n", np.hstack([b, h]), F, np.hstack([a, h]))
    assert np.abs(residual).max() < 1e-9
    a_cv, b_cv = cv2.correctMatches(F, p_L[None], p_R[None])  # Hartley-Sturm, polynomial
    assert np.abs(a - a_cv[0]).max() < 1e-3  # px
    assert np.abs(b - b_cv[0]).max() < 1e-3


def test_parallel_rays_give_nan_not_garbage(rig):
    # Both pixels see points at infinity in the same direction: rays parallel.
    far = np.array([[0.4, 0.3, 0.0]]) + 1e9 * rig.T_world_left[:3, 2]
    p_L, p_R = _project(rig.Q_L, far), _project(rig.Q_R, far)
    P = geometry.triangulate_dlt(rig.Q_L, rig.Q_R, p_L, p_R)
    assert np.all(np.isnan(P)) or np.linalg.norm(P) > 1e6


def test_fundamental_matrix_agrees_with_rig(rig):
    F1 = geometry.fundamental_from_projections(rig.Q_L, rig.Q_R)
    F2 = rig.F / np.linalg.norm(rig.F)
    assert min(np.abs(F1 - F2).max(), np.abs(F1 + F2).max()) < 1e-9


def test_triangulate_rejects_unknown_method(rig):
    with pytest.raises(ValueError, match="method: expected 'dlt' or 'optimal'"):
        geometry.triangulate(rig.Q_L, rig.Q_R, np.zeros((1, 2)), np.zeros((1, 2)), method="svd")


def _cover(yaw_deg: float, centre, length: float = 0.24, width: float = 0.16) -> np.ndarray:
    """A book cover's corners (4, 3) parallel to the desk, cyclic order, metres."""
    c, s = np.cos(np.radians(yaw_deg)), np.sin(np.radians(yaw_deg))
    local = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]]) * [length / 2, width / 2]
    return np.column_stack([local @ np.array([[c, s], [-s, c]]), np.zeros(4)]) + centre


def test_rectangle_fit_is_exact_without_noise_and_always_a_rectangle(rig):
    P = _cover(30.0, [0.45, 0.35, 0.03])
    pl, pr = _project(rig.Q_L, P), _project(rig.Q_R, P)
    fit = geometry.fit_rectangle(rig.Q_L, rig.Q_R, pl, pr, P + 0.002)  # started 2 mm off
    assert np.abs(fit - P).max() < 1e-6
    rng = np.random.default_rng(4)
    err_dlt, err_fit = [], []
    for _ in range(50):
        noisy_l, noisy_r = pl + rng.normal(0, 0.5, pl.shape), pr + rng.normal(0, 0.5, pr.shape)
        dlt = geometry.triangulate(rig.Q_L, rig.Q_R, noisy_l, noisy_r)
        fit = geometry.fit_rectangle(rig.Q_L, rig.Q_R, noisy_l, noisy_r, dlt)
        sides = np.roll(fit, -1, axis=0) - fit
        assert np.abs(np.sum(sides * np.roll(sides, -1, axis=0), axis=1)).max() < 1e-9  # right angles
        assert np.abs(np.linalg.norm(sides[0]) - np.linalg.norm(sides[2])) < 1e-9
        # one plane: the fourth corner lies in the plane of the other three
        n = np.cross(fit[1] - fit[0], fit[3] - fit[0])
        assert abs(n @ (fit[2] - fit[0])) < 1e-12
        err_dlt.append(np.linalg.norm(dlt.mean(axis=0) - P.mean(axis=0)))
        err_fit.append(np.linalg.norm(fit.mean(axis=0) - P.mean(axis=0)))
    # the centre is found at least as well as from the four corners triangulated alone
    assert np.mean(err_fit) <= np.mean(err_dlt) * 1.05


def test_a_rectangle_on_the_desk_stays_parallel_to_it(rig):
    desk = np.array([0.0, 0.0, 1.0, 0.0])
    P = _cover(30.0, [0.45, 0.35, 0.012])
    pl, pr = _project(rig.Q_L, P), _project(rig.Q_R, P)
    start = P + np.array([[0, 0, 0.008], [0, 0, 0.0], [0, 0, -0.004], [0, 0, 0.006]])  # tilted
    fit = geometry.fit_rectangle(rig.Q_L, rig.Q_R, pl, pr, start, desk)
    assert np.abs(fit - P).max() < 1e-6
    # corners each a pixel off, differently in the two images: the four triangulated alone
    # lie centimetres apart in height, the fit is flat and within millimetres of the cover
    rng = np.random.default_rng(2)
    noisy_l, noisy_r = pl + rng.normal(0, 0.7, pl.shape), pr + rng.normal(0, 0.7, pr.shape)
    dlt = geometry.triangulate(rig.Q_L, rig.Q_R, noisy_l, noisy_r)
    fit = geometry.fit_rectangle(rig.Q_L, rig.Q_R, noisy_l, noisy_r, dlt, desk)
    assert np.ptp(fit[:, 2]) < 1e-9  # parallel to the desk
    assert np.ptp(dlt[:, 2]) > 0.003
    assert np.linalg.norm(fit.mean(axis=0) - P.mean(axis=0)) < 0.004
    # a tilted cover (an outline with its page block) fits no flat rectangle closely
    T = P.copy()
    T[[0, 3], 2] += 0.03
    tl, tr = _project(rig.Q_L, T), _project(rig.Q_R, T)
    fit = geometry.fit_rectangle(rig.Q_L, rig.Q_R, tl, tr, T, desk)
    off = max(np.linalg.norm(_project(rig.Q_L, fit) - tl, axis=1).max(),
              np.linalg.norm(_project(rig.Q_R, fit) - tr, axis=1).max())
    assert off > 2.0  # px


def test_rectangle_on_the_desk_is_the_least_squares_optimum(rig):
    """The fit parallel to the desk (analytic Jacobian) reaches the reprojection error's
    minimum: no nearby flat rectangle (heading, centre, size moved a little) fits the
    noisy corners better, and two starts end at one answer."""
    desk = np.array([0.0, 0.0, 1.0, 0.0])
    rng = np.random.default_rng(5)
    for yaw in (10.0, 75.0, 140.0):
        P = _cover(yaw, [0.5, 0.4, 0.03])
        pl = _project(rig.Q_L, P) + rng.normal(0, 0.7, (4, 2))
        pr = _project(rig.Q_R, P) + rng.normal(0, 0.7, (4, 2))

        def cost(C: np.ndarray) -> float:
            return float(np.sum((_project(rig.Q_L, C) - pl) ** 2)
                         + np.sum((_project(rig.Q_R, C) - pr) ** 2))

        fit = geometry.fit_rectangle(rig.Q_L, rig.Q_R, pl, pr, P + 0.004, desk)
        again = geometry.fit_rectangle(rig.Q_L, rig.Q_R, pl, pr,
                                       geometry.triangulate(rig.Q_L, rig.Q_R, pl, pr), desk)
        assert np.abs(fit - again).max() < 1e-6  # metres
        centre = fit.mean(axis=0)
        x = (fit[1] - fit[0]) / np.linalg.norm(fit[1] - fit[0])
        y = (fit[3] - fit[0]) / np.linalg.norm(fit[3] - fit[0])
        best = cost(fit)
        for move in ([0.0005, 0, 0], [0, 0.0005, 0], [0, 0, 0.0005]):  # the centre, 0.5 mm
            for sign in (1, -1):
                assert cost(fit + sign * np.array(move)) >= best
        turn = np.radians(0.05)  # the heading, about the centre
        R = np.array([[np.cos(turn), -np.sin(turn), 0], [np.sin(turn), np.cos(turn), 0],
                      [0, 0, 1]])
        assert cost((fit - centre) @ R.T + centre) >= best
        assert cost((fit - centre) @ R + centre) >= best
        for axis in (x, y):  # the length and the width, 0.5 mm longer or shorter
            side = np.sign((fit - centre) @ axis)[:, None] * axis
            assert cost(fit + 0.00025 * side) >= best
            assert cost(fit - 0.00025 * side) >= best


def _side_moved_out(px: np.ndarray, s: int, by: float) -> np.ndarray:
    """Quad ``px`` (4, 2) with side ``s``'s line moved ``by`` pixels out of the quad, its two
    corners where it meets its neighbours' lines (a side seen on an edge beside the cover)."""
    a, b = px[s], px[(s + 1) % 4]
    d = (b - a) / np.linalg.norm(b - a)
    n = np.array([d[1], -d[0]])
    if n @ (a - px.mean(axis=0)) < 0:
        n = -n
    out = px.copy()
    for k, other in ((s, (s - 1) % 4), ((s + 1) % 4, (s + 2) % 4)):
        e = px[k] - px[other]  # the neighbour's line through px[other] and px[k]
        t = by / (n @ e)  # along it, to the moved line
        out[k] = px[k] + t * e
    return out


@pytest.mark.parametrize("yaw, s", [(15.0, 1), (100.0, 3), (60.0, 0)])
def test_a_side_left_out_of_the_flat_fit(rig, yaw, s):
    # the right image's side s on an edge 3 px outside the cover (its page block's foot,
    # its shadow's soft edge): fitted to every side, the flat rectangle misses the side in
    # both images, by up to half of it (still outside it in the right image); with it left
    # out, the rectangle is the cover and the side lies the 3 px outside it
    desk = np.array([0.0, 0.0, 1.0, 0.0])
    P = _cover(yaw, [0.45, 0.4, 0.04], 0.2, 0.13)
    pl, pr = _project(rig.Q_L, P), _project(rig.Q_R, P)
    fit, off = geometry.fit_rectangle_sides(rig.Q_L, rig.Q_R, pl, pr, P + 0.003, desk)
    assert np.abs(fit - P).max() < 1e-6 and np.abs(off).max() < 1e-6
    moved = _side_moved_out(pr, s, 3.0)
    start = geometry.triangulate(rig.Q_L, rig.Q_R, pl, moved)
    fit, off = geometry.fit_rectangle_sides(rig.Q_L, rig.Q_R, pl, moved, start, desk)
    assert off[1, s] > 0.5  # px
    assert np.abs(fit - P).max() > 0.001  # m
    use = np.ones((2, 4), bool)
    use[1, s] = False
    fit, off = geometry.fit_rectangle_sides(rig.Q_L, rig.Q_R, pl, moved, start, desk, use=use)
    assert np.abs(fit - P).max() < 1e-6  # m
    assert np.abs(off[use]).max() < 1e-6
    assert off[1, s] == pytest.approx(3.0, abs=0.01)  # px, outside
    # the corners in the other order round: the same fit, the same offsets
    fit2, off2 = geometry.fit_rectangle_sides(rig.Q_L, rig.Q_R, pl[::-1], moved[::-1],
                                              start[::-1], desk, use=use[:, [2, 1, 0, 3]])
    np.testing.assert_allclose(fit2[::-1], fit, atol=1e-9)
    np.testing.assert_allclose(off2[:, [2, 1, 0, 3]], off, atol=1e-6)
    with pytest.raises(ValueError, match="both images"):
        geometry.fit_rectangle_sides(rig.Q_L, rig.Q_R, pl, moved, start, desk,
                                     use=[[True] * 4, [False] * 4])
