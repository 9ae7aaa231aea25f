// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// The tensors of a weights file: the expected names and shapes, and loading them into Weights.
#include <algorithm>
#include <cstdint>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "ds3d/errors.hpp"
#include "ds3d/htx/weights_io.hpp"
#include "sparse_detector_impl.hpp"

namespace ds3d {

using detail::htx::Attention;
using detail::htx::Linear;
using detail::htx::Mat;
using detail::htx::Norm;
using detail::htx::RowVec;

namespace {

constexpr const char* kHeadNames[5] = {"sem_cls_head", "center_head", "size_head", "angle_cls_head",
                                       "angle_residual_head"};

}  // namespace

std::vector<std::pair<std::string, std::vector<std::int64_t>>> SparseDetector::expected_tensors(
    const DetectorConfig& c) {
  std::vector<std::pair<std::string, std::vector<std::int64_t>>> t;
  auto lin = [&](const std::string& n, std::int64_t out, std::int64_t in) {
    t.push_back({n + ".weight", {out, in}});
    t.push_back({n + ".bias", {out}});
  };
  const std::int64_t d = c.d_model;
  auto norm = [&](const std::string& n) {
    t.push_back({n + ".weight", {d}});
    t.push_back({n + ".bias", {d}});
  };
  auto attn = [&](const std::string& n) {
    t.push_back({n + ".in_proj_weight", {3 * d, d}});
    t.push_back({n + ".in_proj_bias", {3 * d}});
    lin(n + ".out_proj", d, d);
  };
  std::int64_t prev = 3;
  for (std::size_t i = 0; i < c.sa_mlp.size(); ++i) {
    lin("pre_encoder.mlp." + std::to_string(i), c.sa_mlp[i], prev);
    prev = c.sa_mlp[i];
  }
  for (int i = 0; i < c.enc_layers; ++i) {
    const std::string p = "encoder.layers." + std::to_string(i);
    attn(p + ".self_attn");
    lin(p + ".linear1", c.enc_ffn, d);
    lin(p + ".linear2", d, c.enc_ffn);
    norm(p + ".norm1");
    norm(p + ".norm2");
  }
  lin("encoder_to_decoder_projection.0", d, d);
  lin("encoder_to_decoder_projection.1", d, d);
  t.push_back({"pos_embedding.gauss_B", {3, d / 2}});
  lin("query_projection.0", d, d);
  lin("query_projection.1", d, d);
  for (int i = 0; i < c.dec_layers; ++i) {
    const std::string p = "decoder.layers." + std::to_string(i);
    attn(p + ".self_attn");
    attn(p + ".multihead_attn");
    lin(p + ".linear1", c.dec_ffn, d);
    lin(p + ".linear2", d, c.dec_ffn);
    norm(p + ".norm1");
    norm(p + ".norm2");
    norm(p + ".norm3");
  }
  norm("decoder.norm");
  const std::int64_t outs[5] = {c.num_classes + 1, 3, 3, c.num_angle_bins, c.num_angle_bins};
  for (int k = 0; k < 5; ++k) {
    const std::string p = std::string("mlp_heads.") + kHeadNames[k];
    lin(p + ".0", c.head_hidden, d);
    lin(p + ".1", c.head_hidden, c.head_hidden);
    lin(p + ".2", outs[k], c.head_hidden);
  }
  lin("part_head.0", c.part_hidden, d + 3);
  lin("part_head.1", 4, c.part_hidden);
  return t;
}

SparseDetector SparseDetector::load(const std::filesystem::path& weights) {
  return from_weights(WeightsFile::read(weights));
}

SparseDetector SparseDetector::from_weights(const WeightsFile& f) {
  const std::string& fmt = f.metadata("format");
  DS3D_CHECK_AS(IoError, fmt == "ds3d-htx", "ds3d::SparseDetector::load: ", f.source(),
                ": metadata format is '", fmt, "', expected 'ds3d-htx'");
  const std::string& ver = f.metadata("version");
  DS3D_CHECK_AS(IoError, ver == "1", "ds3d::SparseDetector::load: ", f.source(),
                ": unsupported version '", ver, "'");
  DetectorConfig c = DetectorConfig::from_json(f.metadata("config"));
  auto w = std::make_shared<Weights>();
  std::vector<std::string> used;
  auto mat = [&](const std::string& name, std::int64_t rows, std::int64_t cols) {
    used.push_back(name);
    const auto v = f.f32(name, {rows, cols});
    return Mat(Eigen::Map<const Mat>(v.data(), rows, cols));
  };
  auto vec = [&](const std::string& name, std::int64_t n) {
    used.push_back(name);
    const auto v = f.f32(name, {n});
    return RowVec(Eigen::Map<const RowVec>(v.data(), n));
  };
  auto lin = [&](const std::string& name, std::int64_t out, std::int64_t in) {
    Linear l;
    l.w = mat(name + ".weight", out, in);
    l.b = vec(name + ".bias", out);
    return l;
  };
  auto norm = [&](const std::string& name, std::int64_t d) {
    return Norm{vec(name + ".weight", d), vec(name + ".bias", d)};
  };
  const std::int64_t d = c.d_model;
  auto attn = [&](const std::string& name) {
    Attention a;
    a.w_in = mat(name + ".in_proj_weight", 3 * d, d);
    a.b_in = vec(name + ".in_proj_bias", 3 * d);
    a.out = lin(name + ".out_proj", d, d);
    return a;
  };
  std::int64_t prev = 3;
  for (std::size_t i = 0; i < c.sa_mlp.size(); ++i) {
    w->sa_mlp.push_back(lin("pre_encoder.mlp." + std::to_string(i), c.sa_mlp[i], prev));
    prev = c.sa_mlp[i];
  }
  for (int i = 0; i < c.enc_layers; ++i) {
    const std::string p = "encoder.layers." + std::to_string(i);
    w->enc.push_back({attn(p + ".self_attn"), lin(p + ".linear1", c.enc_ffn, d),
                      lin(p + ".linear2", d, c.enc_ffn), norm(p + ".norm1", d),
                      norm(p + ".norm2", d)});
  }
  w->proj0 = lin("encoder_to_decoder_projection.0", d, d);
  w->proj1 = lin("encoder_to_decoder_projection.1", d, d);
  w->gauss_b = mat("pos_embedding.gauss_B", 3, d / 2);
  w->qproj0 = lin("query_projection.0", d, d);
  w->qproj1 = lin("query_projection.1", d, d);
  for (int i = 0; i < c.dec_layers; ++i) {
    const std::string p = "decoder.layers." + std::to_string(i);
    w->dec.push_back({attn(p + ".self_attn"), attn(p + ".multihead_attn"),
                      lin(p + ".linear1", c.dec_ffn, d), lin(p + ".linear2", d, c.dec_ffn),
                      norm(p + ".norm1", d), norm(p + ".norm2", d), norm(p + ".norm3", d)});
  }
  w->dec_norm = norm("decoder.norm", d);
  const std::int64_t h = c.head_hidden;
  const std::int64_t outs[5] = {c.num_classes + 1, 3, 3, c.num_angle_bins, c.num_angle_bins};
  w->head0_all.w.resize(5 * h, d);
  w->head0_all.b.resize(5 * h);
  for (int k = 0; k < 5; ++k) {
    const std::string p = std::string("mlp_heads.") + kHeadNames[k];
    const Linear l0 = lin(p + ".0", h, d);
    w->head0_all.w.middleRows(k * h, h) = l0.w;
    w->head0_all.b.segment(k * h, h) = l0.b;
    w->head1[static_cast<std::size_t>(k)] = lin(p + ".1", h, h);
    w->head2[static_cast<std::size_t>(k)] = lin(p + ".2", outs[k], h);
  }
  w->part0 = lin("part_head.0", c.part_hidden, d + 3);
  w->part1 = lin("part_head.1", 4, c.part_hidden);
  // Nothing unexpected may hide in the file.
  std::sort(used.begin(), used.end());
  for (const auto& name : f.names()) {
    DS3D_CHECK_AS(IoError, std::binary_search(used.begin(), used.end(), name),
                  "ds3d::SparseDetector::load: ", f.source(), ": unexpected tensor '", name, "'");
  }
  return SparseDetector(std::move(c), std::move(w));
}

}  // namespace ds3d
