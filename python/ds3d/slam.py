# SPDX-License-Identifier: Apache-2.0
# SPDX-FileCopyrightText: 2026 ds3d authors
"""RGB-D SLAM front-end conveniences over the compiled ``ds3d.Slam`` (see docs/slam.md).

Every function here builds one ``ds3d.SlamConfig`` (docs/configuration.md) and hands it to the
same C++ path as ``ds3d-slam``; keyword shortcuts are keys of the ``dynamic``, ``pipeline`` and
``htx`` sections.
"""
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
    if isinstance(config, SlamConfig):
        cfg = config.copy()
    else:
        cfg = SlamConfig()
        if config is not None:
            cfg.update(config)
    for key, value in (("dynamic.source", dynamic), ("dynamic.gate", gate),
                       ("dynamic.weights", weights), ("pipeline.threaded", threaded)):
        if value is not None:
            cfg[key] = value
    for name, value in (htx or {}).items():
        if ("htx." + name) not in cfg or (allowed is not None and name not in allowed):
            raise TypeError(f"{fn}: unexpected keyword argument '{name}'")
        if value is not None:
            cfg["htx." + name] = value
    return cfg


def make_dynamic_source(spec="none", config=None, gate=None, weights=None, **htx):
    """The dynamic-object source of a ``--dynamic`` value, as ds3d-slam builds it.

    Args:
        spec: ``"none"``, ``"geometric"``, ``"htx"``, ``"file:PATH"`` or ``"A+B"`` (A, then B
            on what A left, e.g. ``"htx+geometric"``); key ``dynamic.source``.
        config: a ``ds3d.SlamConfig`` or a dict of keys for every other parameter.
        gate: ``"none"``, ``"motion"`` or ``"evidence"`` (key ``dynamic.gate``).
        weights: the HTx weights file (key ``dynamic.weights``; None: the shipped model).
        **htx: shortcuts for ``htx.<name>`` keys (e.g. ``detect_every=2``, ``min_score=0.4``,
            ``report_floor=True``, ``hold_frames=0``).

    Raises:
        ValueError: unknown spec or bad values; RuntimeError: unreadable weights or file.
    """
    cfg = _config_with(config, dynamic=spec, gate=gate, weights=weights, htx=htx,
                       fn="ds3d.make_dynamic_source")
    return _make_dynamic_source(cfg._core)


def run_slam(dataset_dir, camera=None, max_frames=0, config=None, dynamic=None, gate=None,
             weights=None, threaded=None, **htx):
    """Runs the SLAM pipeline on a TUM-layout folder (rgb.txt, depth.txt), as ``ds3d-slam``.

    Args:
        dataset_dir: folder path (str or os.PathLike).
        camera: None (camera.txt in the folder, else the tum_ros preset), a preset name
            (``tum1 tum2 tum3 tum_ros bonn``) or a camera.txt path.
        max_frames: 0 for all frames, else the first ``max_frames``.
        config: a ``ds3d.SlamConfig`` or a dict of keys (docs/configuration.md); None: defaults.
        dynamic: key ``dynamic.source``: ``"none"``, ``"geometric"``, ``"htx"``,
            ``"file:PATH"`` or ``"A+B"`` (e.g. ``"htx+geometric"``); any other than none
            filters keypoints with the box-gated HDBSCAN filter.
        gate: key ``dynamic.gate``: ``"none"``, ``"motion"`` (boxes only where the geometric
            source sees motion) or ``"evidence"`` (boxes with significant geometric evidence,
            tracked).
        weights: key ``dynamic.weights``, the HTx weights file (None: the shipped model).
        threaded: key ``pipeline.threaded`` (same result either way).
        **htx: shortcuts for ``htx.<name>`` keys: detect_every, min_score, hold_frames,
            segment_frames, segment_outside_boxes.

    Returns:
        (N, 8) float64 array: timestamp tx ty tz qx qy qz qw (camera-to-world) per frame.

    Raises:
        ValueError: bad arguments or keys; RuntimeError: unreadable dataset or weights file.
    """
    if int(max_frames) < 0:
        raise ValueError(f"ds3d.run_slam: max_frames must be >= 0 (got {max_frames})")
    cfg = _config_with(config, dynamic, gate, weights, threaded, htx, _HTX_SHORTCUTS)
    return _run_slam(os.fspath(dataset_dir), "" if camera is None else os.fspath(camera),
                     int(max_frames), cfg._core)
