# SPDX-License-Identifier: Apache-2.0
# SPDX-FileCopyrightText: 2026 ds3d authors
import numpy as np
import pytest

import ds3d

CAMERA = ds3d.Camera(525.0, 525.0, 319.5, 239.5)  # 640 x 480


def test_person_in_front_of_wall():
    rng = np.random.default_rng(1)
    wall = np.column_stack([rng.uniform(0, 639, 800), rng.uniform(0, 479, 800), np.full(800, 3.0)])
    inside = (wall[:, 0] >= 200) & (wall[:, 0] <= 330) & (wall[:, 1] >= 100)
    wall = wall[~inside]
    person = np.column_stack([rng.uniform(200, 330, 200), rng.uniform(100, 470, 200),
                              1.5 + rng.uniform(-0.15, 0.15, 200)])
    kp = np.vstack([wall, person]).astype(np.float32)
    f = ds3d.DynamicFeatureFilter()
    r = f.filter(kp, [ds3d.ImageBox(200, 100, 330, 470, score=0.9)], CAMERA)
    dyn = np.asarray(r.dynamic, dtype=bool)
    assert dyn[len(wall):].mean() >= 0.95
    assert dyn[:len(wall)].mean() <= 0.02


def test_bad_params_raise_value_error():
    p = ds3d.DynamicFilterParams()
    p.min_cluster_size = 1
    with pytest.raises(ValueError, match="min_cluster_size"):
        ds3d.DynamicFeatureFilter(p)


def test_support_plane_and_solid_box():
    # Camera 1.2 m above a textured floor (y down: floor y = 1.2 m); a person 2.5 m ahead in a
    # loose box that reaches below the feet: with the floor plane, floor keypoints stay static.
    rng = np.random.default_rng(3)
    f, cx, cy = 525.0, 319.5, 239.5

    def project(x, y, z):
        return np.column_stack([f * x / z + cx, f * y / z + cy, z])

    z = rng.uniform(1.0, 5.0, 1500)
    floor = project(rng.uniform(-2, 2, 1500), np.full(1500, 1.2), z)
    zp = 2.5 + rng.uniform(-0.15, 0.15, 300)
    person = project(rng.uniform(-0.25, 0.25, 300), rng.uniform(-0.5, 1.2, 300), zp)
    kp = np.vstack([floor, person]).astype(np.float32)
    ok = (kp[:, 0] >= 0) & (kp[:, 0] <= 639) & (kp[:, 1] >= 0) & (kp[:, 1] <= 479)
    is_floor = np.arange(len(kp)) < len(floor)
    kp, is_floor = kp[ok], is_floor[ok]
    loose = ds3d.ImageBox(cx - f * 0.65 / 2.5, cy + f * -0.6 / 2.5, cx + f * 0.65 / 2.5,
                          cy + f * 1.5 / 2.5, score=0.9)
    plain = np.asarray(ds3d.DynamicFeatureFilter().filter(kp, [loose], CAMERA).dynamic, bool)
    r = ds3d.DynamicFeatureFilter().filter(kp, [loose], CAMERA, support_plane=[0, -1, 0, 1.2])
    dyn = np.asarray(r.dynamic, bool)
    assert (plain & is_floor).sum() > 20  # the failure the plane fixes
    assert not (dyn & is_floor).any() and r.num_on_support > 20
    assert dyn[~is_floor].mean() >= 0.9
    gated = np.asarray(r.gated, bool)  # went into the box's clustering: the person, not the floor
    assert not (gated & is_floor).any() and gated[~is_floor].mean() >= 0.9
    with pytest.raises(ValueError, match="support_plane"):
        ds3d.DynamicFeatureFilter().filter(kp, [loose], CAMERA, support_plane=[0, 0, 0, 1])

    # SolidBox from cuboid corners (any order); a point beside the box is outside it.
    corners = np.array([[x, y, zz] for x in (-0.3, 0.3) for y in (-0.85, 0.85)
                        for zz in (2.0, 3.0)], np.float32)[[3, 0, 6, 1, 7, 2, 5, 4]]
    solid = ds3d.solid_from_corners(corners, margin=0.05)
    assert solid is not None and np.allclose(solid.centre, [0, 0, 2.5], atol=1e-5)
    assert np.allclose(sorted(solid.half), [0.3, 0.5, 0.85], atol=1e-5)
    assert solid.contains([0.32, 0.0, 2.9]) and not solid.contains([0.4, 0.0, 2.9])
    bent = corners.copy()
    bent[0, 0] += 0.1
    assert ds3d.solid_from_corners(bent) is None
    box = ds3d.ImageBox(100, 0, 500, 479, score=0.9, z_min=2.0, z_max=3.0)
    assert box.solid is None
    box.solid = solid
    assert box.solid is not None and box.solid.margin == pytest.approx(0.05)
    p = ds3d.DynamicFilterParams()
    p.support_margin = -1
    with pytest.raises(ValueError, match="support_margin"):
        ds3d.DynamicFeatureFilter(p)


def test_camera_forms():
    rng = np.random.default_rng(2)
    kp = np.column_stack([rng.uniform(0, 639, 300), rng.uniform(0, 479, 300),
                          rng.uniform(1, 3, 300)]).astype(np.float32)
    boxes = [ds3d.ImageBox(100, 100, 300, 400, score=0.9)]
    ref = np.asarray(ds3d.DynamicFeatureFilter().filter(kp, boxes, CAMERA).dynamic)
    for cam in (CAMERA.to_dict(), {"fx": 525, "fy": 525, "cx": 319.5, "cy": 239.5}):
        r = ds3d.DynamicFeatureFilter().filter(kp, boxes, camera=cam)
        assert np.array_equal(np.asarray(r.dynamic), ref)
    r = ds3d.DynamicFeatureFilter().filter(kp, boxes, fx=525, fy=525, cx=319.5, cy=239.5)
    assert np.array_equal(np.asarray(r.dynamic), ref)  # the explicit keyword form still works
    with pytest.raises(TypeError, match="camera is required"):
        ds3d.DynamicFeatureFilter().filter(kp, boxes)
    with pytest.raises(ValueError, match="not both"):
        ds3d.DynamicFeatureFilter().filter(kp, boxes, CAMERA, fx=500, fy=500, cx=1, cy=1)
    with pytest.raises(ValueError, match="fx"):
        ds3d.DynamicFeatureFilter().filter(kp, boxes, {"fx": -1, "fy": 1, "cx": 0, "cy": 0})
