"""The desk marker stage and `rovis register`, on self-contained renders of the real marker.

The scenes come from ``marker_scene`` (exact plane homographies, supersampled, real lens
distortion, noise), not from ``rovis.synth``, so the marker code is checked against an image
formation it does not share.
"""

from __future__ import annotations

import cv2
import numpy as np
import pytest
import yaml
from marker_scene import marker_scene

from rovis import geometry, load_calibration, save_calibration
from rovis.calib import make_rig
from rovis.calibrate import read_pose, register
from rovis.cli import main
from rovis.imageio import read_gray, to_gray_u8
from rovis.marker import (desk_plane_from_marker, detect_marker, marker_model,
                          marker_pose_mono, marker_pose_stereo, workspace_polygon)

SEEDS = range(6)


def rotation_error_deg(R_a, R_b) -> float:
    return float(np.degrees(np.arccos(np.clip((np.trace(R_a.T @ R_b) - 1) / 2, -1, 1))))


@pytest.fixture(scope="module")
def scenes():
    """(true rig, left, right) for cameras 0.9–1.4 m away, looking down 40–70°."""
    return [marker_scene(seed) for seed in SEEDS]


@pytest.fixture(scope="module")
def scene(scenes):
    return scenes[0]


def _uncalibrated_world(rig):
    """The same cameras with no world transform (world = left camera)."""
    return make_rig(distortion=rig.D1)


# --------------------------------------------------------------------------- detection


def test_detects_the_marker_corners_to_a_twentieth_of_a_pixel(scenes):
    for rig, left, right in scenes:
        for camera, image in (("left", left), ("right", right)):
            found = detect_marker(image, intrinsics=rig.intrinsics(camera))
            assert found is not None and found.marker_id == 0
            truth = rig.project(marker_model(0.10), camera)
            assert np.abs(found.corners_px - truth).max() < 0.05  # pixels (measured ≤ 0.03)


def test_edge_refinement_beats_arucos_own_corners(scene):
    rig, left, _ = scene
    truth = rig.project(marker_model(0.10), "left")
    raw = detect_marker(left, refine=False)
    refined = detect_marker(left, intrinsics=rig.intrinsics("left"))
    assert np.abs(refined.corners_px - truth).max() < np.abs(raw.corners_px - truth).max()


def test_detection_takes_colour_and_ignores_other_ids(scene):
    rig, left, _ = scene
    colour = cv2.cvtColor(left, cv2.COLOR_GRAY2BGR)
    a, b = detect_marker(colour), detect_marker(left)
    np.testing.assert_allclose(a.corners_px, b.corners_px, atol=1e-9)
    assert detect_marker(left, marker_id=7) is None
    assert detect_marker(np.full((480, 640), 128, np.uint8)) is None


# --------------------------------------------------------------------------- pose


def test_stereo_pose_recovers_the_true_marker_pose(scenes):
    for rig, left, right in scenes:
        cl = detect_marker(left, intrinsics=rig.intrinsics("left")).corners_px
        cr = detect_marker(right, intrinsics=rig.intrinsics("right")).corners_px
        T_left_marker = marker_pose_stereo(_uncalibrated_world(rig), cl, cr)
        T_true = rig.T_left_world  # world = marker frame
        assert np.linalg.norm(T_left_marker[:3, 3] - T_true[:3, 3]) < 2e-3  # 2 mm
        assert rotation_error_deg(T_left_marker[:3, :3], T_true[:3, :3]) < 0.2
        T_mono = marker_pose_mono(rig.K1, rig.D1, cl)
        assert np.linalg.norm(T_mono[:3, 3] - T_true[:3, 3]) < 5e-3  # 5 mm
        assert rotation_error_deg(T_mono[:3, :3], T_true[:3, :3]) < 0.5


def test_stereo_pose_refuses_bad_corners(rig):
    with pytest.raises(ValueError, match=r"corners_left_px: expected shape \(4, 2\)"):
        marker_pose_stereo(rig, np.zeros((3, 2)), np.zeros((4, 2)))


def test_desk_plane_from_marker():
    np.testing.assert_allclose(desk_plane_from_marker(np.eye(4)), [0, 0, 1, 0])
    T = geometry.make_transform(np.eye(3), [0.1, 0.2, 0.75])  # desk 0.75 m above the base
    plane = desk_plane_from_marker(T)
    np.testing.assert_allclose(plane, [0, 0, 1, -0.75])
    assert geometry.plane_distance(plane, [[0.5, 0.5, 0.80]])[0] == pytest.approx(0.05)


# --------------------------------------------------------------------------- workspace


def test_workspace_polygon_follows_the_distorted_projection(rig):
    poly = workspace_polygon(rig, "left")
    w, h = rig.image_size
    assert len(poly) > 100
    assert np.all((poly >= 0) & (poly <= [w - 1, h - 1]))
    corners = np.array([[0.05, 0.05, 0], [0.85, 0.05, 0], [0.85, 0.65, 0], [0.05, 0.65, 0]])
    for px in rig.project(corners, "left"):
        if np.all((px >= 0) & (px <= [w - 1, h - 1])):
            assert np.min(np.linalg.norm(poly - px, axis=1)) < 1e-6  # a vertex of the polygon
    # an edge midpoint lies on the polygon: the projection, not a straight chord, is followed
    mid = rig.project([[0.45, 0.05, 0.0]], "left")[0]
    assert np.min(np.linalg.norm(poly - mid, axis=1)) < 1e-6


def test_workspace_polygon_is_clipped_or_empty(rig):
    w, h = rig.image_size
    big = workspace_polygon(rig, "right", x=(-2.0, 3.0), y=(-2.0, 3.0))
    assert len(big) >= 4
    assert np.all((big >= -1e-9) & (big <= [w - 1 + 1e-9, h - 1 + 1e-9]))
    # the desk fills the view, so the clipped polygon is the whole image
    assert cv2.contourArea(big.astype(np.float32)) == pytest.approx((w - 1) * (h - 1), rel=1e-6)
    T_behind = geometry.make_transform(np.eye(3), [0.0, 0.0, 5.0])  # rectangle above the camera
    assert workspace_polygon(rig, "left", T_world_marker=T_behind).shape == (0, 2)


# --------------------------------------------------------------------------- register


def test_register_recovers_the_rendered_camera_pose(scenes):
    for rig, left, right in scenes:
        registered = register(_uncalibrated_world(rig), left, right)
        assert registered.world_frame == "marker"
        T = registered.T_world_left
        assert np.linalg.norm(T[:3, 3] - rig.T_world_left[:3, 3]) < 2e-3  # 2 mm
        assert rotation_error_deg(T[:3, :3], rig.T_world_left[:3, :3]) < 0.2


def test_register_in_the_robot_base_frame(scene):
    rig, left, right = scene
    T_base_marker = geometry.make_transform(
        cv2.Rodrigues(np.array([0.0, 0.0, 0.7]))[0], [0.6, -0.2, 0.74])
    registered = register(_uncalibrated_world(rig), left, right, T_base_marker=T_base_marker)
    assert registered.world_frame == "calibration"
    T_true = T_base_marker @ rig.T_world_left
    assert np.linalg.norm(registered.T_world_left[:3, 3] - T_true[:3, 3]) < 2e-3  # 2 mm


def test_register_names_the_image_without_a_marker(scene):
    rig, left, _ = scene
    blank = np.full_like(left, 128)
    with pytest.raises(ValueError, match="right image: no ArUco marker id 0 found"):
        register(rig, left, blank)
    with pytest.raises(ValueError, match="left image: no ArUco marker"):
        register(rig, blank, left)
    with pytest.raises(ValueError, match=r"left image: size 640x480 does not match the "
                                         r"calibration's 1024x768"):
        register(rig, cv2.resize(left, (640, 480)), left)


def test_cli_register_writes_the_world_transform(scene, tmp_path, capsys):
    rig, left, right = scene
    calib = tmp_path / "calib.yaml"
    save_calibration(_uncalibrated_world(rig), calib)
    cv2.imwrite(str(tmp_path / "left.png"), left)
    cv2.imwrite(str(tmp_path / "right.png"), right)
    out = tmp_path / "registered.yaml"
    assert main(["register", "--calib", str(calib), str(tmp_path / "left.png"),
                 str(tmp_path / "right.png"), "--out", str(out)]) == 0
    assert "T_world_left" in capsys.readouterr().out
    registered = load_calibration(out)
    assert registered.world_frame == "marker"
    assert np.linalg.norm(registered.T_world_left[:3, 3] - rig.T_world_left[:3, 3]) < 2e-3

    pose = np.eye(4)
    pose[:3, 3] = [1.0, 2.0, 0.5]
    (tmp_path / "pose.yaml").write_text(yaml.safe_dump({"T_base_marker": pose.tolist()}))
    assert main(["register", "--calib", str(calib), str(tmp_path / "left.png"),
                 str(tmp_path / "right.png"), "--marker-pose", str(tmp_path / "pose.yaml"),
                 "--out", str(out)]) == 0
    based = load_calibration(out)
    assert based.world_frame == "calibration"
    np.testing.assert_allclose(based.T_world_left[:3, 3],
                               rig.T_world_left[:3, 3] + [1.0, 2.0, 0.5], atol=2e-3)  # 2 mm


def test_register_on_real_images_without_a_marker_says_so(bumblebee_dir):
    rig = load_calibration(bumblebee_dir / "chess" / "stereo.yaml")
    scenes = bumblebee_dir / "scenes"
    with pytest.raises(ValueError, match=r"left image .*garden01_left.jpg: no ArUco marker"):
        register(rig, scenes / "garden01_left.jpg", scenes / "garden01_right.jpg")


def test_cli_register_bad_input_exits_2(scene, tmp_path, capsys):
    rig, left, _ = scene
    calib = tmp_path / "calib.yaml"
    save_calibration(rig, calib)
    cv2.imwrite(str(tmp_path / "left.png"), left)
    cv2.imwrite(str(tmp_path / "blank.png"), np.zeros_like(left))
    assert main(["register", "--calib", str(calib), str(tmp_path / "left.png"),
                 str(tmp_path / "blank.png")]) == 2
    err = capsys.readouterr().err
    assert "right image" in err and "blank.png" in err and "no ArUco marker" in err
    assert main(["register", "--calib", str(calib), str(tmp_path / "left.png"),
                 str(tmp_path / "missing.png")]) == 2
    assert "missing.png: image file not found" in capsys.readouterr().err
    assert main(["register", "--calib", str(calib), str(tmp_path / "left.png"),
                 str(tmp_path / "left.png"), "--marker-pose", "1 2 3"]) == 2
    assert "expected 16 numbers" in capsys.readouterr().err


# --------------------------------------------------------------------------- small helpers


def test_read_pose_forms(tmp_path):
    T = geometry.make_transform(cv2.Rodrigues(np.array([0.1, -0.2, 0.3]))[0], [1, 2, 3])
    numbers = [repr(float(v)) for v in T.ravel()]
    np.testing.assert_allclose(read_pose(" ".join(numbers)), T)
    np.testing.assert_allclose(read_pose(", ".join(numbers)), T)
    np.testing.assert_allclose(read_pose(numbers), T)
    (tmp_path / "pose.txt").write_text("\n".join(" ".join(numbers[4 * i:4 * i + 4])
                                                 for i in range(4)))
    np.testing.assert_allclose(read_pose(tmp_path / "pose.txt"), T)
    (tmp_path / "pose.yaml").write_text(yaml.safe_dump(T.tolist()))
    np.testing.assert_allclose(read_pose(str(tmp_path / "pose.yaml")), T)
    with pytest.raises(ValueError, match=r"marker pose \(rotation part\): expected a rotation matrix"):
        read_pose("2 0 0 0  0 2 0 0  0 0 2 0  0 0 0 1")
    with pytest.raises(ValueError, match="nothing.yaml: marker pose file not found"):
        read_pose(str(tmp_path / "nothing.yaml"))


def test_read_gray_converts_and_names_bad_files(tmp_path):
    img16 = np.tile(np.linspace(0, 65535, 64).astype(np.uint16), (8, 1))
    cv2.imwrite(str(tmp_path / "deep.png"), img16)
    g = read_gray(tmp_path / "deep.png")
    assert g.dtype == np.uint8 and g.shape == (8, 64) and g.min() == 0 and g.max() == 255
    bgr = np.zeros((4, 5, 3), np.uint8)
    bgr[..., 2] = 255  # pure red
    cv2.imwrite(str(tmp_path / "red.png"), bgr)
    assert read_gray(tmp_path / "red.png")[0, 0] == 76  # 0.299 * 255
    assert to_gray_u8(np.ones((2, 2), np.float32))[0, 0] == 255
    (tmp_path / "bad.png").write_bytes(b"garbage")
    with pytest.raises(ValueError, match="bad.png: cannot read image"):
        read_gray(tmp_path / "bad.png")
    with pytest.raises(ValueError, match="none.png: image file not found"):
        read_gray(tmp_path / "none.png")
