# SPDX-License-Identifier: Apache-2.0
# SPDX-FileCopyrightText: 2026 ds3d authors
"""ds3d.synth: a generated folder reads back through RgbdDataset; rendering is deterministic."""
import numpy as np
import pytest

import ds3d


def test_generate_and_read_back(tmp_path):
    s = ds3d.synth.generate(tmp_path / "seq", scenario="walking_xyz", frames=3, seed=2)
    assert s["frames"] == 3 and s["dynamic_pixels"] > 0
    ds = ds3d.RgbdDataset(str(tmp_path / "seq"))
    assert len(ds) == 3
    f = ds.frame(1)
    assert f["rgb"].shape == (480, 640, 3) and f["rgb"].dtype == np.uint8
    assert f["depth"].dtype == np.uint16
    assert ds.camera["fx"] == 525.0
    assert ds.groundtruth_path.endswith("groundtruth.txt")
    r = ds3d.synth.Scene("walking_xyz", frames=3, seed=2).render(1)
    np.testing.assert_array_equal(r["rgb"], f["rgb"])
    np.testing.assert_array_equal(r["depth"], f["depth"])
    assert (r["dynamic_mask"] > 0).sum() == sum(b["visible_pixels"] for b in r["boxes"])
    assert r["T_world_cam"].shape == (4, 4)


def test_presets_and_bad_arguments():
    assert ds3d.camera_preset("tum3")["fx"] == 535.4
    with pytest.raises(ValueError, match="unknown name"):
        ds3d.camera_preset("kinect")
    with pytest.raises(ValueError, match="scenario"):
        ds3d.synth.Scene("flying")
    with pytest.raises(ValueError, match="num_frames"):
        ds3d.synth.Scene("walking_xyz", frames=0)
    with pytest.raises(RuntimeError):
        ds3d.RgbdDataset("/nonexistent/folder")


def test_room_size_and_furniture():
    base = ds3d.synth.Scene("walking_xyz", frames=10, seed=4).render(5)
    same = ds3d.synth.Scene("walking_xyz", frames=10, seed=4, room_size=(4.5, 5.0, 2.8),
                            furniture=0).render(5)
    np.testing.assert_array_equal(base["rgb"], same["rgb"])
    clutter = ds3d.synth.Scene("walking_xyz", frames=10, seed=4, furniture=6).render(5)
    assert [b["center"] for b in clutter["boxes"]] == [b["center"] for b in base["boxes"]]
    assert (clutter["depth"] != base["depth"]).sum() > 1000
    big = ds3d.synth.Scene("static_room", frames=1, seed=4, room_size=(6.0, 7.0, 3.0)).render(0)
    assert not np.array_equal(big["depth"], ds3d.synth.Scene("static_room", frames=1, seed=4).render(0)["depth"])
    with pytest.raises(ValueError, match="room_size"):
        ds3d.synth.Scene("walking_xyz", room_size=(2.0, 5.0, 2.8))
    with pytest.raises(ValueError, match="room_size"):
        ds3d.synth.Scene("walking_xyz", room_size=(4.5, 5.0))
    with pytest.raises(ValueError, match="extra_furniture"):
        ds3d.synth.Scene("walking_xyz", furniture=20)
