# SPDX-License-Identifier: Apache-2.0
# SPDX-FileCopyrightText: 2026 ds3d authors
"""RGB-D SLAM front-end conveniences over the compiled ``ds3d.Slam`` (see docs/slam.md)."""
import os

from ._ds3d import Slam, SlamConfig, _run_slam

__all__ = ["Slam", "SlamConfig", "run_slam"]


def run_slam(dataset_dir, camera=None, max_frames=0, threaded=True, config=None,
             dynamic="none", weights=None, detect_every=1, min_score=None, hold_frames=None,
             segment_frames=None, segment_outside_boxes=True):
    """Runs the SLAM pipeline on a TUM-layout folder (rgb.txt, depth.txt).

    Args:
        dataset_dir: folder path (str or os.PathLike).
        camera: None (camera.txt in the folder, else the tum_ros preset), a preset name
            (``tum1 tum2 tum3 tum_ros bonn``) or a camera.txt path.
        max_frames: 0 for all frames, else the first ``max_frames``.
        threaded: run the pipeline stages in threads (same result either way).
        config: a ``ds3d.SlamConfig`` (its camera is replaced by the dataset's).
        dynamic: source of moving objects, as ``ds3d-slam --dynamic``: ``"none"``,
            ``"geometric"``, ``"htx"``, ``"file:PATH"``, ``"A+B"`` (e.g. ``"htx+geometric"``) or
            ``"A&B"`` (A's boxes only where B sees motion, e.g. ``"htx&geometric"``) or
            ``"A&&geometric"`` (A's boxes where the geometric source's raw evidence inside them
            is significant, tracked while they stay, e.g. ``"htx&&geometric"``);
            any other than none filters keypoints with the box-gated HDBSCAN filter.
        weights: HTx weights file for ``htx`` (None: models/htx_lite_fast.safetensors of the
            source tree, else <prefix>/share/ds3d/models/).
        detect_every: run the HTx detector on every k-th frame (k >= 1; boxes carried between).
        min_score: HTx box score threshold in [0, 1] (None: the library default, 0.3).
        hold_frames: frames an HTx box the detector then misses is held while its part head
            still sees foreground in it (>= 0; None: the library default, 10; ignored under
            ``"A&&geometric"``, whose tracks hold the boxes).
        segment_frames: earlier frames whose part-head logits are averaged into each point's
            (nearest point within one voxel; >= 0; None: the library default, 10; 0 = off).
        segment_outside_boxes: the part head also marks the keypoints it sees on people outside
            the HTx boxes (default True; False: it decides inside the boxes only).

    Returns:
        (N, 8) float64 array: timestamp tx ty tz qx qy qz qw (camera-to-world) per frame.

    Raises:
        ValueError: bad arguments; RuntimeError: unreadable dataset or weights file.
    """
    if int(max_frames) < 0:
        raise ValueError(f"ds3d.run_slam: max_frames must be >= 0 (got {max_frames})")
    if int(detect_every) < 1:
        raise ValueError(f"ds3d.run_slam: detect_every must be >= 1 (got {detect_every})")
    return _run_slam(os.fspath(dataset_dir), "" if camera is None else os.fspath(camera),
                     int(max_frames), bool(threaded), config, str(dynamic),
                     "" if weights is None else os.fspath(weights), int(detect_every),
                     None if min_score is None else float(min_score),
                     None if hold_frames is None else int(hold_frames),
                     None if segment_frames is None else int(segment_frames),
                     bool(segment_outside_boxes))
