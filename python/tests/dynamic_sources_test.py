# SPDX-License-Identifier: Apache-2.0
# SPDX-FileCopyrightText: 2026 ds3d authors
"""ds3d.FileSource, HdbscanMasker, DynamicObjects, image_boxes, keypoint_array and
make_dynamic_source (include/ds3d/dynamic_sources.hpp)."""
import json

import numpy as np
import pytest

import ds3d
from textured_images import textured

CAM = ds3d.camera_preset("tum_ros")  # 640 x 480, depth_scale 5000
CORNERS = [[x, y, z] for x in (-0.2, 0.2) for y in (-0.5, 0.5) for z in (2.0, 2.4)]


@pytest.fixture()
def detections(tmp_path):
    lines = [
        {"timestamp": 1.0, "boxes": [
            {"bbox": [10, 20, 110, 220], "score": 0.9, "class": "person"},
            {"corners": CORNERS, "score": 0.5, "class": "chair"}]},
        {"timestamp": 2.0, "boxes": []},
    ]
    path = tmp_path / "det.jsonl"
    path.write_text("# test\n" + "\n".join(json.dumps(x) for x in lines) + "\n")
    return path


def test_file_source_round_trip(detections):
    rgb = np.zeros((480, 640, 3), np.uint8)
    src = ds3d.FileSource(detections)
    assert src.name == "file" and isinstance(src, ds3d.DynamicObjectSource)
    o = src.detect(rgb, None, CAM, 1.005)
    assert np.allclose(o.boxes_2d, [[10, 20, 110, 220]]) and np.allclose(o.scores, [0.9])
    assert o.boxes_3d.shape == (1, 8, 3) and np.allclose(o.boxes_3d[0], CORNERS)
    assert o.pixel_mask is None and not o.empty
    assert src.detect(rgb, None, CAM, 1.5).empty  # no line within max_dt = 0.02 s
    assert src.detect(rgb, None, CAM, 2.0).empty  # a line with no boxes
    assert (src.num_matched, src.num_unmatched) == (2, 1)
    assert src.num_carried == 0  # no depth image: nothing to follow a box by
    p = ds3d.FileSourceParams()
    p.classes = ["person"]
    only = ds3d.FileSource(str(detections), p).detect(rgb, None, CAM, 1.0)
    assert len(only.boxes_2d) == 1 and len(only.boxes_3d) == 0
    p = ds3d.FileSourceParams()
    p.min_score = 0.95
    assert ds3d.FileSource(detections, p).detect(rgb, None, CAM, 1.0).empty
    p = ds3d.FileSourceParams()
    p.max_dt = 0.6
    assert not ds3d.FileSource(detections, p).detect(rgb, None, CAM, 1.5).empty
    via_spec = ds3d.make_dynamic_source(f"file:{detections}").detect(rgb, None, CAM, 1.0)
    assert np.array_equal(via_spec.boxes_3d, o.boxes_3d)
    text = ds3d.FileSource.from_text(detections.read_text()).detect(rgb, None, CAM, 1.0)
    assert np.array_equal(text.boxes_2d, o.boxes_2d)


def test_image_boxes_and_keypoint_array(detections):
    rgb = textured(4)
    o = ds3d.FileSource(detections).detect(rgb, None, CAM, 1.0)
    boxes = ds3d.image_boxes(o, CAM)
    assert len(boxes) == 2
    assert (boxes[0].x_min, boxes[0].y_max, boxes[0].score) == pytest.approx((10, 220, 0.9))
    b = boxes[1]  # the projected 3-D box: x in [-0.2, 0.2] m at 2-2.4 m, centred on cx
    assert b.z_max > 0  # carries a depth range
    assert 2.0 - 1e-4 <= b.z_min < b.z_max <= 2.4 + 1e-4
    assert b.x_min == pytest.approx(319.5 - 525 * 0.2 / 2.0, abs=0.5)
    assert b.x_max == pytest.approx(319.5 + 525 * 0.2 / 2.0, abs=0.5)
    depth = np.full((480, 640), 10000, np.uint16)
    f = ds3d.OrbExtractor().extract(rgb, depth, CAM)
    kp = ds3d.keypoint_array(f, depth, CAM)
    assert kp.shape == (len(f), 3) and kp.dtype == np.float32
    assert np.array_equal(kp[:, :2], f.keypoints) and np.allclose(kp[:, 2], 2.0)
    assert np.allclose(ds3d.keypoint_array(f, None, CAM)[:, 2], f.depth)
    assert boxes[1].solid is None  # a file's 3-D box has no metric uncertainty
    # With one, image_boxes makes the oriented box the masker gates in 3-D.
    o3 = ds3d.DynamicObjects(boxes_3d=[CORNERS], boxes_3d_margin=[0.1],
                             support_plane=[0, -1, 0, 1.2])
    assert np.allclose(o3.boxes_3d_margin, [0.1]) and np.allclose(o3.support_plane, [0, -1, 0, 1.2])
    s = ds3d.image_boxes(o3, CAM)[0].solid
    assert s is not None and s.margin == pytest.approx(0.1)
    assert np.allclose(sorted(s.half), [0.2, 0.2, 0.5], atol=1e-5)
    loose = ds3d.DynamicObjects(boxes_3d=[CORNERS], boxes_3d_margin=[np.inf])
    assert ds3d.image_boxes(loose, CAM)[0].solid is None
    assert ds3d.DynamicObjects().support_plane is None
    assert ds3d.DynamicObjects().ego_motion is None
    step = np.eye(4)
    step[:3, 3] = [0.01, 0, 0]
    t, T = ds3d.DynamicObjects(ego_motion=(1.5, step)).ego_motion
    assert t == 1.5 and np.array_equal(T, step)
    with pytest.raises(ValueError, match="ego_motion's T_cur_ref must be a finite rigid"):
        ds3d.DynamicObjects(ego_motion=(1.5, 2 * step))
    with pytest.raises(ValueError, match=r"ego_motion's T_cur_ref must be a \(4, 4\)"):
        ds3d.DynamicObjects(ego_motion=(1.5, np.eye(3)))
    with pytest.raises(ValueError, match="ego_motion must be a tuple"):
        ds3d.DynamicObjects(ego_motion=step)
    with pytest.raises(ValueError, match="reference_timestamp must be finite"):
        ds3d.DynamicObjects(ego_motion=(np.nan, step))
    with pytest.raises(ValueError, match="boxes_3d_margin"):
        ds3d.DynamicObjects(boxes_3d=[CORNERS], boxes_3d_margin=[0.1, 0.2])
    with pytest.raises(ValueError, match="boxes_3d_margin"):
        ds3d.DynamicObjects(boxes_3d=[CORNERS], boxes_3d_margin=[-0.1])
    with pytest.raises(ValueError, match="support_plane"):
        ds3d.DynamicObjects(support_plane=[0, 0, 0, 1])


def test_hdbscan_masker_flags_the_near_object_in_its_box():
    rgb = textured(5)
    depth = np.full((480, 640), 15000, np.uint16)  # wall at 3 m
    depth[120:380, 240:400] = 7500  # an object at 1.5 m
    f = ds3d.OrbExtractor().extract(rgb, depth, CAM)
    kp = f.keypoints
    box = np.array([[220, 100, 420, 400]], np.float32)
    objects = ds3d.DynamicObjects(boxes_2d=box, scores=[0.9])
    masker = ds3d.HdbscanMasker()
    dyn = masker.mask(rgb, depth, CAM, f, objects, timestamp=0.0)
    assert dyn.dtype == bool and dyn.shape == (len(f),)
    on_object = (kp[:, 0] > 244) & (kp[:, 0] < 396) & (kp[:, 1] > 124) & (kp[:, 1] < 376)
    in_box = (kp[:, 0] >= 220) & (kp[:, 0] <= 420) & (kp[:, 1] >= 100) & (kp[:, 1] <= 400)
    assert on_object.sum() > 30
    assert dyn[on_object].mean() > 0.9
    assert not dyn[~in_box].any()  # nothing outside the box
    assert not dyn[in_box & (f.depth > 2.5)].any()  # the wall behind the object stays
    assert masker.last_result.num_dynamic == dyn.sum()
    # A pixel mask alone marks exactly the keypoints on its non-zero pixels.
    mask = np.zeros((480, 640), np.uint8)
    mask[:, :320] = 1
    dyn2 = ds3d.HdbscanMasker().mask(rgb, depth, CAM, f, ds3d.DynamicObjects(pixel_mask=mask))
    assert np.array_equal(dyn2, np.round(kp[:, 0]) < 320)
    assert ds3d.HdbscanMasker().mask(rgb, depth, CAM, f, ds3d.DynamicObjects()).sum() == 0


def test_bad_input_errors(detections, tmp_path):
    rgb = np.zeros((480, 640, 3), np.uint8)
    with pytest.raises(ValueError, match="boxes_2d row 0"):
        ds3d.DynamicObjects(boxes_2d=[[10, 10, 5, 20]])
    with pytest.raises(ValueError, match="boxes_2d row 0"):
        ds3d.DynamicObjects(boxes_2d=[[np.nan, 10, 15, 20]])
    with pytest.raises(ValueError, match="boxes_2d must be a \\(K, 4\\)"):
        ds3d.DynamicObjects(boxes_2d=np.zeros((2, 3)))
    with pytest.raises(ValueError, match="boxes_2d must be a \\(K, 4\\)"):
        ds3d.DynamicObjects(boxes_2d=[["a", "b", "c", "d"]])
    with pytest.raises(ValueError, match="scores"):
        ds3d.DynamicObjects(boxes_2d=[[0, 0, 1, 1]], scores=[0.5, 0.5])
    with pytest.raises(ValueError, match="scores\\[0\\]"):
        ds3d.DynamicObjects(boxes_2d=[[0, 0, 1, 1]], scores=[1.5])
    with pytest.raises(ValueError, match="boxes_3d must be a \\(K, 8, 3\\)"):
        ds3d.DynamicObjects(boxes_3d=np.zeros((1, 4, 3)))
    with pytest.raises(ValueError, match="pixel_mask must be .*bool"):
        ds3d.DynamicObjects(pixel_mask=np.zeros((480, 640), bool))
    src = ds3d.FileSource(detections)
    with pytest.raises(ValueError, match="detect \\(file\\): depth .*float32"):
        src.detect(rgb, np.zeros((480, 640), np.float32), CAM, 1.0)
    with pytest.raises(ValueError, match="timestamp must be finite"):
        src.detect(rgb, None, CAM, float("nan"))
    with pytest.raises(ValueError, match="camera must be a dict"):
        src.detect(rgb, None, [525.0], 1.0)
    # the (rgb, depth, timestamp, camera) order of earlier releases: a TypeError naming the order
    with pytest.raises(TypeError, match=r"depth: object, camera: object, timestamp: float"):
        src.detect(rgb, None, 1.0, CAM)
    with pytest.raises(TypeError, match=r"got float\); the order is detect\(rgb, depth, camera, timestamp"):
        src.detect(rgb, None, 1.0, 3)  # no camera at all
    f = ds3d.OrbExtractor().extract(rgb, None, CAM)
    with pytest.raises(TypeError, match=r"got OrbFeatures\); the order is mask\(rgb, depth, camera, features"):
        ds3d.HdbscanMasker().mask(rgb, None, f, f, ds3d.DynamicObjects())
    with pytest.raises(ValueError, match="keypoint_array: depth is 10x10"):
        ds3d.keypoint_array(f, np.zeros((10, 10), np.uint16), CAM)
    with pytest.raises(ValueError, match="objects.pixel_mask is 10x10"):
        ds3d.HdbscanMasker().mask(rgb, None, CAM, f, ds3d.DynamicObjects(pixel_mask=np.zeros((10, 10), np.uint8)))
    bad = ds3d.DynamicFilterParams()
    bad.min_cluster_size = 0
    with pytest.raises(ValueError, match="min_cluster_size"):
        ds3d.HdbscanMasker(bad)
    p = ds3d.FileSourceParams()
    p.min_score = 2.0
    with pytest.raises(ValueError, match="min_score"):
        p.validate()
    with pytest.raises(ValueError, match="min_score"):
        ds3d.FileSource(detections, p)
    p = ds3d.FileSourceParams()
    assert (p.hold_frames, p.hold_min_points, p.hold_seconds) == (10, 5, 0.5)
    assert p.hold_margin == pytest.approx(0.15)
    p.hold_frames = -1
    with pytest.raises(ValueError, match="hold_frames"):
        p.validate()
    broken = tmp_path / "broken.jsonl"
    broken.write_text('{"timestamp": 1.0, "boxes": [{"bbox": [1, 2, 3]}]}\n')
    with pytest.raises(RuntimeError, match="broken.jsonl"):
        ds3d.FileSource(broken)
    with pytest.raises(ValueError, match="bogus"):
        ds3d.make_dynamic_source("bogus")
    assert ds3d.make_dynamic_source("none").detect(rgb, None, CAM, 0.0).empty


def test_sources_keep_copies_not_views_of_the_frames():
    # GeometricMotionSource keeps past depth images; overwriting the caller's arrays after each
    # detect() must not change what it finds (it did when detect() passed numpy views).
    scene = ds3d.synth.Scene("walking_xyz", frames=8, seed=1)
    frames = [scene.render(i) for i in range(8)]

    def boxes(scribble):
        src = ds3d.make_dynamic_source("geometric")
        out = []
        for f in frames:
            rgb, depth = f["rgb"].copy(), f["depth"].copy()
            out.append(src.detect(rgb, depth, CAM, f["timestamp"]).boxes_3d)
            if scribble:
                rgb[:] = 7
                depth[:] = 1234
        return out

    clean, scribbled = boxes(False), boxes(True)
    assert sum(len(b) for b in clean) > 0
    assert all(np.array_equal(a, b) for a, b in zip(clean, scribbled))


def test_make_dynamic_source_builds_htx_and_composites():
    import pathlib
    weights = pathlib.Path(__file__).resolve().parents[2] / "tests" / "data" / "htx" / "tiny_weights.safetensors"
    f = ds3d.synth.Scene("walking_xyz", frames=1, seed=3).render(0)
    names = {"motion": "htx&geometric", "evidence": "htx&&geometric"}
    for spec, gate in (("htx", None), ("htx+geometric", None), ("geometric+htx", None),
                       ("htx", "motion"), ("htx", "evidence")):
        src = ds3d.make_dynamic_source(spec, gate=gate, weights=weights, min_score=0.0,
                                       report_floor=True)
        assert src.name == (names[gate] if gate else spec)
        o = src.detect(f["rgb"], f["depth"], CAM, f["timestamp"])
        assert o.boxes_3d.shape[1:] == (8, 3) and np.all(np.isfinite(o.boxes_3d))
        if spec == "htx" and gate is None:  # one metric uncertainty per box, the floor of the frame
            assert np.allclose(o.boxes_3d_margin, 0.15) and len(o.boxes_3d_margin) == len(o.boxes_3d)
            assert o.support_plane is not None and o.support_plane[1] < -0.8
        if gate is None:  # the gates need motion, which a first frame cannot show
            assert len(o.boxes_3d) > 0  # min_score 0 keeps the untrained fixture's boxes
    with pytest.raises(ValueError, match="htx&&htx"):  # gates are a separate setting now
        ds3d.make_dynamic_source("htx&&htx", weights=weights)
    with pytest.raises(ValueError, match="gate"):
        ds3d.make_dynamic_source("none", gate="motion")
    with pytest.raises(TypeError, match="no_such"):
        ds3d.make_dynamic_source("htx", weights=weights, no_such=1)
    with pytest.raises(RuntimeError, match="nonexistent"):
        ds3d.make_dynamic_source("htx", weights="/nonexistent/w.safetensors")
    with pytest.raises(ValueError, match="detect_every"):
        ds3d.make_dynamic_source("htx", weights=weights, detect_every=0)
    loose = ds3d.make_dynamic_source("htx", weights=weights, min_score=0.0,
                                     box_uncertainty=float("inf"))
    assert np.all(np.isinf(loose.detect(f["rgb"], f["depth"], CAM, f["timestamp"]).boxes_3d_margin))
    with pytest.raises(ValueError, match="box_uncertainty"):
        ds3d.make_dynamic_source("htx", weights=weights, box_uncertainty=-1.0)
    # The floor is reported only on request (report_floor, off by default).
    plain = ds3d.make_dynamic_source("htx", weights=weights, min_score=0.0)
    assert plain.detect(f["rgb"], f["depth"], CAM, f["timestamp"]).support_plane is None
    with pytest.raises(ValueError, match="hold_frames"):
        ds3d.make_dynamic_source("htx", weights=weights, hold_frames=-1)
    with pytest.raises(ValueError, match="segment_frames"):
        ds3d.make_dynamic_source("htx", weights=weights, segment_frames=-1)


def test_frame_smoothing_keeps_the_boxes():
    """segment_frames changes the foreground points, never the boxes."""
    import pathlib
    weights = pathlib.Path(__file__).resolve().parents[2] / "models" / "htx_lite_fast.safetensors"
    scene = ds3d.synth.Scene("sitting_static", frames=6, seed=7)
    kw = dict(weights=weights, report_floor=True, hold_frames=0)
    one = ds3d.make_dynamic_source("htx", segment_frames=0, **kw)
    smooth = ds3d.make_dynamic_source("htx", segment_frames=10, **kw)
    changed = 0
    for i in range(len(scene)):
        f = scene.render(i)
        a, b = (s.detect(f["rgb"], f["depth"], CAM, f["timestamp"], index=i)
                for s in (one, smooth))
        assert np.allclose(a.boxes_3d, b.boxes_3d)
        assert np.all(np.isfinite(b.foreground_points))
        changed += int(len(a.foreground_points) != len(b.foreground_points)
                       or not np.allclose(a.foreground_points, b.foreground_points))
    assert changed > 0  # from the second frame on, earlier frames' logits take part


def test_hold_carries_missed_boxes_of_seated_people():
    """hold_frames (default 30): boxes of earlier frames come after this frame's detections
    while the part head sees foreground in them; hold_frames=0 reports the detections only."""
    import pathlib
    weights = pathlib.Path(__file__).resolve().parents[2] / "models" / "htx_lite_fast.safetensors"
    scene = ds3d.synth.Scene("sitting_static", frames=12, seed=7)
    held = ds3d.make_dynamic_source("htx", weights=weights, report_floor=True)
    plain = ds3d.make_dynamic_source("htx", weights=weights, report_floor=True, hold_frames=0)
    carried = 0
    for i in range(len(scene)):
        f = scene.render(i)
        a = plain.detect(f["rgb"], f["depth"], CAM, f["timestamp"], index=i)
        b = held.detect(f["rgb"], f["depth"], CAM, f["timestamp"], index=i)
        assert len(b.boxes_3d) >= len(a.boxes_3d)
        assert np.allclose(b.boxes_3d[:len(a.boxes_3d)], a.boxes_3d)
        assert b.boxes_3d_segmented.all() and len(b.boxes_3d_margin) == len(b.boxes_3d)
        carried += len(b.boxes_3d) - len(a.boxes_3d)
    assert carried > 0


def test_segmentation_fields_and_the_masker_check():
    """foreground_points / boxes_3d_segmented round-trip, htx reports them (segment, default on)
    and the masker keeps a segmented box's dynamic keypoints only near the foreground."""
    import pathlib
    weights = pathlib.Path(__file__).resolve().parents[2] / "models" / "htx_lite_fast.safetensors"
    f = ds3d.synth.Scene("walking_xyz", frames=1, seed=7, humans=1).render(0)
    src = ds3d.make_dynamic_source("htx", weights=weights)
    o = src.detect(f["rgb"], f["depth"], CAM, f["timestamp"])
    assert len(o.boxes_3d) > 0 and o.boxes_3d_segmented.dtype == bool and o.boxes_3d_segmented.all()
    fg = o.foreground_points
    assert fg.shape[1] == 3 and len(fg) > 20 and fg.dtype == np.float32
    u = np.round(525 * fg[:, 0] / fg[:, 2] + 319.5).astype(int).clip(0, 639)
    v = np.round(525 * fg[:, 1] / fg[:, 2] + 239.5).astype(int).clip(0, 479)
    assert (f["dynamic_mask"][v, u] > 0).mean() > 0.8  # the points lie on the walker
    off = ds3d.make_dynamic_source("htx", weights=weights, segment=False)
    o2 = off.detect(f["rgb"], f["depth"], CAM, f["timestamp"])
    assert len(o2.foreground_points) == 0 and len(o2.boxes_3d_segmented) == 0
    bg = o.background_points  # the other input points of the network
    assert bg.shape[1] == 3 and len(bg) > len(fg) and len(o2.background_points) == 0
    assert np.allclose(o2.boxes_3d, o.boxes_3d)
    # The masker: the same box with no foreground near the walker keeps everything static.
    feats = ds3d.OrbExtractor().extract(f["rgb"], f["depth"], CAM)
    with_fg = ds3d.HdbscanMasker().mask(f["rgb"], f["depth"], CAM, feats, o)
    far = ds3d.DynamicObjects(boxes_3d=o.boxes_3d, boxes_3d_margin=o.boxes_3d_margin,
                              foreground_points=[[9.0, 9.0, 9.0]],
                              boxes_3d_segmented=np.ones(len(o.boxes_3d), bool))
    assert with_fg.sum() > 0
    assert ds3d.HdbscanMasker().mask(f["rgb"], f["depth"], CAM, feats, far).sum() == 0
    kp = feats.keypoints.round().astype(int)
    on = f["dynamic_mask"][kp[:, 1].clip(0, 479), kp[:, 0].clip(0, 639)] > 0
    without = ds3d.HdbscanMasker().mask(f["rgb"], f["depth"], CAM, feats, o2)
    assert on[with_fg].mean() > on[without].mean() + 0.1  # fewer keypoints off the walker
    # With the floor reported too, the dynamic keypoints are (nearly) all on the walker.
    floor = ds3d.make_dynamic_source("htx", weights=weights, report_floor=True)
    o3 = floor.detect(f["rgb"], f["depth"], CAM, f["timestamp"])
    dyn3 = ds3d.HdbscanMasker().mask(f["rgb"], f["depth"], CAM, feats, o3)
    assert dyn3.sum() > 10 and on[dyn3].mean() > 0.9
    with pytest.raises(ValueError, match="boxes_3d_segmented"):
        ds3d.DynamicObjects(boxes_3d=o.boxes_3d, boxes_3d_segmented=[True] * (len(o.boxes_3d) + 1))
    with pytest.raises(ValueError, match="foreground_points"):
        ds3d.DynamicObjects(foreground_points=np.zeros((3, 2)))
    with pytest.raises(ValueError, match="background_points"):
        ds3d.DynamicObjects(background_points=np.zeros((3, 4)))
    # Background points right on the foreground points: every tie goes to the foreground
    # (nearest foreground no farther than nearest background), so the radius alone decides.
    kw = dict(boxes_3d=o.boxes_3d, boxes_3d_margin=o.boxes_3d_margin, foreground_points=fg,
              boxes_3d_segmented=np.ones(len(o.boxes_3d), bool))
    radius_only = ds3d.HdbscanMasker().mask(f["rgb"], f["depth"], CAM, feats, ds3d.DynamicObjects(**kw))
    tie = ds3d.DynamicObjects(background_points=fg, **kw)
    assert tie.background_points.shape == fg.shape
    assert (ds3d.HdbscanMasker().mask(f["rgb"], f["depth"], CAM, feats, tie) == radius_only).all()
    # The network's own background points can only take keypoints away (inside the boxes).
    inside = ds3d.make_dynamic_source("htx", weights=weights, segment_outside_boxes=False)
    o4 = inside.detect(f["rgb"], f["depth"], CAM, f["timestamp"])
    assert not o4.segment_outside_boxes and len(o4.foreground_points) >= len(fg)
    assert len(o4.foreground_points) + len(o4.background_points) == len(fg) + len(bg)
    in_boxes = ds3d.HdbscanMasker().mask(f["rgb"], f["depth"], CAM, feats, o4)
    assert not (in_boxes & ~radius_only).any()
    with pytest.raises(ValueError, match="foreground_radius"):
        ds3d.DynamicObjects(foreground_radius=0.0)
    # By default the segmentation covers the frame, with the floor preprocess removed: it adds
    # keypoints outside the boxes, never takes any away.
    assert o.segment_outside_boxes and o.support_plane is None
    assert o.segment_plane is not None and o.segment_plane[1] < -0.8
    assert np.linalg.norm(o.segment_plane[:3]) == pytest.approx(1.0, abs=1e-5)
    assert o2.segment_plane is None and not o2.segment_outside_boxes
    assert not (in_boxes & ~with_fg).any()
    assert on[with_fg].mean() > 0.9
    kw_all = dict(kw, background_points=bg, segment_plane=o.segment_plane)
    rebuilt = ds3d.DynamicObjects(segment_outside_boxes=True, **kw_all)
    assert rebuilt.segment_outside_boxes and np.allclose(rebuilt.segment_plane, o.segment_plane)
    assert (ds3d.HdbscanMasker().mask(f["rgb"], f["depth"], CAM, feats, rebuilt) == with_fg).all()
    assert ds3d.DynamicObjects().segment_plane is None
    assert not ds3d.DynamicObjects().segment_outside_boxes
    for bad in ([0, 0, 0, 1], [0, np.nan, 0, 1], [0, 1, 0]):
        with pytest.raises(ValueError, match="segment_plane"):
            ds3d.DynamicObjects(segment_plane=bad)
    # The reported foreground is connected to the boxes: anchoring it again moves nothing.
    again, moved = ds3d.keep_anchored_foreground(o, 0.15)
    assert moved == 0 and np.allclose(again.foreground_points, o.foreground_points)
    # A far-away patch with the walker's foreground moves to the background, nothing else.
    patch = np.array([[5.0, 0.0, 6.0], [5.1, 0.0, 6.0]], np.float32)
    extra = ds3d.DynamicObjects(boxes_3d=o.boxes_3d, foreground_points=np.vstack([fg, patch]),
                                background_points=bg, foreground_radius=o.foreground_radius)
    kept, moved = ds3d.keep_anchored_foreground(extra, 0.15)
    assert moved == 2 and len(extra.foreground_points) == len(fg) + 2  # the input is unchanged
    assert np.allclose(kept.foreground_points, fg) and np.allclose(kept.background_points[-2:], patch)
    with pytest.raises(ValueError, match="margin"):
        ds3d.keep_anchored_foreground(o, -1.0)
