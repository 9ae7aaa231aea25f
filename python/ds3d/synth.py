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
    "crowd_cross",
    "crowd_board",
    "crowd_start",
    "crowd_handheld",
)


def generate(out_dir, scenario="walking_xyz", frames=30, seed=1, humans=-1, fps=30.0,
             depth_noise=True, parts=False, room_size=(4.5, 5.0, 2.8), furniture=0,
             overwrite=False):
    """Writes a TUM-layout folder (rgb/, depth/, mask/, lists, groundtruth.txt, camera.txt,
    boxes.jsonl; parts/ and parts_loc/ with parts=True). room_size: the room's (x, y, z) extent
    [m], in [3.5, 12] x [3, 12] x [2.2, 5]; furniture: 0-12 extra chairs, tables and floor lamps.
    A non-empty out_dir is refused unless overwrite=True; the folder is written under a hidden
    sibling name and renamed into place at the end (an earlier one is removed only then).
    Returns a summary dict. Raises ValueError for bad arguments, RuntimeError when out_dir is
    not empty (without overwrite) or writing fails."""
    return _ds3d._synth_generate(str(out_dir), scenario, int(frames), int(seed), int(humans),
                                 float(fps), bool(depth_noise), bool(parts),
                                 [float(v) for v in room_size], int(furniture), bool(overwrite))


class Scene:
    """A procedural scene rendered frame by frame, deterministic by seed."""

    def __init__(self, scenario="walking_xyz", frames=30, seed=1, humans=-1, fps=30.0,
                 depth_noise=True, room_size=(4.5, 5.0, 2.8), furniture=0):
        """room_size: (x, y, z) extent of the room [m] (x ahead of the start pose, y across, z up),
        in [3.5, 12] x [3, 12] x [2.2, 5]; furniture: 0-12 extra free-standing chairs, tables
        and floor lamps (their own random stream: the rest of the scene does not change)."""
        self._scene = _ds3d._SyntheticScene(scenario, int(frames), int(seed), int(humans),
                                            float(fps), bool(depth_noise),
                                            [float(v) for v in room_size], int(furniture))

    def __len__(self):
        return len(self._scene)

    def render(self, i):
        """Frame i as a dict of numpy arrays plus 'boxes' (list of dicts) and 'T_world_cam'."""
        return self._scene.render(int(i))
