# SPDX-License-Identifier: Apache-2.0
# SPDX-FileCopyrightText: 2026 ds3d authors
"""RGB-D SLAM front-end conveniences over the compiled ``ds3d.Slam`` (see docs/slam.md)."""
import os

from ._ds3d import Slam, SlamConfig, _run_slam

__all__ = ["Slam", "SlamConfig", "run_slam"]


def run_slam(dataset_dir, camera=None, max_frames=0, threaded=True, config=None):
    """Runs the SLAM pipeline on a TUM-layout folder (rgb.txt, depth.txt).

    Args:
        dataset_dir: folder path (str or os.PathLike).
        camera: None (camera.txt in the folder, else the tum_ros preset), a preset name
            (``tum1 tum2 tum3 tum_ros bonn``) or a camera.txt path.
        max_frames: 0 for all frames, else the first ``max_frames``.
        threaded: run the pipeline stages in threads (same result either way).
        config: a ``ds3d.SlamConfig`` (its camera is replaced by the dataset's).

    Returns:
        (N, 8) float64 array: timestamp tx ty tz qx qy qz qw (camera-to-world) per frame.

    Raises:
        ValueError: bad arguments; RuntimeError: unreadable dataset.
    """
    if int(max_frames) < 0:
        raise ValueError(f"ds3d.run_slam: max_frames must be >= 0 (got {max_frames})")
    return _run_slam(os.fspath(dataset_dir), "" if camera is None else os.fspath(camera),
                     int(max_frames), bool(threaded), config)
