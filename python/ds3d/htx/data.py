# SPDX-License-Identifier: Apache-2.0
# SPDX-FileCopyrightText: 2026 ds3d authors
"""Training and test data for HTx-lite from the synthetic generator (docs/htx_training.md).

Each frame is rendered by ``ds3d.synth`` (TUM-like camera motions, 0-4 humanoids, Kinect-like depth
noise), preprocessed by exactly the call used at inference (``ds3d.preprocess`` with its defaults:
stride 2, 0.1 m voxels, RANSAC ground removal, radius outliers), and turned into the detector's
frame with :func:`gravity_rotation` (spec §6.1 step 3). Labels are the humanoids' boxes in the
same upright frame (spec §2 box convention) and Part-A2 point targets (``targets.part_targets``).

Upright frame (ours, the contract with the SLAM wiring): origin at the camera; Z = the floor
plane's normal pointing to the camera's side; Y = the camera's optical axis projected onto the
horizontal plane; X = Y x Z (image right). ``p_up = R_up_cam @ p_cam``; boxes map back with R.T.

Frames are stored in compressed ``.npz`` shards (see :func:`write_shard`) outside git.
"""
import json
import math
import os
import pathlib

import numpy as np

from .boxes import points_in_box, corners
from .targets import part_targets

SCENARIOS = ("walking_static", "walking_xyz", "walking_halfsphere", "walking_rpy",
             "sitting_static", "sitting_xyz", "static_room")
# Sampling weight of each scenario: mostly walkers (the dynamic sequences), some seated people and
# a few empty rooms so the detector learns to report nothing.
SCENARIO_WEIGHTS = (0.17, 0.2, 0.14, 0.14, 0.12, 0.13, 0.1)
# Crowd scenes (generate's crowd_share): 3-6 people passing 0.5-1.5 m from a handheld camera, cut
# by the image edge, carrying boards, boxes and bags (the carried object is part of its carrier's
# box and human pixels), with motion blur. Drawn uniformly.
CROWD_SCENARIOS = ("crowd_cross", "crowd_board", "crowd_start", "crowd_handheld")
MAX_POINTS = 4096          # spec §6.1 step 5: at most this many points go to the network
MIN_BOX_POINTS = 5         # a humanoid is a label when it holds >= this many input points
TALL = 1.85                # [m] test-only body heights (train scenes never hold taller walkers)
HUMAN_CLASS = 0
# Room extent per scene, drawn uniformly: x (ahead of the start pose), y (across), z (height) [m];
# the synthetic sensor has no depth beyond 4.5 m, so larger rooms mostly add empty far space.
ROOM_RANGE = ((3.8, 6.5), (4.0, 7.5), (2.5, 3.2))
MAX_EXTRA_FURNITURE = 6    # free-standing chairs / tables / floor lamps per scene: 0 ... this

# Preprocess settings: the defaults of ds3d.preprocess (include/ds3d/preprocess.hpp), i.e. what
# inference calls. Stored in every shard so a mismatch can be detected.
PREPROCESS = {"leaf_size": 0.1, "stride": 2}


def gravity_rotation(ground_plane, fallback_up=(0.0, -1.0, 0.0)):
    """Rotation R_up_cam [3, 3] (float64) from the camera frame (x right, y down, z forward) to
    the upright detector frame (X right, Y forward, Z up; spec §2), from the ground plane.

    ground_plane: (a, b, c, d) with n = (a, b, c) the plane normal in the camera frame
    (``PreprocessResult.ground_plane``), or None when no floor was found; then ``fallback_up``
    (camera frame, e.g. the last frame's up or the SLAM gravity) is used. The normal is oriented
    so that the camera (origin) lies on its positive side (a floor below the camera gives an
    upward normal). Rows of R are X = Y x Z, Y = camera z projected on the plane, Z = up.
    Raises ValueError for a degenerate normal or an optical axis parallel to it.
    """
    if ground_plane is not None:
        g = np.asarray(ground_plane, dtype=np.float64).reshape(4)
        up = g[:3].copy()
        if g[3] < 0:  # origin on the negative side: flip so the camera is "above"
            up = -up
    else:
        up = np.asarray(fallback_up, dtype=np.float64).reshape(3).copy()
    norm = float(np.linalg.norm(up))
    if not np.isfinite(norm) or norm < 1e-9:
        raise ValueError(f"ds3d.htx.data.gravity_rotation: up vector must be finite and non-zero (got {up})")
    z = up / norm
    fwd = np.array([0.0, 0.0, 1.0]) - z[2] * z
    fn = float(np.linalg.norm(fwd))
    if fn < 1e-6:
        raise ValueError("ds3d.htx.data.gravity_rotation: optical axis is parallel to the up vector")
    y = fwd / fn
    x = np.cross(y, z)
    return np.stack([x, y, z])


def world_boxes_to_upright(boxes, T_world_cam, R_up_cam):
    """Synth boxes (list of dicts with centre, size, yaw about world z, counter-clockwise) to
    spec §2 boxes [g, 7] (cx, cy, cz, dx, dy, dz, theta from +X towards -Y) in the upright frame.
    With an estimated floor the upright Z differs slightly from the world's; the box keeps its
    world size and takes the heading of its length axis projected onto the upright XY plane."""
    T = np.asarray(T_world_cam, dtype=np.float64)
    R_cw = T[:3, :3].T
    t_cw = -R_cw @ T[:3, 3]
    M = R_up_cam @ R_cw
    out = np.zeros((len(boxes), 7))
    for i, b in enumerate(boxes):
        c = M @ np.asarray(b["center"], np.float64) + R_up_cam @ t_cw
        a = M @ np.array([math.cos(b["yaw"]), math.sin(b["yaw"]), 0.0])
        out[i, :3] = c
        out[i, 3:6] = b["size"]
        out[i, 6] = math.atan2(-a[1], a[0])
    return out


def project_box(box, R_up_cam, camera):
    """Projects the 8 corners of an upright-frame box into the image: (u [8], v [8], z [8]) with
    z the camera depth [m] (points behind the camera have z <= 0)."""
    pc = corners(box) @ R_up_cam  # rows: R.T @ p
    z = pc[:, 2]
    zs = np.where(z > 1e-6, z, 1e-6)
    return camera["fx"] * pc[:, 0] / zs + camera["cx"], camera["fy"] * pc[:, 1] / zs + camera["cy"], z


def visibility(box, human_index, frame, R_up_cam, camera):
    """(truncated, occluded_fraction) of one humanoid: truncated when its pixels touch the image
    border or its box crosses the camera plane; occluded_fraction = share of the pixels of its
    (clipped) projected box covered by something else that lies nearer than the box's nearest
    corner (furniture or another person in front)."""
    hid = frame["human_id"]
    mine = hid == human_index + 1
    truncated = bool(mine[0].any() or mine[-1].any() or mine[:, 0].any() or mine[:, -1].any())
    u, v, z = project_box(box, R_up_cam, camera)
    h, w = hid.shape
    if np.any(z <= 0.05):
        return True, 0.0
    iu0, iu1 = int(max(0, math.floor(u.min()))), int(min(w - 1, math.ceil(u.max())))
    iv0, iv1 = int(max(0, math.floor(v.min()))), int(min(h - 1, math.ceil(v.max())))
    if iu1 < iu0 or iv1 < iv0:
        return True, 1.0
    d = frame["depth_true"][iv0:iv1 + 1, iu0:iu1 + 1]
    occ = (d > 0) & (d < z.min()) & (hid[iv0:iv1 + 1, iu0:iu1 + 1] != human_index + 1)
    return truncated, float(occ.mean())


def make_frame(frame, camera, rng, max_points=MAX_POINTS, prev_up=None, config=None):
    """One training/test sample from a rendered synth frame (dict of ``Scene.render``).

    Runs ``ds3d.preprocess`` (inference defaults), aligns to gravity (floor plane; if none is
    found: ``prev_up`` or, failing that, the true gravity of the synthetic pose), keeps at most
    ``max_points`` points (seeded subset in input order, as at inference), and labels them.
    The network's parameter-free selections for ``config`` (default: the fast profile) are
    stored too (network_indices). Returns a dict of numpy arrays (see write_shard for the keys)
    or None when fewer than 16 points survive preprocessing.
    """
    from .config import make_config

    import ds3d  # the compiled module; imported here so that ds3d.htx loads without it

    r = ds3d.preprocess(frame["depth"], camera["fx"], camera["fy"], camera["cx"], camera["cy"],
                        depth_scale=camera["depth_scale"], **PREPROCESS)
    pts = np.asarray(r.points, dtype=np.float32)
    pix = np.asarray(r.pixels, dtype=np.int32).reshape(-1, 2)
    if len(pts) < 16:
        return None
    T = np.asarray(frame["T_world_cam"], np.float64)
    true_up = T[:3, :3].T @ np.array([0.0, 0.0, 1.0])
    if r.ground_found:
        R = gravity_rotation(r.ground_plane)
        up_source = 0
    elif prev_up is not None:
        R = gravity_rotation(None, prev_up)
        up_source = 1
    else:
        R = gravity_rotation(None, true_up)
        up_source = 2
    if len(pts) > max_points:  # seeded subset, input order kept (FPS and ball query depend on it)
        keep = np.sort(rng.choice(len(pts), max_points, replace=False))
        pts, pix = pts[keep], pix[keep]
    up_pts = (pts.astype(np.float64) @ R.T).astype(np.float32)
    all_boxes = world_boxes_to_upright(frame["boxes"], T, R)
    human_px = frame["human_id"][pix[:, 1], pix[:, 0]]
    counts = np.array([int(points_in_box(up_pts, b).sum()) for b in all_boxes], dtype=np.int64)
    labelled = counts >= MIN_BOX_POINTS
    boxes = all_boxes[labelled]
    tg = part_targets(up_pts, boxes)
    label = tg["label"].copy()
    # A point inside a humanoid box that does not see a human pixel (chair, wall behind) is
    # ignored rather than foreground; a human point outside every labelled box is ignored too.
    label[(label == 1) & (human_px == 0)] = -1
    label[(label == 0) & (human_px > 0)] = -1
    for b in all_boxes[~labelled]:  # too few points to be a label: neither fg nor bg
        label[points_in_box(up_pts, b, enlarge=0.2) & (label == 0)] = -1
    meta = []
    idx = np.nonzero(labelled)[0]
    for k in idx:
        b = frame["boxes"][k]
        trunc, occ = visibility(all_boxes[k], int(b["id"]), frame, R, camera)
        meta.append([counts[k], b["visible_pixels"], int(b["sitting"]), int(trunc), occ, b["size"][2]])
    net = network_indices(up_pts, config or make_config("fast"))
    return {
        **net,
        "points": up_pts, "pixels": pix.astype(np.int16), "label": label.astype(np.int8),
        "part": tg["part"].astype(np.float16), "human": human_px.astype(np.uint8),
        "boxes": boxes.astype(np.float32),
        "box_meta": np.asarray(meta, dtype=np.float32).reshape(-1, 6),
        "R_up_cam": R.astype(np.float32), "up_source": np.int8(up_source),
        "true_up_error_deg": np.float32(math.degrees(math.acos(min(1.0, max(-1.0, float((R @ true_up)[2])))))),
    }


def network_indices(points, config):
    """The parameter-free selections of the network for one cloud (spec §3.2, §6.3), computed
    once per sample so the trainer does not redo them every epoch: FPS centre indices [t], ball
    query groups [t, s], query indices into the centres [q], 3 nearest centres of every point
    [n, 3] with their inverse-squared-distance weights [n, 3]. Same rules as ds3d.htx.ops
    (``topk`` instead of a full sort: identical results while distances are distinct).
    They are unchanged by the trainer's x -> -x mirror (negation is exact in float)."""
    import torch
    from . import ops

    x = torch.from_numpy(np.ascontiguousarray(points, dtype=np.float32))
    n = x.shape[0]
    t = min(config["num_centres"], n)
    cidx = ops.farthest_point_sample(x, t, config["fps_padding_norm2"])
    centres = x[cidx]
    d2 = ops.sq_dist(centres, x)  # [t, n]
    r2 = torch.tensor(config["sa_radius"], dtype=torch.float32) ** 2
    ar = torch.arange(n, dtype=torch.long)
    key = torch.where(d2 < r2, ar[None, :], ar[None, :] + n)
    s = config["sa_samples"]
    first = torch.topk(key, min(s, n), dim=1, largest=False, sorted=True).values
    if first.shape[1] < s:
        first = torch.cat([first, first[:, :1].expand(-1, s - first.shape[1])], dim=1)
    valid = first < n
    group = torch.where(valid, first, first[:, :1].expand_as(first))
    q = min(config["num_queries"], t)
    qidx = ops.farthest_point_sample(centres, q, config["fps_padding_norm2"])
    d2p = d2.t()  # [n, t]
    k = min(3, t)
    vals, nn = torch.topk(d2p, k, dim=1, largest=False, sorted=True)
    if k < 3:
        nn = torch.cat([nn, nn[:, -1:].expand(-1, 3 - k)], dim=1)
        vals = torch.cat([vals, torch.full((n, 3 - k), float("inf"))], dim=1)
    w = 1.0 / (vals + 1e-8)
    w = w / w.sum(dim=1, keepdim=True)
    return {"centre_idx": cidx.numpy().astype(np.int16), "group": group.numpy().astype(np.int16),
            "query_idx": qidx.numpy().astype(np.int16), "nn_idx": nn.numpy().astype(np.int16),
            "nn_w": w.numpy().astype(np.float32)}


BOX_META_COLUMNS = ("points_in_box", "visible_pixels", "sitting", "truncated", "occluded_fraction", "height")


def write_shard(path, frames, info):
    """Writes frames (list of make_frame dicts) to one compressed .npz: per-point arrays
    concatenated with ``point_offsets``, boxes with ``box_offsets``; ``info`` (dict) as JSON."""
    po = np.cumsum([0] + [len(f["points"]) for f in frames]).astype(np.int64)
    co = np.cumsum([0] + [len(f["centre_idx"]) for f in frames]).astype(np.int64)
    qo = np.cumsum([0] + [len(f["query_idx"]) for f in frames]).astype(np.int64)
    bo = np.cumsum([0] + [len(f["boxes"]) for f in frames]).astype(np.int64)
    cat = (lambda k, shape, dt: np.concatenate([f[k] for f in frames]).astype(dt)
           if frames else np.zeros(shape, dt))
    tmp = str(path) + ".tmp"  # a file object keeps numpy from appending ".npz"
    with open(tmp, "wb") as fh:
        np.savez_compressed(
            fh, point_offsets=po, box_offsets=bo, centre_offsets=co, query_offsets=qo,
            centre_idx=cat("centre_idx", (0,), np.int16), group=cat("group", (0, 32), np.int16),
            query_idx=cat("query_idx", (0,), np.int16), nn_idx=cat("nn_idx", (0, 3), np.int16),
            nn_w=cat("nn_w", (0, 3), np.float32),
            points=cat("points", (0, 3), np.float32), pixels=cat("pixels", (0, 2), np.int16),
            label=cat("label", (0,), np.int8), part=cat("part", (0, 3), np.float16),
            human=cat("human", (0,), np.uint8), boxes=cat("boxes", (0, 7), np.float32),
            box_meta=cat("box_meta", (0, 6), np.float32),
            R_up_cam=np.stack([f["R_up_cam"] for f in frames]) if frames else np.zeros((0, 3, 3), np.float32),
            up_source=np.array([f["up_source"] for f in frames], np.int8),
            true_up_error_deg=np.array([f["true_up_error_deg"] for f in frames], np.float32),
            frame_info=np.array([json.dumps(f.get("info", {})) for f in frames]),
            info=np.array(json.dumps(info)))
    os.replace(tmp, path)


def shard_files(folder):
    """The complete shards of a folder (files being written end in .tmp and are skipped)."""
    return sorted(f for f in pathlib.Path(folder).glob("*.npz") if ".tmp" not in f.name)


class HtxDataset:
    """All frames of the ``*.npz`` shards in a folder (kept in memory; ~40 kB per frame).

    ``ds[i]`` is a dict: points [n, 3] float32, label [n] int8 (1 fg, 0 bg, -1 ignore), part
    [n, 3] float32, boxes [g, 7] float32, classes [g] int64 (all 0 = person), box_meta [g, 6]
    (BOX_META_COLUMNS), R_up_cam [3, 3], info (dict: seed, scenario, frame), and the network
    selections of network_indices (fast profile) as int64/float32.
    """

    def __init__(self, folder):
        folder = pathlib.Path(folder)
        files = shard_files(folder)
        if not files:
            raise ValueError(f"ds3d.htx.data.HtxDataset: no .npz shards in {str(folder)!r}")
        self.shards = []
        self.index = []
        for s, f in enumerate(files):
            with np.load(f) as z:
                d = {k: z[k] for k in z.files}
            self.shards.append(d)
            self.index += [(s, i) for i in range(len(d["point_offsets"]) - 1)]
        self.info = json.loads(str(self.shards[0]["info"]))

    def __len__(self):
        return len(self.index)

    def num_centres(self, i):
        """Token count stored for sample i (the fast profile's 384 unless the cloud is smaller)."""
        s, j = self.index[i]
        co = self.shards[s]["centre_offsets"]
        return int(co[j + 1] - co[j])

    def __getitem__(self, i):
        s, j = self.index[i]
        d = self.shards[s]
        p0, p1 = d["point_offsets"][j], d["point_offsets"][j + 1]
        b0, b1 = d["box_offsets"][j], d["box_offsets"][j + 1]
        c0, c1 = d["centre_offsets"][j], d["centre_offsets"][j + 1]
        q0, q1 = d["query_offsets"][j], d["query_offsets"][j + 1]
        return {
            "centre_idx": d["centre_idx"][c0:c1].astype(np.int64),
            "group": d["group"][c0:c1].astype(np.int64),
            "query_idx": d["query_idx"][q0:q1].astype(np.int64),
            "nn_idx": d["nn_idx"][p0:p1].astype(np.int64), "nn_w": d["nn_w"][p0:p1],
            "points": d["points"][p0:p1], "pixels": d["pixels"][p0:p1].astype(np.int32),
            "label": d["label"][p0:p1], "part": d["part"][p0:p1].astype(np.float32),
            "human": d["human"][p0:p1], "boxes": d["boxes"][b0:b1],
            "classes": np.full(b1 - b0, HUMAN_CLASS, np.int64), "box_meta": d["box_meta"][b0:b1],
            "R_up_cam": d["R_up_cam"][j], "info": json.loads(str(d["frame_info"][j])),
        }


SPLITS = ("train", "val", "test")


def scene_seeds(split, count, base_seed):
    """Scene seeds of a split: disjoint ranges (train from base_seed, val from base_seed + 10^6,
    test from base_seed + 2 10^6; count <= 10^6)."""
    if split not in SPLITS:
        raise ValueError(f"ds3d.htx.data.scene_seeds: split must be one of {SPLITS} (got {split!r})")
    off = 1_000_000 * SPLITS.index(split)
    return range(base_seed + off, base_seed + off + count)


def generate(out_dir, split, frames, seed, frames_per_scene=8, shard_size=256, log=None,
             crowd_share=0.0):
    """Generates ``frames`` samples of ``split`` ('train', 'val' or 'test') into ``out_dir``/*.npz.

    Scenes: scenario drawn by SCENARIO_WEIGHTS, 0-4 humanoids (static_room: 0), a room size drawn
    uniformly from ROOM_RANGE and 0-MAX_EXTRA_FURNITURE free-standing chairs, tables and floor
    lamps (hard negatives), a 90 s sequence per scene of which ``frames_per_scene`` random frames
    are used (varied poses and gaits). With ``crowd_share`` in (0, 1], that share of the scenes
    (drawn per scene) is one of CROWD_SCENARIOS instead, with the scenario's own people (3-6).
    Train scenes holding a walker taller than TALL metres are skipped (test keeps every size, so
    test bodies include sizes never trained on). Deterministic for (split, seed).
    Returns a summary dict.
    """
    import ds3d

    if not 0.0 <= crowd_share <= 1.0:
        raise ValueError(f"ds3d.htx.data.generate: crowd_share must be in [0, 1] (got {crowd_share})")
    if frames < 1 or frames_per_scene < 1 or shard_size < 1:
        raise ValueError("ds3d.htx.data.generate: frames, frames_per_scene and shard_size must be >= 1 "
                         f"(got {frames}, {frames_per_scene}, {shard_size})")
    out = pathlib.Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    camera = ds3d.camera_preset("tum_ros")  # the generator's intrinsics (SynthOptions default)
    if split not in SPLITS:
        raise ValueError(f"ds3d.htx.data.generate: split must be one of {SPLITS} (got {split!r})")
    rng = np.random.default_rng([seed, SPLITS.index(split)])
    info = {"split": split, "seed": seed, "preprocess": PREPROCESS, "max_points": MAX_POINTS,
            "camera": camera, "frame": "upright (docs/htx_training.md)", "format": 1,
            "room_range": [list(r) for r in ROOM_RANGE], "max_extra_furniture": MAX_EXTRA_FURNITURE}
    if crowd_share > 0:  # files written without the crowd mix stay byte-identical
        info["crowd_share"] = crowd_share
    pending, shard_no, done, skipped, scene_i = [], 0, 0, 0, 0
    stats = {"boxes": 0, "frames_with_people": 0, "up_source": [0, 0, 0]}
    seeds = iter(scene_seeds(split, 10**6, seed * 10_000_000))
    while done < frames:
        s = next(seeds)
        srng = np.random.default_rng(s)
        if crowd_share > 0 and srng.random() < crowd_share:
            scen, humans = CROWD_SCENARIOS[int(srng.integers(len(CROWD_SCENARIOS)))], -1
        else:
            scen = SCENARIOS[int(srng.choice(len(SCENARIOS), p=SCENARIO_WEIGHTS))]
            humans = 0 if scen == "static_room" else int(srng.integers(1, 5))
        room = tuple(round(float(srng.uniform(lo, hi)), 3) for lo, hi in ROOM_RANGE)
        furniture = int(srng.integers(0, MAX_EXTRA_FURNITURE + 1))
        scene = ds3d.synth.Scene(scen, frames=2700, seed=s, humans=humans, room_size=room,
                                 furniture=furniture)
        picks = np.sort(srng.choice(2700, frames_per_scene, replace=False))
        first = scene.render(int(picks[0]))
        if split != "test" and any((not b["sitting"]) and b["size"][2] > TALL for b in first["boxes"]):
            skipped += 1
            continue
        prev_up = None
        for fi in picks:
            if done >= frames:
                break
            f = first if fi == picks[0] else scene.render(int(fi))
            sample = make_frame(f, camera, rng, prev_up=prev_up)
            if sample is None:
                continue
            prev_up = sample["R_up_cam"].T.astype(np.float64) @ np.array([0, 0, 1.0])
            sample["info"] = {"seed": s, "scenario": scen, "frame": int(fi),
                              "humans": humans if humans >= 0 else len(f["boxes"]),  # crowd: own count
                              "room": list(room), "furniture": furniture}
            pending.append(sample)
            done += 1
            stats["boxes"] += len(sample["boxes"])
            stats["frames_with_people"] += int(len(sample["boxes"]) > 0)
            stats["up_source"][int(sample["up_source"])] += 1
            if len(pending) == shard_size:
                write_shard(out / f"{split}_s{seed}_{shard_no:04d}.npz", pending, info)
                pending, shard_no = [], shard_no + 1
        scene_i += 1
        if log:
            log(f"{split}: {done}/{frames} frames, {scene_i} scenes")
    if pending:
        write_shard(out / f"{split}_s{seed}_{shard_no:04d}.npz", pending, info)
    summary = dict(info, frames=done, scenes=scene_i, skipped_tall_scenes=skipped, **stats)
    (out / f"{split}_s{seed}_summary.json").write_text(json.dumps(summary, indent=1))
    return summary
