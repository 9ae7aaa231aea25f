# SPDX-License-Identifier: Apache-2.0
# SPDX-FileCopyrightText: 2026 ds3d authors
"""RGB-D SLAM front-end conveniences over the compiled ``ds3d.Slam`` (see docs/slam.md)."""
import os

from ._ds3d import FrontendConfig, Slam, _make_dynamic_source, _run_slam
from .config import SlamConfig

__all__ = ["Slam", "FrontendConfig", "SlamConfig", "run_slam", "make_dynamic_source"]

# run_slam's shortcuts for keys of the htx section (htx.<name>).
_HTX_SHORTCUTS = ("detect_every", "min_score", "hold_frames", "segment_frames",
                  "segment_outside_boxes")


def _config_with(config, dynamic=None, gate=None, weights=None, threaded=None, htx=None,
                 allowed=None, fn="ds3d.run_slam"):
    """A copy of ``config`` (SlamConfig, dict or None) with the shortcut arguments applied."""
    cfg = _config_with(config, dynamic, gate, weights, threaded, htx, _HTX_SHORTCUTS)
    return _run_slam(os.fspath(dataset_dir), "" if camera is None else os.fspath(camera),
                     int(max_frames), cfg._core)
