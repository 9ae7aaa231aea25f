# SPDX-License-Identifier: Apache-2.0
# SPDX-FileCopyrightText: 2026 ds3d authors
"""Pure-torch point operations with the exact 3DETR/PointNet++ selection rules (spec §3.2).

The reference pointnet2 kernels are CUDA-only; these run on Debian's CPU torch and are the
definition the C++ ``ds3d::SparseDetector`` copies (identical sampling indices in float32).
"""
import torch


def sq_dist(a, b):
    """Squared distances [n, m] between rows of a [n, 3] and b [m, 3], float32, written as
    dx*dx + dy*dy + dz*dz so that C++ computes bit-identical values."""
    d = a[:, None, :] - b[None, :, :]
    return d[..., 0] * d[..., 0] + d[..., 1] * d[..., 1] + d[..., 2] * d[..., 2]


@torch.no_grad()
def farthest_point_sample(xyz, k, padding_norm2=1e-3):
    """Farthest point sampling of ``k`` indices from xyz [n, 3] (float32).

    Starts at index 0; each step takes the point with the largest squared distance to its nearest
    chosen point, lowest index on ties. Points with |p|^2 <= padding_norm2 are never chosen
    after the first (3DETR's padding rule). k may exceed n (indices then repeat).
    """
    n = xyz.shape[0]
    xyz = xyz.to(torch.float32)
    out = torch.zeros(k, dtype=torch.long)
    if n == 0 or k == 0:
        return out[:0] if n == 0 else out
    norm2 = xyz[:, 0] * xyz[:, 0] + xyz[:, 1] * xyz[:, 1] + xyz[:, 2] * xyz[:, 2]
    candidate = norm2 > padding_norm2
    dist = torch.full((n,), 1e10, dtype=torch.float32)
    last = 0
    for i in range(1, k):
        d = xyz - xyz[last]
        d2 = d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1] + d[:, 2] * d[:, 2]
        dist = torch.minimum(dist, d2)
        masked = torch.where(candidate, dist, torch.full_like(dist, -1.0))
        best = torch.max(masked)
        if best < 0:  # only padding left: the kernel's default index 0
            last = 0
        else:
            last = int(torch.nonzero(masked == best)[0, 0])  # lowest index among ties
        out[i] = last
    return out


@torch.no_grad()
def ball_query(xyz, centres, radius, nsample):
    """For each centre, the first ``nsample`` indices (in input order) with squared distance
    < radius^2 (strict); empty slots repeat the first found index. Returns [m, nsample] long.
    A centre with no neighbour at all (impossible when centres are input points) gets index 0."""
    n = xyz.shape[0]
    d2 = sq_dist(centres.to(torch.float32), xyz.to(torch.float32))  # [m, n]
    r2 = torch.tensor(radius, dtype=torch.float32) ** 2
    inside = d2 < r2
    ar = torch.arange(n, dtype=torch.long)
    key = torch.where(inside, ar[None, :], ar[None, :] + n)
    first = torch.sort(key, dim=1).values[:, :nsample]
    if first.shape[1] < nsample:  # fewer input points than samples
        pad = first[:, :1].expand(-1, nsample - first.shape[1])
        first = torch.cat([first, pad], dim=1)
    valid = first < n
    head = torch.where(valid[:, :1], first[:, :1], torch.zeros_like(first[:, :1]))
    return torch.where(valid, first, head.expand_as(first))


def three_nn_weights(points, tokens):
    """Indices [n, 3] of the 3 nearest tokens of every point (lowest index first on ties) and
    their normalised inverse-squared-distance weights (PointNet++ feature propagation)."""
    d2 = sq_dist(points, tokens)  # [n, t]
    k = min(3, tokens.shape[0])
    # stable sort so equal distances keep index order (matches the C++ partial sort)
    order = torch.sort(d2, dim=1, stable=True)
    idx = order.indices[:, :k]
    dk = order.values[:, :k]
    if k < 3:
        idx = torch.cat([idx, idx[:, -1:].expand(-1, 3 - k)], dim=1)
        dk = torch.cat([dk, torch.full((dk.shape[0], 3 - k), float("inf"))], dim=1)
    w = 1.0 / (dk + 1e-8)
    w = w / w.sum(dim=1, keepdim=True)
    return idx, w
