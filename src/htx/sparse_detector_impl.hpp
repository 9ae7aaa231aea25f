// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
#pragma once
// Internals of the HTx-lite inference shared by src/htx/*.cpp: layer weights, the
// SparseDetector::Weights struct, the dense helpers (inline, so that every stage compiles the
// same arithmetic it did in one file) and the stage functions split across files. Not API.

#include <array>
#include <cmath>
#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "ds3d/htx/sparse_detector.hpp"

// The selection steps (FPS, ball query, 3-NN) must round exactly like the PyTorch reference, which
// multiplies and adds in separate kernels: forbid GCC from contracting them into FMAs when the
// build enables FMA (-mfma, -march=native). Clang contracts only within one expression, and every
// product here is its own statement.
#if defined(__GNUC__) && !defined(__clang__)
#define DS3D_NO_FP_CONTRACT __attribute__((optimize("fp-contract=off")))
#else
#define DS3D_NO_FP_CONTRACT
#endif

namespace ds3d::detail::htx {

using Mat = Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
using Vec = Eigen::VectorXf;
using RowVec = Eigen::RowVectorXf;

struct Linear {
  Mat w;     // [out, in]
  RowVec b;  // [out]
};
struct Norm {
  RowVec g, b;
};
struct Attention {
  Mat w_in;  // [3d, d]: q, k, v rows
  RowVec b_in;
  Linear out;
};
struct EncLayer {
  Attention self_attn;
  Linear l1, l2;
  Norm n1, n2;
};
struct DecLayer {
  Attention self_attn, cross_attn;
  Linear l1, l2;
  Norm n1, n2, n3;
};

// y = x W^T + b  ([rows, in] -> [rows, out]). The bias is written first and the product added
// into it: Eigen would otherwise zero the output before its GEMM and add the bias in another pass.
// [rows, b.size()] with every row = b (row copies: Eigen's replicate() indexes element-wise).
template <class Row>
Mat broadcast_rows(const Row& b, Eigen::Index rows) {
  Mat y(rows, b.size());
  for (Eigen::Index r = 0; r < rows; ++r) y.row(r) = b;
  return y;
}

inline Mat linear(const Mat& x, const Linear& l) {
  Mat y = broadcast_rows(l.b, x.rows());
  y.noalias() += x * l.w.transpose();
  return y;
}
inline Mat linear_relu(const Mat& x, const Linear& l) {
  Mat y = linear(x, l);
  y = y.cwiseMax(0.0F);  // in place: no second [rows, out] buffer
  return y;
}

inline Mat layer_norm(const Mat& x, const Norm& n, float eps) {
  Mat y(x.rows(), x.cols());
  const float inv_d = 1.0F / static_cast<float>(x.cols());
  for (Eigen::Index r = 0; r < x.rows(); ++r) {
    const float mean = x.row(r).sum() * inv_d;
    const RowVec c = x.row(r).array() - mean;
    const float var = c.squaredNorm() * inv_d;
    y.row(r) = (c * (1.0F / std::sqrt(var + eps))).cwiseProduct(n.g) + n.b;
  }
  return y;
}

inline float sigmoid(float x) { return 1.0F / (1.0F + std::exp(-x)); }

// ---- point_sampling.cpp: the selection steps, rounded exactly like the PyTorch reference ----

// FPS of k indices over rows of p (spec §3.2).
DS3D_NO_FP_CONTRACT std::vector<std::int32_t> farthest_point_sample(const Mat& p, Eigen::Index k,
                                                                    float padding_norm2);
// Ball query "first s by index" around every centre: offsets / r, group i in rows
// [begin[i], begin[i+1]).
DS3D_NO_FP_CONTRACT Mat ball_group(const Mat& p, const Mat& centres, float r, Eigen::Index s,
                                   std::vector<Eigen::Index>& begin);
// The 3 nearest tokens of every row of `points` (lowest index first on ties) and their squared
// distances: row i of idx / dist, of which k = min(3, tokens) entries are valid.
DS3D_NO_FP_CONTRACT void three_nn(
    const Mat& tokens, const Mat& points, Eigen::Index k,
    Eigen::Matrix<Eigen::Index, Eigen::Dynamic, 3, Eigen::RowMajor>& idx,
    Eigen::Matrix<float, Eigen::Dynamic, 3, Eigen::RowMajor>& dist);

// ---- transformer.cpp: encoder, positional embedding, decoder ------------------------------

// Encoder layers over the token features: [t, d] -> [t, d].
Mat encode(Mat enc, const SparseDetector::Weights& w, const DetectorConfig& c, int threads);
// Fourier positional embedding of points in the scene box: [m, 3] -> [m, d].
Mat fourier_embedding(const Mat& pts, const RowVec& scene_min, const RowVec& pe_extent,
                      const Mat& gauss_b, Eigen::Index d);
// Decoder layers and the final LayerNorm: queries qpos [nq, d] over memory [t, d] -> [nq, d].
Mat decode(const Mat& memory, const Mat& mem_k, const Mat& qpos, const SparseDetector::Weights& w,
           const DetectorConfig& c, int threads);

}  // namespace ds3d::detail::htx

namespace ds3d {

struct SparseDetector::Weights {
  using Linear = detail::htx::Linear;
  using Norm = detail::htx::Norm;
  using Mat = detail::htx::Mat;
  std::vector<Linear> sa_mlp;
  std::vector<detail::htx::EncLayer> enc;
  Linear proj0, proj1;
  Mat gauss_b;  // [3, d/2]
  Linear qproj0, qproj1;
  std::vector<detail::htx::DecLayer> dec;
  Norm dec_norm;
  Linear head0_all;             // the 5 heads' first layers stacked: [5 h, d]
  std::array<Linear, 5> head1;  // [h, h]
  std::array<Linear, 5> head2;  // [out, h]
  Linear part0, part1;
};

}  // namespace ds3d
