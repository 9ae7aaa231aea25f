# SPDX-License-Identifier: Apache-2.0
# SPDX-FileCopyrightText: 2026 ds3d authors
"""Data-parallel training of HTx-lite under torch.distributed (torchrun / python3 -m
torch.distributed.run): process group from the environment, BatchNorm statistics over all ranks,
the DistributedDataParallel wrapper of the batch loss and the collective bookkeeping of train.py.

Each rank takes a contiguous 1/world share of every global batch (the same global batch, in the
same order, as a single process: every rank draws the same data order), so a run with N
processes and ``--batch B`` computes the loss of a single process with ``--batch B`` (BatchNorm
statistics and Part-A2's foreground normaliser are global, the detection loss is divided by the
global scene count); only the dropout masks differ (each rank has its own torch RNG stream).
"""
import os

import torch
import torch.distributed as dist
import torch.distributed.nn.functional as dist_fn


class DistContext:
    """rank, world size and a second process group for everything but the gradients (BatchNorm
    statistics, loss sums, flags), kept apart from DistributedDataParallel's asynchronous buckets."""

    def __init__(self, rank, world, stats_group):
        self.rank, self.world, self.stats_group = rank, world, stats_group

    @property
    def is_main(self):
        return self.rank == 0

    def shard(self, items):
        """This rank's contiguous share of a global batch (len(items) divisible by world)."""
        b = len(items) // self.world
        return items[self.rank * b:(self.rank + 1) * b]

    def sum_floats(self, values):
        """Elementwise sum over ranks of a list of floats (float64)."""
        t = torch.tensor(values, dtype=torch.float64)
        dist.all_reduce(t, group=self.stats_group)
        return t.tolist()

    def broadcast_flags(self, flags):
        """Rank 0's booleans on every rank (time-based decisions must agree)."""
        t = torch.tensor([int(bool(f)) for f in flags], dtype=torch.int64)
        dist.broadcast(t, 0, group=self.stats_group)
        return [bool(v) for v in t.tolist()]

    def gather_objects(self, obj):
        out = [None] * self.world
        dist.all_gather_object(out, obj, group=self.stats_group)
        return out

    def barrier(self):
        dist.barrier(group=self.stats_group)


def init_from_env(backend="gloo"):
    """A DistContext when torch.distributed.run started this process with WORLD_SIZE > 1
    (process group from its env:// variables), None for a plain single process. The trainer
    computes on the CPU, so the backend is gloo; nccl is refused (it needs CUDA tensors)."""
    world = int(os.environ.get("WORLD_SIZE", "1"))
    if world <= 1:
        return None
    if backend != "gloo":
        raise ValueError(f"ds3d.htx.distributed.init_from_env: backend must be 'gloo' for the CPU "
                         f"trainer (got {backend!r})")
    dist.init_process_group(backend="gloo")
    stats = dist.new_group(backend="gloo")
    return DistContext(dist.get_rank(), dist.get_world_size(), stats)


def shutdown(ctx):
    """Ends the process group of init_from_env (no-op for None)."""
    if ctx is not None and dist.is_initialized():
        dist.destroy_process_group()


class GlobalBatchNorm1d(torch.nn.BatchNorm1d):
    """BatchNorm1d over [n, c] rows whose training statistics are those of the rows of all ranks
    (torch 1.13's SyncBatchNorm needs CUDA). Sums in float64, one differentiable all_reduce per
    call; running statistics updated as BatchNorm1d does (unbiased variance)."""

    stats_group = None

    def forward(self, x):
        if not self.training:
            return super().forward(x)
        if x.dim() != 2:
            raise ValueError(f"ds3d.htx.distributed.GlobalBatchNorm1d: expects [n, c] rows (got {tuple(x.shape)})")
        xd = x.double()
        local = torch.cat([xd.sum(0), (xd * xd).sum(0), xd.new_tensor([float(x.shape[0])])])
        tot = dist_fn.all_reduce(local, group=self.stats_group)
        c = x.shape[1]
        n = tot[2 * c]
        mean = tot[:c] / n
        var = torch.clamp(tot[c:2 * c] / n - mean * mean, min=0.0)
        if self.track_running_stats:
            with torch.no_grad():
                self.num_batches_tracked += 1
                f = 1.0 / float(self.num_batches_tracked) if self.momentum is None else self.momentum
                unbiased = var * (n / torch.clamp(n - 1, min=1.0))
                self.running_mean.mul_(1 - f).add_(f * mean.to(x.dtype))
                self.running_var.mul_(1 - f).add_(f * unbiased.to(x.dtype))
        y = (x - mean.to(x.dtype)) * torch.rsqrt(var.to(x.dtype) + self.eps)
        if self.affine:
            y = y * self.weight + self.bias
        return y


def sync_batchnorm(model, ctx):
    """Turns every BatchNorm1d of model into a GlobalBatchNorm1d in place (same parameters and
    buffers, so optimiser and state_dict are unaffected). Returns model."""
    for m in model.modules():
        if type(m) is torch.nn.BatchNorm1d:
            m.__class__ = GlobalBatchNorm1d
            m.stats_group = ctx.stats_group
    return model


class LossModule(torch.nn.Module):
    """forward(samples) = this rank's share of the global batch loss (train.batch_loss with the
    global scene count and foreground normaliser); the module DistributedDataParallel wraps."""

    def __init__(self, model, weights, loss_fn, ctx, global_batch):
        super().__init__()
        self.model = model
        self.weights, self.loss_fn, self.ctx, self.global_batch = weights, loss_fn, ctx, global_batch

    def forward(self, samples):
        def global_fg(n):
            return int(round(self.ctx.sum_floats([float(n)])[0]))

        return self.loss_fn(self.model, samples, self.weights, scenes=self.global_batch, count_fg=global_fg)


def wrap(model, weights, loss_fn, ctx, global_batch):
    """DistributedDataParallel over LossModule. Which parameters get a gradient depends on the
    shard (a rank whose scenes have no person leaves the size and angle heads out of its loss),
    so unused parameters are searched every step; a parameter no rank used keeps grad None, as
    in a single process."""
    mod = LossModule(model, weights, loss_fn, ctx, global_batch)
    return torch.nn.parallel.DistributedDataParallel(mod, broadcast_buffers=False,
                                                     find_unused_parameters=True)
