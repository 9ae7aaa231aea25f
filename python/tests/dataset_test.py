# SPDX-License-Identifier: Apache-2.0
# SPDX-FileCopyrightText: 2026 ds3d authors
"""ds3d.RgbdDataset (include/ds3d/dataset.hpp) on a tiny TUM-layout folder written here."""
import struct
import zlib

import numpy as np
import pytest

import ds3d


def write_png(path, img):
    """Minimal PNG writer (no PIL/cv2 needed): (H, W, 3) uint8 RGB or (H, W) uint16 grey."""
    if img.dtype == np.uint8:
        h, w, _ = img.shape
        ihdr = struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0)
        rows = img.tobytes()
        stride = w * 3
    else:
        h, w = img.shape
        ihdr = struct.pack(">IIBBBBB", w, h, 16, 0, 0, 0, 0)
        rows = img.astype(">u2").tobytes()
        stride = w * 2
    raw = b"".join(b"\x00" + rows[y * stride:(y + 1) * stride] for y in range(h))

    def chunk(tag, data):
        return struct.pack(">I", len(data)) + tag + data + struct.pack(">I", zlib.crc32(tag + data))

    path.write_bytes(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IDAT", zlib.compress(raw))
                     + chunk(b"IEND", b""))


@pytest.fixture()
def folder(tmp_path):
    rng = np.random.default_rng(7)
    h, w = 24, 32
    (tmp_path / "rgb").mkdir()
    (tmp_path / "depth").mkdir()
    imgs = []
    for i, t in enumerate((1.0, 1.1, 1.2)):
        rgb = rng.integers(0, 256, (h, w, 3), dtype=np.uint8)
        write_png(tmp_path / "rgb" / f"{i}.png", rgb)
        imgs.append(rgb)
    depths = []
    for i, t in enumerate((1.005, 1.104, 1.3)):  # the last one has no rgb partner within 0.02 s
        d = rng.integers(0, 60000, (h, w), dtype=np.uint16)
        write_png(tmp_path / "depth" / f"{i}.png", d)
        depths.append(d)
    (tmp_path / "rgb.txt").write_text("# rgb\n1.0 rgb/0.png\n1.1 rgb/1.png\n1.2 rgb/2.png\n")
    (tmp_path / "depth.txt").write_text("# depth\n1.005 depth/0.png\n1.104 depth/1.png\n1.3 depth/2.png\n")
    (tmp_path / "camera.txt").write_text("fx 30\nfy 31\ncx 15.5\ncy 11.5\nwidth 32\nheight 24\n"
                                         "depth_scale 1000\n")
    (tmp_path / "groundtruth.txt").write_text("# t tx ty tz qx qy qz qw\n"
                                              "1.0 0 0 0 0 0 0 1\n1.1 0.1 0 0 0 0 0 1\n")
    return tmp_path, imgs, depths


def test_frames_camera_and_groundtruth(folder):
    path, imgs, depths = folder
    ds = ds3d.RgbdDataset(path)
    assert len(ds) == 2  # the third rgb and depth stamps are 0.1 s apart
    assert np.allclose(ds.timestamps, [1.0, 1.1]) and np.allclose(ds.depth_timestamps, [1.005, 1.104])
    assert ds.rgb_files == ["rgb/0.png", "rgb/1.png"] and ds.depth_files[1] == "depth/1.png"
    for i, f in enumerate(ds):
        assert f["index"] == i and f["timestamp"] == pytest.approx(1.0 + 0.1 * i)
        assert f["rgb"].shape == (24, 32, 3) and f["rgb"].dtype == np.uint8
        assert np.array_equal(f["rgb"], imgs[i][:, :, ::-1])  # BGR, as cv::imread
        assert f["depth"].dtype == np.uint16 and np.array_equal(f["depth"], depths[i])
    assert np.array_equal(ds[-1]["depth"], ds.frame(1)["depth"])
    cam = ds.camera
    assert (cam["fx"], cam["fy"], cam["width"], cam["height"], cam["depth_scale"]) == (30, 31, 32, 24, 1000)
    gt = ds.groundtruth()
    assert gt.shape == (2, 8) and gt[1, 1] == pytest.approx(0.1)
    assert ds.groundtruth_path.endswith("groundtruth.txt")
    assert "2 frames" in repr(ds)


def test_options_and_errors(folder, tmp_path_factory):
    path, _, _ = folder
    assert len(ds3d.RgbdDataset(path, max_difference=0.2)) == 3
    shifted = ds3d.RgbdDataset(path, offset=-0.1, max_difference=0.0055)  # depth stamps - 0.1 s
    assert np.allclose(shifted.timestamps, [1.0, 1.2]) and np.allclose(shifted.depth_timestamps, [1.104, 1.3])
    cam = dict(ds3d.camera_preset("tum_ros"), width=32, height=24)
    assert ds3d.RgbdDataset(path, camera=cam).camera["fx"] == 525.0
    assert ds3d.RgbdDataset(path, camera="bonn").camera == ds3d.camera_preset("bonn")
    ds = ds3d.RgbdDataset(path)
    with pytest.raises(IndexError):
        ds[2]
    with pytest.raises(IndexError):
        ds[-3]
    with pytest.raises(ValueError):
        ds.frame(2)
    with pytest.raises(ValueError, match="max_difference"):
        ds3d.RgbdDataset(path, max_difference=-1.0)
    with pytest.raises(ValueError, match="fx"):
        ds3d.RgbdDataset(path, camera={"fx": -1.0, "fy": 1.0, "cx": 0.0, "cy": 0.0})
    with pytest.raises(ValueError, match="lacks 'cy'"):
        ds3d.RgbdDataset(path, camera={"fx": 1.0, "fy": 1.0, "cx": 0.0})
    with pytest.raises(RuntimeError):
        ds3d.RgbdDataset(path / "missing")
    empty = tmp_path_factory.mktemp("nogt")
    (empty / "rgb.txt").write_text("")
    (empty / "depth.txt").write_text("")
    e = ds3d.RgbdDataset(empty)
    assert len(e) == 0 and e.groundtruth() is None and e.groundtruth_path is None
    (path / "rgb" / "1.png").write_bytes(b"not a png")
    with pytest.raises(RuntimeError):
        ds[1]
