# SPDX-License-Identifier: Apache-2.0
# SPDX-FileCopyrightText: 2026 ds3d authors
"""Weight export to the safetensors layout (spec §7), written with numpy only.

File = 8-byte little-endian header length N, N bytes of UTF-8 JSON (space-padded so the data
starts 8-byte aligned), then the raw little-endian C-order tensors back to back. BatchNorm is
folded into the preceding bias-free layer: W' = W * g / sqrt(var + eps), b' = beta - mean * g /
sqrt(var + eps). 1x1 convolutions are stored as [out, in].
"""
import hashlib
import json
import struct

import numpy as np
import torch

FORMAT = "ds3d-htx"
VERSION = "1"
_DTYPES = {"F32": np.dtype("<f4"), "F64": np.dtype("<f8"), "F16": np.dtype("<f2"),
           "I64": np.dtype("<i8"), "I32": np.dtype("<i4"), "I16": np.dtype("<i2"),
           "I8": np.dtype("i1"), "U8": np.dtype("u1"), "BOOL": np.dtype("?")}


def _fold(cbr):
    """(weight [out, in], bias [out]) of a ConvBNReLU with its BatchNorm folded in."""
    w = cbr.linear.weight.detach().double()
    bn = cbr.bn
    g = bn.weight.detach().double() / torch.sqrt(bn.running_var.detach().double() + bn.eps)
    return (w * g[:, None]).float(), (bn.bias.detach().double() - bn.running_mean.detach().double() * g).float()


def _lin(lin):
    return lin.weight.detach().float(), lin.bias.detach().float()


def folded_tensors(model):
    """Ordered dict name -> float32 numpy array of everything the C++ detector needs."""
    t = {}

    def put(name, wb):
        t[name + ".weight"], t[name + ".bias"] = wb[0].numpy(), wb[1].numpy()

    def attn(prefix, mha):
        t[prefix + ".in_proj_weight"] = mha.in_proj_weight.detach().float().numpy()
        t[prefix + ".in_proj_bias"] = mha.in_proj_bias.detach().float().numpy()
        put(prefix + ".out_proj", _lin(mha.out_proj))

    def norm(name, ln):
        put(name, (ln.weight.detach().float(), ln.bias.detach().float()))

    for i, layer in enumerate(model.pre_encoder):
        put(f"pre_encoder.mlp.{i}", _fold(layer))
    for i, layer in enumerate(model.encoder):
        p = f"encoder.layers.{i}"
        attn(p + ".self_attn", layer.self_attn)
        put(p + ".linear1", _lin(layer.linear1))
        put(p + ".linear2", _lin(layer.linear2))
        norm(p + ".norm1", layer.norm1)
        norm(p + ".norm2", layer.norm2)
    for i, layer in enumerate(model.encoder_to_decoder_projection):
        put(f"encoder_to_decoder_projection.{i}", _fold(layer))
    t["pos_embedding.gauss_B"] = model.gauss_B.detach().float().numpy()
    for i, lin in enumerate(model.query_projection):
        put(f"query_projection.{i}", _lin(lin))
    for i, layer in enumerate(model.decoder):
        p = f"decoder.layers.{i}"
        attn(p + ".self_attn", layer.self_attn)
        attn(p + ".multihead_attn", layer.multihead_attn)
        put(p + ".linear1", _lin(layer.linear1))
        put(p + ".linear2", _lin(layer.linear2))
        norm(p + ".norm1", layer.norm1)
        norm(p + ".norm2", layer.norm2)
        norm(p + ".norm3", layer.norm3)
    norm("decoder.norm", model.decoder_norm)
    for name, head in model.mlp_heads.items():
        put(f"mlp_heads.{name}.0", _fold(head.layers[0]))
        put(f"mlp_heads.{name}.1", _fold(head.layers[1]))
        put(f"mlp_heads.{name}.2", _lin(head.out))
    put("part_head.0", _fold(model.part_head[0]))
    put("part_head.1", _lin(model.part_out))
    return t


CHECKSUM_KEY = "tensors_sha256"


def write_safetensors(path, tensors, metadata=None, checksum=False):
    """Writes name -> numpy array (dtypes of spec §7) and string metadata to ``path``.
    With ``checksum``, the SHA-256 of the data buffer goes into metadata["tensors_sha256"]
    (checked by the C++ reader and by read_safetensors)."""
    header, chunks, offset = {}, [], 0
    if metadata:
        if not all(isinstance(k, str) and isinstance(v, str) for k, v in metadata.items()):
            raise ValueError("ds3d.htx.write_safetensors: metadata must map str to str")
        header["__metadata__"] = dict(metadata)
    for name, arr in tensors.items():
        a = np.asarray(arr, order="C")  # not ascontiguousarray: it turns 0-d into (1,)
        code = next((k for k, v in _DTYPES.items() if v == a.dtype.newbyteorder("<") or v == a.dtype), None)
        if code is None:
            raise ValueError(f"ds3d.htx.write_safetensors: tensor {name!r} has unsupported dtype {a.dtype}")
        raw = a.astype(_DTYPES[code], copy=False).tobytes(order="C")
        header[name] = {"dtype": code, "shape": list(a.shape), "data_offsets": [offset, offset + len(raw)]}
        chunks.append(raw)
        offset += len(raw)
    if checksum:
        header.setdefault("__metadata__", {})[CHECKSUM_KEY] = hashlib.sha256(b"".join(chunks)).hexdigest()
    text = json.dumps(header, separators=(",", ":"), ensure_ascii=False).encode("utf-8")
    text += b" " * ((8 - (8 + len(text)) % 8) % 8)
    with open(path, "wb") as f:
        f.write(struct.pack("<Q", len(text)))
        f.write(text)
        for c in chunks:
            f.write(c)


def read_safetensors(path):
    """Reads a file written by write_safetensors: returns (dict name -> numpy array, metadata)."""
    with open(path, "rb") as f:
        data = f.read()
    if len(data) < 8:
        raise RuntimeError(f"ds3d.htx.read_safetensors: {path}: file shorter than 8 bytes")
    (n,) = struct.unpack("<Q", data[:8])
    if 8 + n > len(data):
        raise RuntimeError(f"ds3d.htx.read_safetensors: {path}: header length {n} exceeds file size")
    header = json.loads(data[8:8 + n].decode("utf-8"))
    meta = header.pop("__metadata__", {})
    buf = data[8 + n:]
    if CHECKSUM_KEY in meta and hashlib.sha256(buf).hexdigest() != meta[CHECKSUM_KEY]:
        raise RuntimeError(f"ds3d.htx.read_safetensors: {path}: {CHECKSUM_KEY} does not match the "
                           "tensor bytes: the file is corrupted or was edited after export")
    out = {}
    for name, e in header.items():
        b, end = e["data_offsets"]
        out[name] = np.frombuffer(buf[b:end], dtype=_DTYPES[e["dtype"]]).reshape(tuple(e["shape"])).copy()
    return out, meta


def export(model, path):
    """Writes ``model``'s weights (BatchNorm folded, float32) and its config to ``path``
    (format "ds3d-htx", version 1) for ``ds3d.SparseDetector.load(path)``."""
    meta = {"format": FORMAT, "version": VERSION, "config": json.dumps(model.config, sort_keys=True)}
    write_safetensors(path, folded_tensors(model), meta, checksum=True)
