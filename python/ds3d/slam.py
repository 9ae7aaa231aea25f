# SPDX-License-Identifier: Apache-2.0
# SPDX-FileCopyrightText: 2026 ds3d authors
"""RGB-D SLAM front-end conveniences over the compiled ``ds3d._ds3d.Slam`` (see docs/slam.md).

Every function here builds one ``ds3d.SlamConfig`` (docs/configuration.md) and hands it to the
same C++ path as ``ds3d-slam`` (dynamic source, masker, ``SlamFrontend(cfg, source, masker)``);
keyword shortcuts are keys of the ``dynamic``, ``pipeline`` and ``htx`` sections.
"""
import os
import sys

import numpy as np

from . import _ds3d
from ._ds3d import (DynamicObjectSource, FrontendConfig, HdbscanMasker, KeypointStatus,
                    TrackResult, _make_dynamic_source, _make_masker, _run_slam)
from .config import SlamConfig

__all__ = ["Slam", "FrontendConfig", "SlamConfig", "SlamResult", "TrackResult", "KeypointStatus",
           "run_slam", "make_dynamic_source"]

# run_slam's shortcuts for keys of the htx section (htx.<name>).
_HTX_SHORTCUTS = ("detect_every", "min_score", "hold_frames", "segment_frames",
                  "segment_outside_boxes")


def _config_with(config, dynamic=None, gate=None, weights=None, threaded=None, htx=None,
                 allowed=None, fn="ds3d.run_slam"):
    """A copy of ``config`` (SlamConfig, dict or None) with the shortcut arguments applied."""
    if isinstance(config, SlamConfig):
        cfg = config.copy()
    elif config is None or isinstance(config, dict):
        cfg = SlamConfig()
        if config is not None:
            cfg.update(config)
    else:
        raise TypeError(f"{fn}: config must be a ds3d.SlamConfig, a dict of keys or None "
                        f"(got {type(config).__name__})")
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
        spec: ``"none"``, ``"geometric"``, ``"htx"``, ``"file:PATH"`` or ``"A+B"`` (A, then B,
            each on the whole frame, objects united, e.g. ``"htx+geometric"``); key
            ``dynamic.source``.
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


class Slam(_ds3d.Slam):
    """The RGB-D SLAM front-end, frame by frame, with the dynamic stages of ``ds3d-slam``.

    ``Slam(config, camera=..., dynamic=..., masker=...)`` runs, in every :meth:`track` call,
    the same source -> masker -> tracking path as ``ds3d-slam`` and ``ds3d.run_slam`` (the C++
    ``SlamFrontend(cfg, source, masker)``): fed the frames of a folder in order, then
    :meth:`finish`, :meth:`trajectory` is bit-identical to theirs with the same config.

    Args:
        config: a ``ds3d.SlamConfig`` or a dict of keys (then ``camera`` is required), or a
            ``ds3d.FrontendConfig`` (the front-end alone; its camera fields are used unless
            ``camera`` is given), or None (a default SlamConfig when ``camera``, ``dynamic``,
            ``gate`` or ``weights`` is given, else a default FrontendConfig).
        camera: a ``ds3d.Camera``, a dict, a preset name (``tum1 tum2 tum3 tum_ros bonn``) or a
            camera.txt path: the intrinsics of the images (e.g. ``RgbdDataset(dir).camera``).
        dynamic: key ``dynamic.source`` (``"geometric"``, ``"htx"``, ``"file:PATH"``, ``"A+B"``)
            or a ``ds3d.DynamicObjectSource`` object (e.g. ``ds3d.make_dynamic_source(...)``).
        masker: a ``ds3d.HdbscanMasker``; None: ``HdbscanMasker(config's filter section)``
            whenever there is a source (as ds3d-slam).
        gate, weights, **htx: keys ``dynamic.gate``, ``dynamic.weights`` and ``htx.<name>``.

    Raises:
        TypeError: missing camera or wrong argument types; ValueError: bad keys or values;
        RuntimeError: unreadable weights or detections file.
    """

    def __init__(self, config=None, camera=None, dynamic=None, masker=None, gate=None,
                 weights=None, **htx):
        fn = "ds3d.Slam"
        if masker is not None and not isinstance(masker, HdbscanMasker):
            raise TypeError(f"{fn}: masker must be a ds3d.HdbscanMasker or None "
                            f"(got {type(masker).__name__})")
        source = dynamic if isinstance(dynamic, DynamicObjectSource) else None
        spec = None if source is not None else dynamic
        if spec is not None and not isinstance(spec, (str, os.PathLike)):
            raise TypeError(f"{fn}: dynamic must be a spec string or a ds3d.DynamicObjectSource "
                            f"(got {type(dynamic).__name__})")
        new_style = not (config is None or isinstance(config, FrontendConfig)) or any(
            v is not None for v in (spec, gate, weights)) or htx
        if isinstance(config, FrontendConfig) and new_style:
            raise TypeError(f"{fn}: dynamic spec, gate, weights and htx keys need a "
                            "ds3d.SlamConfig (or dict), not a ds3d.FrontendConfig")
        if not new_style:
            frontend = FrontendConfig() if config is None else config
            if camera is not None:
                frontend = frontend.copy()
                frontend.camera = camera
            if source is not None and masker is None:
                masker = HdbscanMasker()
            super().__init__(frontend, source, masker)
            self._config = None
            return
        if camera is None:
            raise TypeError(f"{fn}: camera is required with a SlamConfig (a ds3d.Camera, a "
                            "dict, a preset name or a camera.txt path)")
        cfg = _config_with(config, dynamic=spec, gate=gate, weights=weights, htx=htx, fn=fn)
        cfg.validate()
        frontend = cfg.frontend_config()
        frontend.camera = camera
        if source is None:
            source = _make_dynamic_source(cfg._core)  # the source first, as ds3d-slam does
        if masker is None:
            masker = _make_masker(cfg._core, force=dynamic is not None and spec is None)
        super().__init__(frontend, source, masker)
        self._config = cfg

    @classmethod
    def from_config(cls, config, camera, **kwargs):
        """``Slam(config, camera=camera, **kwargs)``: the ds3d-slam pipeline of a SlamConfig."""
        return cls(config if config is not None else SlamConfig(), camera=camera, **kwargs)

    @property
    def config(self):
        """A copy of the ``ds3d.SlamConfig`` this front-end was built from (None when built
        from a ``FrontendConfig``)."""
        return None if self._config is None else self._config.copy()


class SlamResult(np.ndarray):
    """What ``ds3d.run_slam`` returns: the (N, 8) float64 trajectory itself (timestamp tx ty tz
    qx qy qz qw, camera-to-world; every numpy operation works on it as before), with

    * ``trajectory``: the same rows as a plain ``numpy.ndarray``;
    * ``keyframes``: (K, 8) keyframe poses, same layout;
    * ``per_frame``: dict of (N,) arrays ``index timestamp state tracked keyframe features
      dynamic refilled depth_edge inliers`` (state as str: ``tracking``, ``lost``, ...);
    * ``stopped_early``: True when a KeyboardInterrupt (Ctrl-C) ended the run before the last
      frame: the rows are then the frames tracked so far, finished as usual;
    * ``total``: the frames the run was asked for.
    """

    def __new__(cls, trajectory, keyframes=None, per_frame=None, stopped_early=False, total=0):
        obj = np.asarray(trajectory, dtype=np.float64).view(cls)
        obj.keyframes = np.zeros((0, 8)) if keyframes is None else keyframes
        obj.per_frame = {} if per_frame is None else per_frame
        obj.stopped_early = bool(stopped_early)
        obj.total = int(total)
        return obj

    def __array_finalize__(self, obj):
        self.keyframes = getattr(obj, "keyframes", np.zeros((0, 8)))
        self.per_frame = getattr(obj, "per_frame", {})
        self.stopped_early = getattr(obj, "stopped_early", False)
        self.total = getattr(obj, "total", 0)

    def __reduce__(self):  # pickles as the plain trajectory
        return np.asarray(self).__reduce__()

    @property
    def trajectory(self):
        return self.view(np.ndarray)


def _progress_callback(progress, fn):
    """(callback for _run_slam or None, close function) for run_slam's ``progress``."""
    if progress is None or progress is False:
        return None, lambda: None
    if callable(progress):
        return progress, lambda: None
    if progress is not True:
        raise TypeError(f"{fn}: progress must be True, False or a callable "
                        f"(got {type(progress).__name__})")
    try:
        from tqdm import tqdm
    except ImportError:
        tqdm = None
    state = {}

    def on_frame(result, done, total):
        if tqdm is not None:
            if "bar" not in state:
                state["bar"] = tqdm(total=total, unit="frame", desc="ds3d.run_slam")
            state["bar"].update(1)
            if done % 5 == 0 or done == total:
                state["bar"].set_postfix_str(result.state, refresh=False)
        elif done % 5 == 0 or done == total:
            sys.stderr.write(f"\rds3d.run_slam: {done}/{total} frames  {result.state}   ")
            sys.stderr.flush()
            state["line"] = True

    def close():
        if "bar" in state:
            state["bar"].close()
        if "line" in state:
            sys.stderr.write("\n")

    return on_frame, close


def run_slam(dataset_dir, camera=None, max_frames=0, config=None, dynamic=None, gate=None,
             weights=None, threaded=None, progress=False, **htx):
    """Runs the SLAM pipeline on a TUM-layout folder (rgb.txt, depth.txt), as ``ds3d-slam``.

    Args:
        dataset_dir: folder path (str or os.PathLike).
        camera: None (camera.txt in the folder, else the tum_ros preset), a ``ds3d.Camera``, a
            dict, a preset name (``tum1 tum2 tum3 tum_ros bonn``) or a camera.txt path.
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
        progress: False (default): silent; True: a tqdm progress bar when tqdm is installed,
            else a status line on stderr; a callable: called after every frame as
            ``progress(result, done, total)`` with the ``ds3d.TrackResult`` (raise
            KeyboardInterrupt in it to stop).
        **htx: shortcuts for ``htx.<name>`` keys: detect_every, min_score, hold_frames,
            segment_frames, segment_outside_boxes.

    Returns:
        ``ds3d.SlamResult``: the (N, 8) float64 trajectory (timestamp tx ty tz qx qy qz qw,
        camera-to-world, one row per frame) with ``.keyframes``, ``.per_frame``,
        ``.stopped_early``. Ctrl-C (KeyboardInterrupt) stops reading frames: the frames read so
        far are tracked and finished, and returned with ``stopped_early=True``.

    Raises:
        ValueError: bad arguments or keys; RuntimeError: unreadable dataset or weights file;
        whatever ``progress`` raises other than KeyboardInterrupt (after the run has stopped).
    """
    if int(max_frames) < 0:
        raise ValueError(f"ds3d.run_slam: max_frames must be >= 0 (got {max_frames})")
    cfg = _config_with(config, dynamic, gate, weights, threaded, htx, _HTX_SHORTCUTS)
    on_frame, close = _progress_callback(progress, "ds3d.run_slam")
    try:
        out = _run_slam(os.fspath(dataset_dir), camera, int(max_frames), cfg._core, on_frame)
    finally:
        close()
    return SlamResult(out["trajectory"], out["keyframes"], out["per_frame"],
                      out["stopped_early"], out["total"])
