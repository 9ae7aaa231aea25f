// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// HTx-lite inference (htx spec §3, §6). Every stage mirrors python/ds3d/htx/model.py; the
// selection steps (FPS, ball query, 3-NN) use the same float32 expressions so that the sampling
// indices are bit-identical to the PyTorch reference.
// This file runs the stages in order and decodes boxes and part logits; the stages live in
// point_sampling.cpp and transformer.cpp, the shared helpers in sparse_detector_impl.hpp.
#include "ds3d/htx/sparse_detector.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <numbers>
#include <vector>

#include <Eigen/Core>

#include "ds3d/detail/parallel.hpp"
#include "ds3d/errors.hpp"
#include "sparse_detector_impl.hpp"

namespace ds3d {

using detail::htx::ball_group;
using detail::htx::decode;
using detail::htx::encode;
using detail::htx::farthest_point_sample;
using detail::htx::fourier_embedding;
using detail::htx::linear;
using detail::htx::linear_relu;
using detail::htx::Mat;
using detail::htx::RowVec;
using detail::htx::sigmoid;
using detail::htx::three_nn;

namespace {

// Set abstraction around the sampled centres: ball query, shared MLP, max-pool -> [t, d].
Mat set_abstraction(const Mat& p, const Mat& centres, const SparseDetector::Weights& w,
                    const DetectorConfig& c) {
  const Eigen::Index t = centres.rows();
  std::vector<Eigen::Index> group_begin;
  const Mat grouped =
      ball_group(p, centres, c.sa_radius, c.sa_samples, group_begin);  // [samples, 3]
  const Eigen::Index d = c.d_model;
  Mat feats(t, d);  // [t, d]
  // Shared MLP + max-pool in chunks of centres, so the [samples, 128] activations stay in cache.
  constexpr Eigen::Index kChunk = 32;
  for (Eigen::Index c0 = 0; c0 < t; c0 += kChunk) {
    const Eigen::Index c1 = std::min(t, c0 + kChunk);
    const Eigen::Index r0 = group_begin[static_cast<std::size_t>(c0)];
    Mat x = grouped.middleRows(r0, group_begin[static_cast<std::size_t>(c1)] - r0);
    for (const auto& l : w.sa_mlp) x = linear_relu(x, l);  // [chunk samples, d]
    for (Eigen::Index i = c0; i < c1; ++i) {
      const Eigen::Index b = group_begin[static_cast<std::size_t>(i)] - r0;
      feats.row(i) = x.middleRows(b, group_begin[static_cast<std::size_t>(i) + 1] - r0 - b)
                         .colwise()
                         .maxCoeff();
    }
  }
  return feats;
}

// The five MLP heads and box decoding: the proposal and class probabilities of every query.
void decode_boxes(const Mat& hin, const Mat& qxyz, const RowVec& extent,
                  const SparseDetector::Weights& w, const DetectorConfig& c, DetectorOutput& out) {
  const Eigen::Index nq = qxyz.rows();
  const Mat h0 = linear_relu(hin, w.head0_all);  // [nq, 5 h]
  const Eigen::Index hh = c.head_hidden;
  std::array<Mat, 5> ho;
  for (std::size_t k = 0; k < 5; ++k) {
    const Mat h1 = linear_relu(h0.middleCols(static_cast<Eigen::Index>(k) * hh, hh), w.head1[k]);
    ho[k] = linear(h1, w.head2[k]);
  }
  const Eigen::Index nk = c.num_classes;
  const int nb = c.num_angle_bins;
  const RowVec size_scale = extent.cwiseMax(c.min_size_extent);
  out.class_prob.resize(nq, nk);
  out.proposals.resize(static_cast<std::size_t>(nq));
  const auto bin_width = static_cast<float>(2.0 * std::numbers::pi / nb);
  const auto half_bin = static_cast<float>(std::numbers::pi / nb);
  const auto pi_f = static_cast<float>(std::numbers::pi);
  const auto two_pi_f = static_cast<float>(2.0 * std::numbers::pi);
  for (Eigen::Index q = 0; q < nq; ++q) {
    Box3& b = out.proposals[static_cast<std::size_t>(q)];
    for (int a = 0; a < 3; ++a) {
      b.centre[a] = qxyz(q, a) + (sigmoid(ho[1](q, a)) - 0.5F);
      b.size[a] = sigmoid(ho[2](q, a)) * size_scale[a];
    }
    Eigen::Index bin = 0;
    ho[3].row(q).maxCoeff(&bin);
    float yaw = static_cast<float>(bin) * bin_width + ho[4](q, bin) * half_bin;
    if (yaw > pi_f) yaw -= two_pi_f;
    b.yaw = yaw;
    // softmax over K + 1; objectness = 1 - p[background]
    const RowVec logits = ho[0].row(q);
    const float mx = logits.maxCoeff();
    const RowVec e = (logits.array() - mx).exp();
    const RowVec prob = e / e.sum();
    b.objectness = 1.0F - prob[nk];
    out.class_prob.row(q) = prob.head(nk);
    Eigen::Index label = 0;
    out.class_prob.row(q).maxCoeff(&label);
    b.label = static_cast<std::int32_t>(label);
    b.score =
        static_cast<float>(static_cast<double>(prob[label]) * static_cast<double>(b.objectness));
  }
}

// Part head (spec §6.3 option A): foreground and part-location logits of every input point.
void part_head(const Mat& p, const Mat& centres, const Mat& enc, const RowVec& scene_min,
               const RowVec& pe_extent, const SparseDetector::Weights& w, const DetectorConfig& c,
               DetectorOutput& out) {
  const Eigen::Index n = p.rows();
  const Eigen::Index t = centres.rows();
  const Eigen::Index d = c.d_model;
  // Linear in the interpolated features, so project tokens first: G = enc W0a^T [t, part_hidden].
  const Mat g = enc * w.part0.w.leftCols(d).transpose();
  const Mat wxyz = w.part0.w.rightCols(3);  // [part_hidden, 3]
  out.part_logits.resize(n, 4);
  const Eigen::Index k = std::min<Eigen::Index>(3, t);
  Mat hidden(n, c.part_hidden);
  Eigen::Matrix<Eigen::Index, Eigen::Dynamic, 3, Eigen::RowMajor> nn;
  Eigen::Matrix<float, Eigen::Dynamic, 3, Eigen::RowMajor> nn_d2;
  three_nn(centres, p, k, nn, nn_d2);
  for (Eigen::Index i = 0; i < n; ++i) {
    const Eigen::Index* idx = &nn(i, 0);
    const float* dist = &nn_d2(i, 0);
    float wt[3] = {0.0F, 0.0F, 0.0F};
    float wsum = 0.0F;
    for (Eigen::Index m = 0; m < k; ++m) {
      wt[m] = 1.0F / (dist[m] + 1e-8F);
      wsum += wt[m];
    }
    RowVec row = RowVec::Zero(c.part_hidden);
    for (Eigen::Index m = 0; m < k; ++m) row += (wt[m] / wsum) * g.row(idx[m]);
    const RowVec xn = (p.row(i) - scene_min).array() / pe_extent.array();
    row += xn * wxyz.transpose();
    hidden.row(i) = (row + w.part0.b).cwiseMax(0.0F);
  }
  out.part_logits = linear(hidden, w.part1);
}

}  // namespace

std::vector<Box3> SparseDetector::detect(Eigen::Ref<const Points3f> xyz, int num_threads) const {
  return run(xyz, DetectOptions{.num_threads = num_threads, .part_logits = false}).boxes;
}

DetectorOutput SparseDetector::run(Eigen::Ref<const Points3f> xyz,
                                   const DetectOptions& options) const {
  const int threads = detail::resolve_num_threads(options.num_threads, "ds3d::SparseDetector::run");
  const Eigen::Index n = xyz.rows();
  for (Eigen::Index i = 0; i < n; ++i) {
    DS3D_CHECK(xyz.row(i).allFinite(), "ds3d::SparseDetector::run: xyz row ", i, " is not finite (",
               xyz.row(i), ")");
  }
  DetectorOutput out;
  out.class_prob.resize(0, config_.num_classes);
  if (n == 0) return out;
  const Weights& w = *w_;
  const DetectorConfig& c = config_;
  const Mat p = xyz;  // [n, 3]
  const RowVec scene_min = p.colwise().minCoeff();
  const RowVec scene_max = p.colwise().maxCoeff();
  const RowVec extent = scene_max - scene_min;

  // ---- pre-encoder: FPS, ball query, shared MLP, max-pool --------------------------------
  const Eigen::Index t = std::min<Eigen::Index>(c.num_centres, n);
  out.centre_indices = farthest_point_sample(p, t, c.fps_padding_norm2);
  Mat centres(t, 3);  // [t, 3]
  for (Eigen::Index i = 0; i < t; ++i)
    centres.row(i) = p.row(out.centre_indices[static_cast<std::size_t>(i)]);
  const Mat feats = set_abstraction(p, centres, w, c);  // [t, d]
  const Eigen::Index d = c.d_model;

  // ---- encoder ----------------------------------------------------------------------------
  const Mat enc = encode(feats, w, c, threads);                        // [t, d]
  const Mat memory = linear_relu(linear_relu(enc, w.proj0), w.proj1);  // [t, d]

  // ---- queries and positional embeddings ---------------------------------------------------
  const Eigen::Index nq = std::min<Eigen::Index>(c.num_queries, t);
  out.query_indices = farthest_point_sample(centres, nq, c.fps_padding_norm2);
  Mat qxyz(nq, 3);  // [nq, 3]
  for (Eigen::Index i = 0; i < nq; ++i)
    qxyz.row(i) = centres.row(out.query_indices[static_cast<std::size_t>(i)]);
  const RowVec pe_extent = extent.cwiseMax(1e-6F);
  const Mat qpos = linear_relu(
      linear_relu(fourier_embedding(qxyz, scene_min, pe_extent, w.gauss_b, d), w.qproj0),
      w.qproj1);                                                                    // [nq, d]
  const Mat mpos = fourier_embedding(centres, scene_min, pe_extent, w.gauss_b, d);  // [t, d]
  const Mat mem_k = memory + mpos;

  // ---- decoder ---------------------------------------------------------------------------------
  const Mat hin = decode(memory, mem_k, qpos, w, c, threads);  // [nq, d]

  // ---- heads and box decoding ----------------------------------------------------------------
  decode_boxes(hin, qxyz, extent, w, c, out);
  for (const std::size_t i : postprocess(xyz, out.proposals)) out.boxes.push_back(out.proposals[i]);

  // ---- part head (spec §6.3 option A) ----------------------------------------------------------
  if (options.part_logits) part_head(p, centres, enc, scene_min, pe_extent, w, c, out);
  return out;
}

std::vector<std::size_t> SparseDetector::postprocess(Eigen::Ref<const Points3f> xyz,
                                                     const std::vector<Box3>& proposals) const {
  const std::size_t q = proposals.size();
  std::vector<char> keep(q, 0);
  bool any = false;
  for (std::size_t b = 0; b < q; ++b) {
    const Box3& box = proposals[b];
    const double cs = std::cos(static_cast<double>(box.yaw));
    const double sn = std::sin(static_cast<double>(box.yaw));
    const Eigen::Vector3d ctr = box.centre.cast<double>();
    const Eigen::Vector3d half = box.size.cast<double>() / 2.0;
    int count = 0;
    for (Eigen::Index i = 0; i < xyz.rows() && count < config_.min_points_in_box; ++i) {
      const double dx = static_cast<double>(xyz(i, 0)) - ctr.x();
      const double dy = static_cast<double>(xyz(i, 1)) - ctr.y();
      const double dz = static_cast<double>(xyz(i, 2)) - ctr.z();
      const double lx = cs * dx - sn * dy;
      const double ly = sn * dx + cs * dy;
      if (std::abs(lx) < half.x() && std::abs(ly) < half.y() && std::abs(dz) <= half.z()) ++count;
    }
    keep[b] = static_cast<char>(count >= config_.min_points_in_box);
    any = any || keep[b];
  }
  if (!any && q > 0) {
    std::size_t best = 0;
    for (std::size_t b = 1; b < q; ++b) {
      if (proposals[b].objectness > proposals[best].objectness) best = b;
    }
    keep[best] = 1;
  }
  std::vector<std::size_t> cand;
  for (std::size_t b = 0; b < q; ++b) {
    if (keep[b] && static_cast<double>(proposals[b].objectness) >
                       static_cast<double>(config_.score_threshold)) {
      cand.push_back(b);
    }
  }
  std::stable_sort(cand.begin(), cand.end(), [&](std::size_t a, std::size_t b) {
    return proposals[a].objectness > proposals[b].objectness;
  });
  std::vector<std::size_t> kept;
  for (const std::size_t i : cand) {
    bool suppressed = false;
    for (const std::size_t j : kept) {
      if (proposals[j].label == proposals[i].label &&
          box::aabb_iou(proposals[i], proposals[j]) > static_cast<double>(config_.nms_iou)) {
        suppressed = true;
        break;
      }
    }
    if (!suppressed) kept.push_back(i);
  }
  return kept;
}

}  // namespace ds3d
