// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// The transformer of the forward pass: multi-head attention, the pre-norm encoder and decoder
// layers (3DETR) and the Fourier positional embedding of the queries and tokens.
#include <cmath>
#include <cstddef>
#include <numbers>

#include "ds3d/detail/parallel.hpp"
#include "sparse_detector_impl.hpp"

namespace ds3d::detail::htx {

namespace {

// Multi-head attention as torch.nn.MultiheadAttention (packed in_proj, scale 1/sqrt(head_dim)).
// q_in [nq, d], k_in [nk, d], v_in [nk, d] -> [nq, d]. Heads run in parallel on num_threads.
// Softmax row by row while the row is in L1 (max, exp, sum in one sweep each over nk floats
// instead of three passes over the whole [nq, nk] matrix), and its 1/sum is applied to the
// [nq, hd] output instead of the [nq, nk] weights (same value up to float rounding, ~1e-7).
Mat attention(const Mat& q_in, const Mat& k_in, const Mat& v_in, const Attention& a, int heads,
              int num_threads) {
  const Eigen::Index d = a.w_in.cols();
  const Eigen::Index hd = d / heads;
  Mat q;
  Mat k;
  Mat v;
  if (&q_in == &k_in && &k_in == &v_in) {           // self-attention on one input: one [n, 3d] GEMM
    Mat qkv = broadcast_rows(a.b_in, q_in.rows());  // [n, 3d]
    qkv.noalias() += q_in * a.w_in.transpose();
    q = qkv.leftCols(d);
    k = qkv.middleCols(d, d);
    v = qkv.rightCols(d);
  } else {
    q = broadcast_rows(a.b_in.head(d), q_in.rows());
    q.noalias() += q_in * a.w_in.topRows(d).transpose();
    k = broadcast_rows(a.b_in.segment(d, d), k_in.rows());
    k.noalias() += k_in * a.w_in.middleRows(d, d).transpose();
    v = broadcast_rows(a.b_in.tail(d), v_in.rows());
    v.noalias() += v_in * a.w_in.bottomRows(d).transpose();
  }
  q *= 1.0F / std::sqrt(static_cast<float>(hd));
  Mat o(q.rows(), d);
  detail::parallel_chunks(static_cast<std::size_t>(heads), static_cast<std::size_t>(heads),
                          num_threads, [&](std::size_t begin, std::size_t end, std::size_t) {
                            Mat s(q.rows(), k.rows());  // [nq, nk]
                            Vec inv(q.rows());
                            for (std::size_t h = begin; h < end; ++h) {
                              const auto c0 = static_cast<Eigen::Index>(h) * hd;
                              s.noalias() = q.middleCols(c0, hd) * k.middleCols(c0, hd).transpose();
                              for (Eigen::Index r = 0; r < s.rows(); ++r) {
                                auto row = s.row(r).array();
                                row = (row - row.maxCoeff()).exp();  // Eigen's vectorised exp
                                inv[r] = 1.0F / row.sum();
                              }
                              o.middleCols(c0, hd).noalias() = s * v.middleCols(c0, hd);
                              o.middleCols(c0, hd) = inv.asDiagonal() * o.middleCols(c0, hd);
                            }
                          });
  return linear(o, a.out);
}

}  // namespace

Mat encode(Mat enc, const SparseDetector::Weights& w, const DetectorConfig& c, int threads) {
  for (const auto& l : w.enc) {
    Mat y = layer_norm(enc, l.n1, c.layer_norm_eps);
    enc += attention(y, y, y, l.self_attn, c.num_heads, threads);
    y = layer_norm(enc, l.n2, c.layer_norm_eps);
    enc += linear(linear_relu(y, l.l1), l.l2);
  }
  return enc;
}

Mat fourier_embedding(const Mat& pts, const RowVec& scene_min, const RowVec& pe_extent,
                      const Mat& gauss_b, Eigen::Index d) {
  Mat xh(pts.rows(), 3);
  for (Eigen::Index i = 0; i < pts.rows(); ++i) {
    xh.row(i) = ((pts.row(i) - scene_min).array() / pe_extent.array()) *
                static_cast<float>(2.0 * std::numbers::pi);
  }
  const Mat u = xh * gauss_b;  // [m, d/2]
  Mat e(pts.rows(), d);
  e.leftCols(d / 2) = u.array().sin();
  e.rightCols(d / 2) = u.array().cos();
  return e;
}

Mat decode(const Mat& memory, const Mat& mem_k, const Mat& qpos, const SparseDetector::Weights& w,
           const DetectorConfig& c, int threads) {
  const Eigen::Index nq = qpos.rows();
  const Eigen::Index d = c.d_model;
  Mat tgt = Mat::Zero(nq, d);  // [nq, d]
  for (const auto& l : w.dec) {
    Mat y = layer_norm(tgt, l.n1, c.layer_norm_eps);
    const Mat qk = y + qpos;
    tgt += attention(qk, qk, y, l.self_attn, c.num_heads, threads);
    y = layer_norm(tgt, l.n2, c.layer_norm_eps);
    tgt += attention(y + qpos, mem_k, memory, l.cross_attn, c.num_heads, threads);
    y = layer_norm(tgt, l.n3, c.layer_norm_eps);
    tgt += linear(linear_relu(y, l.l1), l.l2);
  }
  return layer_norm(tgt, w.dec_norm, c.layer_norm_eps);  // [nq, d]
}

}  // namespace ds3d::detail::htx
