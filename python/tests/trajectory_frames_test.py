# SPDX-License-Identifier: Apache-2.0
# SPDX-FileCopyrightText: 2026 ds3d authors
"""New world and body frames of a trajectory; the Bonn marker-to-camera transform."""
import pathlib

import numpy as np
import pytest

import ds3d

FIX = pathlib.Path(__file__).resolve().parents[2] / "tests" / "data" / "trajectory" / "walking_xyz_basic"


def test_frames_and_the_bonn_camera_transform():
    gt = ds3d.read_tum_trajectory(str(FIX / "groundtruth.txt"))
    world = np.eye(4)
    world[:3, 3] = [1.0, -2.0, 0.5]
    world[:3, :3] = [[0, -1, 0], [1, 0, 0], [0, 0, 1]]
    moved = ds3d.transform_trajectory(gt, world, np.eye(4))
    assert moved.shape == gt.shape
    np.testing.assert_allclose(moved[:, 0], gt[:, 0])
    np.testing.assert_allclose(moved[:, 1:4], gt[:, 1:4] @ world[:3, :3].T + world[:3, 3], atol=1e-12)
    assert ds3d.evaluate_ate(gt, moved).rmse < 1e-9  # a world change is aligned away
    cam = ds3d.bonn_marker_to_camera(gt)
    assert cam.shape == gt.shape and np.isfinite(cam).all()
    # The marker-to-camera lever arm is about 2 cm: every camera centre is that far from the
    # marker's, once both are in the same (the camera's) world axes.
    ros = np.array([[-1.0, 0, 0], [0, 0, 1], [0, 1, 0]])
    gap = np.linalg.norm(cam[:, 1:4] - gt[:, 1:4] @ ros.T, axis=1)
    np.testing.assert_allclose(gap, np.linalg.norm([0.0113, -0.0098, 0.0111]), rtol=1e-9)
    assert ds3d.BONN_DEPTH_SCALE_FACTOR == pytest.approx(1.0593)
    bad = np.eye(4)
    bad[0, 0] = 1.05
    with pytest.raises(ValueError, match="ds3d::transform_trajectory: body_to must be a rigid"):
        ds3d.transform_trajectory(gt, np.eye(4), bad)
