# SPDX-License-Identifier: Apache-2.0
# SPDX-FileCopyrightText: 2026 ds3d authors
import numpy as np
import pytest

import ds3d


def test_person_in_front_of_wall():
    rng = np.random.default_rng(1)
    wall = np.column_stack([rng.uniform(0, 639, 800), rng.uniform(0, 479, 800), np.full(800, 3.0)])
    inside = (wall[:, 0] >= 200) & (wall[:, 0] <= 330) & (wall[:, 1] >= 100)
    wall = wall[~inside]
    person = np.column_stack([rng.uniform(200, 330, 200), rng.uniform(100, 470, 200),
                              1.5 + rng.uniform(-0.15, 0.15, 200)])
    kp = np.vstack([wall, person]).astype(np.float32)
    f = ds3d.DynamicFeatureFilter()
    r = f.filter(kp, [ds3d.ImageBox(200, 100, 330, 470, score=0.9)])
    dyn = np.asarray(r.dynamic, dtype=bool)
    assert dyn[len(wall):].mean() >= 0.95
    assert dyn[:len(wall)].mean() <= 0.02


def test_bad_params_raise_value_error():
    p = ds3d.DynamicFilterParams()
    p.min_cluster_size = 1
    with pytest.raises(ValueError, match="min_cluster_size"):
        ds3d.DynamicFeatureFilter(p)
