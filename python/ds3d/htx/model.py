# SPDX-License-Identifier: Apache-2.0
# SPDX-FileCopyrightText: 2026 ds3d authors
"""HTx-lite: 3DETR encoder/decoder (Misra et al., ICCV 2021) with a Part-A2 part head
(Shi et al., TPAMI 2020), the PyTorch reference for ``ds3d::SparseDetector`` (spec §3, §6).

Batch size is one scene per call (scenes have different sizes after preprocessing); the trainer
loops over a batch. Module names follow the weight-file naming of spec §7.
"""
import math

import torch
from torch import nn
import torch.nn.functional as F

from . import ops
from .config import make_config


class ConvBNReLU(nn.Module):
    """1x1 convolution without bias + BatchNorm + ReLU, written as Linear on [..., c] tensors."""

    def __init__(self, c_in, c_out):
        super().__init__()
        self.linear = nn.Linear(c_in, c_out, bias=False)
        self.bn = nn.BatchNorm1d(c_out)

    def forward(self, x):
        c_out = self.linear.out_features
        y = self.bn(self.linear(x).reshape(-1, c_out))
        return F.relu(y).reshape(*x.shape[:-1], c_out)


class EncoderLayer(nn.Module):
    """Pre-norm transformer layer: x += MHA(LN1 x); x += FFN(LN2 x) (spec §3.3)."""

    def __init__(self, d, heads, ffn, eps, dropout):
        super().__init__()
        self.self_attn = nn.MultiheadAttention(d, heads, dropout=dropout)
        self.linear1 = nn.Linear(d, ffn)
        self.linear2 = nn.Linear(ffn, d)
        self.norm1 = nn.LayerNorm(d, eps=eps)
        self.norm2 = nn.LayerNorm(d, eps=eps)
        self.dropout = nn.Dropout(dropout)

    def forward(self, x):  # x: [t, 1, d]
        y = self.norm1(x)
        x = x + self.dropout(self.self_attn(y, y, y, need_weights=False)[0])
        y = self.norm2(x)
        return x + self.dropout(self.linear2(self.dropout(F.relu(self.linear1(y)))))


class DecoderLayer(nn.Module):
    """Pre-norm decoder layer: self-attention, cross-attention, FFN (spec §3.6)."""

    def __init__(self, d, heads, ffn, eps, dropout):
        super().__init__()
        self.self_attn = nn.MultiheadAttention(d, heads, dropout=dropout)
        self.multihead_attn = nn.MultiheadAttention(d, heads, dropout=dropout)
        self.linear1 = nn.Linear(d, ffn)
        self.linear2 = nn.Linear(ffn, d)
        self.norm1 = nn.LayerNorm(d, eps=eps)
        self.norm2 = nn.LayerNorm(d, eps=eps)
        self.norm3 = nn.LayerNorm(d, eps=eps)
        self.dropout = nn.Dropout(dropout)

    def forward(self, t, memory, query_pos, memory_pos):  # t: [q, 1, d]; memory: [m, 1, d]
        y = self.norm1(t)
        q = y + query_pos
        t = t + self.dropout(self.self_attn(q, q, y, need_weights=False)[0])
        y = self.norm2(t)
        t = t + self.dropout(self.multihead_attn(y + query_pos, memory + memory_pos, memory,
                                                 need_weights=False)[0])
        y = self.norm3(t)
        return t + self.dropout(self.linear2(self.dropout(F.relu(self.linear1(y)))))


class Head(nn.Module):
    """conv-BN-ReLU twice, then a biased conv (spec §3.7); dropout 0.3 in training."""

    def __init__(self, c_in, hidden, c_out, dropout=0.3):
        super().__init__()
        self.layers = nn.ModuleList([ConvBNReLU(c_in, hidden), ConvBNReLU(hidden, hidden)])
        self.out = nn.Linear(hidden, c_out)
        self.dropout = nn.Dropout(dropout)

    def forward(self, x):
        for layer in self.layers:
            x = self.dropout(layer(x))
        return self.out(x)


def fourier_embedding(xyz, scene_min, scene_max, gauss_b):
    """[n, 3] -> [n, 2 * gauss_b.shape[1]]: x_hat = (p - min) / extent, u = (2 pi x_hat) B,
    [sin u, cos u] (spec §3.5; extent clamped to 1e-6 so a flat axis gives x_hat = 0)."""
    extent = torch.clamp(scene_max - scene_min, min=1e-6)
    x_hat = (xyz - scene_min) / extent
    u = torch.mm(x_hat * (2.0 * math.pi), gauss_b)
    return torch.cat([torch.sin(u), torch.cos(u)], dim=1)


class HTx(nn.Module):
    """HTx-lite detector. ``forward(xyz)`` takes one preprocessed, gravity-aligned scene [n, 3]
    (metres, Z up) and returns a dict of raw and decoded predictions (see ``forward``)."""

    def __init__(self, config, dropout=0.1):
        super().__init__()
        self.config = dict(config)
        c = self.config
        d, eps = c["d_model"], c["layer_norm_eps"]
        widths = [3] + list(c["sa_mlp"])
        self.pre_encoder = nn.ModuleList(
            [ConvBNReLU(widths[i], widths[i + 1]) for i in range(len(widths) - 1)])
        if widths[-1] != d:
            raise ValueError("ds3d.htx.HTx: sa_mlp must end at d_model")
        self.encoder = nn.ModuleList(
            [EncoderLayer(d, c["num_heads"], c["enc_ffn"], eps, dropout) for _ in range(c["enc_layers"])])
        self.encoder_to_decoder_projection = nn.ModuleList([ConvBNReLU(d, d), ConvBNReLU(d, d)])
        self.register_buffer("gauss_B", torch.randn(3, d // 2))
        self.query_projection = nn.ModuleList([nn.Linear(d, d), nn.Linear(d, d)])
        self.decoder = nn.ModuleList(
            [DecoderLayer(d, c["num_heads"], c["dec_ffn"], eps, dropout) for _ in range(c["dec_layers"])])
        self.decoder_norm = nn.LayerNorm(d, eps=eps)
        h, k, nb = c["head_hidden"], c["num_classes"], c["num_angle_bins"]
        self.mlp_heads = nn.ModuleDict({
            "sem_cls_head": Head(d, h, k + 1),
            "center_head": Head(d, h, 3),
            "size_head": Head(d, h, 3),
            "angle_cls_head": Head(d, h, nb),
            "angle_residual_head": Head(d, h, nb),
        })
        self.part_head = nn.ModuleList([ConvBNReLU(d + 3, c["part_hidden"])])
        self.part_out = nn.Linear(c["part_hidden"], 4)

    # ---- stages ---------------------------------------------------------------------------
    def pre_encode(self, xyz):
        """SA layer: FPS centres, first-by-index ball query, shared MLP, max-pool.
        Returns centre indices [t], centre xyz [t, 3], features [t, d]."""
        c = self.config
        t = min(c["num_centres"], xyz.shape[0])
        idx = ops.farthest_point_sample(xyz, t, c["fps_padding_norm2"])
        centres = xyz[idx]
        group = ops.ball_query(xyz, centres, c["sa_radius"], c["sa_samples"])  # [t, s]
        x = (xyz[group] - centres[:, None, :]) / c["sa_radius"]  # [t, s, 3]
        for layer in self.pre_encoder:
            x = layer(x)
        return idx, centres, x.max(dim=1).values  # [t, d]

    def encode(self, feats):
        x = feats[:, None, :]  # [t, 1, d]
        for layer in self.encoder:
            x = layer(x)
        return x[:, 0, :]

    def part_logits(self, xyz, tokens_xyz, enc_feats, scene_min, scene_max):
        """Part head (spec §6.3 option A): 3-NN interpolation of encoder features to every
        point, concat normalised xyz, MLP -> [n, 4] logits (foreground, part x, y, z)."""
        idx, w = ops.three_nn_weights(xyz, tokens_xyz)
        f = (enc_feats[idx] * w[..., None]).sum(dim=1)  # [n, d]
        extent = torch.clamp(scene_max - scene_min, min=1e-6)
        x = torch.cat([f, (xyz - scene_min) / extent], dim=1)
        for layer in self.part_head:
            x = layer(x)
        return self.part_out(x)

    def heads(self, t, query_xyz, scene_min, scene_max):
        """Raw head outputs and decoded boxes for decoder output t [q, d] (spec §3.7)."""
        c = self.config
        out = {name: head(t) for name, head in self.mlp_heads.items()}
        extent = scene_max - scene_min
        size_scale = torch.clamp(extent, min=c["min_size_extent"])
        center_off = torch.sigmoid(out["center_head"]) - 0.5
        center = query_xyz + center_off
        size_norm = torch.sigmoid(out["size_head"])
        size = size_norm * size_scale
        nb = c["num_angle_bins"]
        angle_bin = torch.argmax(out["angle_cls_head"], dim=-1)
        res_norm = out["angle_residual_head"]
        res = torch.gather(res_norm, 1, angle_bin[:, None])[:, 0] * (math.pi / nb)
        angle = angle_bin.to(torch.float32) * (2.0 * math.pi / nb) + res
        angle = torch.where(angle > math.pi, angle - 2.0 * math.pi, angle)
        prob = torch.softmax(out["sem_cls_head"], dim=-1)
        objectness = 1.0 - prob[:, -1]
        return {
            "sem_cls_logits": out["sem_cls_head"], "center_offset": center_off, "center": center,
            "center_normalized": (center - scene_min) / torch.clamp(extent, min=1e-6),
            "size_normalized": size_norm, "size": size,
            "angle_logits": out["angle_cls_head"], "angle_residual_normalized": res_norm,
            "angle": angle, "sem_cls_prob": prob[:, :-1], "objectness": objectness,
        }

    def forward(self, xyz, with_parts=True, all_layers=None):
        """Runs the network on one scene xyz [n, 3] float32 (n >= 1).

        Returns dict: centre_indices [t], query_indices [q] (into the tokens), scene_min/max [3],
        ``layers`` (list of head dicts, one per decoder layer when all_layers, else only the
        last), and part_logits [n, 4] when with_parts.
        """
        if all_layers is None:
            all_layers = self.training
        c = self.config
        xyz = xyz.to(torch.float32)
        scene_min = xyz.min(dim=0).values
        scene_max = xyz.max(dim=0).values
        cidx, centres, feats = self.pre_encode(xyz)
        enc = self.encode(feats)  # [t, d]
        memory = enc
        for layer in self.encoder_to_decoder_projection:
            memory = layer(memory)
        nq = min(c["num_queries"], centres.shape[0])
        qidx = ops.farthest_point_sample(centres, nq, c["fps_padding_norm2"])
        query_xyz = centres[qidx]
        qpos = fourier_embedding(query_xyz, scene_min, scene_max, self.gauss_B)
        for lin in self.query_projection:
            qpos = F.relu(lin(qpos))
        mpos = fourier_embedding(centres, scene_min, scene_max, self.gauss_B)
        t = torch.zeros_like(qpos)[:, None, :]
        mem, qp, mp = memory[:, None, :], qpos[:, None, :], mpos[:, None, :]
        layers = []
        for i, layer in enumerate(self.decoder):
            t = layer(t, mem, qp, mp)
            if all_layers or i == len(self.decoder) - 1:
                layers.append(self.heads(self.decoder_norm(t[:, 0, :]), query_xyz, scene_min, scene_max))
        result = {"centre_indices": cidx, "query_indices": qidx, "query_xyz": query_xyz,
                  "tokens_xyz": centres, "scene_min": scene_min, "scene_max": scene_max,
                  "layers": layers}
        if with_parts:
            result["part_logits"] = self.part_logits(xyz, centres, enc, scene_min, scene_max)
        return result


def build_model(profile="fast", seed=0, **overrides):
    """A randomly initialised HTx-lite model for ``profile`` ('fast' or 'quality'), deterministic
    for ``seed``; BatchNorm statistics are randomised too so that folding is exercised.
    ``overrides`` change config keys (e.g. num_classes=10, class_names=[...]). Returns it in eval mode."""
    cfg = make_config(profile, **overrides)
    gen_state = torch.random.get_rng_state()
    try:
        torch.manual_seed(seed)
        model = HTx(cfg)
        with torch.no_grad():
            for m in model.modules():
                if isinstance(m, nn.BatchNorm1d):
                    m.weight.uniform_(0.5, 1.5)
                    m.bias.uniform_(-0.2, 0.2)
                    m.running_mean.uniform_(-0.2, 0.2)
                    m.running_var.uniform_(0.5, 2.0)
                elif isinstance(m, nn.LayerNorm):
                    m.weight.uniform_(0.8, 1.2)
                    m.bias.uniform_(-0.1, 0.1)
                elif isinstance(m, nn.MultiheadAttention):
                    m.in_proj_bias.uniform_(-0.1, 0.1)
                    m.out_proj.bias.uniform_(-0.1, 0.1)
    finally:
        torch.random.set_rng_state(gen_state)
    return model.eval()
