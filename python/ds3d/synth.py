# SPDX-License-Identifier: Apache-2.0
# SPDX-FileCopyrightText: 2026 ds3d authors
"""Synthetic dynamic RGB-D sequences (C++: include/ds3d/synth.hpp).

>>> import ds3d
>>> ds3d.synth.generate("/tmp/seq", scenario="walking_xyz", frames=30, seed=1)
>>> scene = ds3d.synth.Scene("sitting_static", frames=10)
>>> f = scene.render(0)   # dict: rgb, depth, depth_true, dynamic_mask, human_id, part_id, boxes, ...
"""
from . import _ds3d

SCENARIOS = (
    "static_room",
    "walking_static",
    "walking_xyz",
    "walking_halfsphere",
    "walking_rpy",
    "sitting_static",
    "sitting_xyz",
)


def generate(out_dir, scenario="walking_xyz", frames=30, seed=1, humans=-1, fps=30.0,
             depth_noise=True, parts=False):
    """Writes a TUM-layout folder (rgb/, depth/, mask/, lists, groundtruth.txt, camera.txt,
    boxes.jsonl; parts/ and parts_loc/ with parts=True). Returns a summary dict.
    Raises ValueError for bad arguments, RuntimeError when writing fails."""
    return _ds3d._synth_generate(str(out_dir), scenario, int(frames), int(seed), int(humans),
                                 float(fps), bool(depth_noise), bool(parts))


class Scene:
    """A procedural scene rendered frame by frame, deterministic by seed."""

    def __init__(self, scenario="walking_xyz", frames=30, seed=1, humans=-1, fps=30.0,
                 depth_noise=True):
        self._scene = _ds3d._SyntheticScene(scenario, int(frames), int(seed), int(humans),
                                            float(fps), bool(depth_noise))

    def __len__(self):
        return len(self._scene)

    def render(self, i):
        """Frame i as a dict of numpy arrays plus 'boxes' (list of dicts) and 'T_world_cam'."""
        return self._scene.render(int(i))
