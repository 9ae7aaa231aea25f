// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// HTx-lite inference (htx spec §3, §6). Every stage mirrors python/ds3d/htx/model.py; the
// selection steps (FPS, ball query, 3-NN) use the same float32 expressions so that the sampling
// indices are bit-identical to the PyTorch reference.
#include "ds3d/htx/sparse_detector.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <numeric>
#include <utility>

#include <Eigen/Geometry>

#include "ds3d/detail/json.hpp"
#include "ds3d/detail/parallel.hpp"
#include "ds3d/errors.hpp"
#include "ds3d/htx/weights_io.hpp"

namespace ds3d {

// The selection steps (FPS, ball query, 3-NN) must round exactly like the PyTorch reference, which
// multiplies and adds in separate kernels: forbid GCC from contracting them into FMAs when the
// build enables FMA (-mfma, -march=native). Clang contracts only within one expression, and every
// product here is its own statement.
#if defined(__GNUC__) && !defined(__clang__)
#define DS3D_NO_FP_CONTRACT __attribute__((optimize("fp-contract=off")))
#else
#define DS3D_NO_FP_CONTRACT
#endif

using Mat = Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
using Vec = Eigen::VectorXf;
using RowVec = Eigen::RowVectorXf;

namespace {

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

constexpr const char* kHeadNames[5] = {"sem_cls_head", "center_head", "size_head", "angle_cls_head",
                                       "angle_residual_head"};

// y = x W^T + b  ([rows, in] -> [rows, out]). The bias is written first and the product added
// into it: Eigen would otherwise zero the output before its GEMM and add the bias in another pass.
// [rows, b.size()] with every row = b (row copies: Eigen's replicate() indexes element-wise).
template <class Row>
Mat broadcast_rows(const Row& b, Eigen::Index rows) {
  Mat y(rows, b.size());
  for (Eigen::Index r = 0; r < rows; ++r) y.row(r) = b;
  return y;
}

Mat linear(const Mat& x, const Linear& l) {
  Mat y = broadcast_rows(l.b, x.rows());
  y.noalias() += x * l.w.transpose();
  return y;
}
Mat linear_relu(const Mat& x, const Linear& l) {
  Mat y = linear(x, l);
  y = y.cwiseMax(0.0F);  // in place: no second [rows, out] buffer
  return y;
}

Mat layer_norm(const Mat& x, const Norm& n, float eps) {
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

float sigmoid(float x) { return 1.0F / (1.0F + std::exp(-x)); }

// FPS of k indices over rows of p (spec §3.2); float32 expressions identical to ops.py.
// Non-candidates (padding) carry distance -1 forever: min(-1, d2) = -1 never beats best_d = -1.
DS3D_NO_FP_CONTRACT std::vector<std::int32_t> farthest_point_sample(const Mat& p, Eigen::Index k,
                                                                    float padding_norm2) {
  const Eigen::Index n = p.rows();
  std::vector<std::int32_t> out(static_cast<std::size_t>(k), 0);
  if (n == 0 || k == 0) return out;
  const Eigen::ArrayXf x = p.col(0), y = p.col(1), z = p.col(2);  // structure of arrays
  Eigen::ArrayXf dist(n);
  for (Eigen::Index j = 0; j < n; ++j) {
    const float xx = x[j] * x[j], yy = y[j] * y[j], zz = z[j] * z[j];
    dist[j] = (xx + yy) + zz > padding_norm2 ? 1e10F : -1.0F;
  }
  Eigen::Index last = 0;
  const float* px = x.data();
  const float* py = y.data();
  const float* pz = z.data();
  float* pd = dist.data();
  for (Eigen::Index i = 1; i < k; ++i) {
    const float lx = px[last], ly = py[last], lz = pz[last];
    for (Eigen::Index j = 0; j < n; ++j) {  // branch-free: vectorised (blend, no FMA)
      const float dx = px[j] - lx, dy = py[j] - ly, dz = pz[j] - lz;
      const float xx = dx * dx, yy = dy * dy, zz = dz * dz;
      const float d2 = (xx + yy) + zz;
      pd[j] = d2 < pd[j] ? d2 : pd[j];
    }
    const float best_d = std::max(-1.0F, dist.maxCoeff());  // Eigen's vectorised reduction
    Eigen::Index best = 0;
    if (best_d >= 0.0F) {
      while (pd[best] != best_d) ++best;  // lowest index holding the maximum
    }
    last = best;
    out[static_cast<std::size_t>(i)] = static_cast<std::int32_t>(best);
  }
  return out;
}

// Ball query "first s by index" (strict <) around every centre: the offsets / r of the distinct
// samples, group i in rows [begin[i], begin[i+1]). The reference repeats the first index in empty
// slots; a repeated row cannot change a max-pool, so only distinct samples are returned.
// Candidates come from a uniform grid of cell size slightly above r (27 cells per centre, each
// cell's points in index order); their distances use the reference's float expression, and the
// first s by index are kept, so the result equals the brute-force scan. Clouds whose bounding box
// would need a huge grid fall back to that scan.
DS3D_NO_FP_CONTRACT Mat ball_group(const Mat& p, const Mat& centres, float r, Eigen::Index s,
                                   std::vector<Eigen::Index>& begin) {
  const Eigen::Index t = centres.rows();
  const Eigen::Index n = p.rows();
  const float r2 = r * r;
  begin.assign(static_cast<std::size_t>(t) + 1, 0);
  Mat grouped(t * s, 3);
  Eigen::Index rows = 0;
  auto take = [&](Eigen::Index i, Eigen::Index j) {
    grouped.row(rows++) = (p.row(j) - centres.row(i)) / r;
  };
  const Eigen::RowVector3f lo = p.colwise().minCoeff();
  const Eigen::RowVector3f hi = p.colwise().maxCoeff();
  const float cell = r * 1.001F;  // margin against rounding in the cell index
  Eigen::Array3i dims;
  double num_cells = 1.0;
  for (int a = 0; a < 3; ++a) {
    const double cells = std::floor(static_cast<double>(hi[a] - lo[a]) / cell) + 1.0;
    dims[a] = static_cast<int>(std::min(cells, 1e6));
    num_cells *= cells;
  }
  if (num_cells > 4.0 * static_cast<double>(n) + 4096.0) {  // sparse outliers: brute force
    for (Eigen::Index i = 0; i < t; ++i) {
      const float cx = centres(i, 0), cy = centres(i, 1), cz = centres(i, 2);
      Eigen::Index found = 0;
      for (Eigen::Index j = 0; j < n && found < s; ++j) {
        const float dx = cx - p(j, 0), dy = cy - p(j, 1), dz = cz - p(j, 2);
        const float xx = dx * dx, yy = dy * dy, zz = dz * dz;
        if ((xx + yy) + zz < r2) {
          take(i, j);
          ++found;
        }
      }
      begin[static_cast<std::size_t>(i) + 1] = rows;
    }
    grouped.conservativeResize(rows, 3);
    return grouped;
  }
  auto cell_of = [&](float v, int a) {
    return std::clamp(static_cast<int>((v - lo[a]) / cell), 0, dims[a] - 1);
  };
  const auto total = static_cast<std::size_t>(dims[0]) * static_cast<std::size_t>(dims[1]) *
                     static_cast<std::size_t>(dims[2]);
  // Counting sort of points by cell: stable, so every cell lists its points in index order.
  std::vector<std::int32_t> start(total + 1, 0);
  std::vector<std::int32_t> key(static_cast<std::size_t>(n));
  for (Eigen::Index j = 0; j < n; ++j) {
    const auto kx = static_cast<std::size_t>(cell_of(p(j, 0), 0));
    const auto ky = static_cast<std::size_t>(cell_of(p(j, 1), 1));
    const auto kz = static_cast<std::size_t>(cell_of(p(j, 2), 2));
    const std::size_t k =
        (kx * static_cast<std::size_t>(dims[1]) + ky) * static_cast<std::size_t>(dims[2]) + kz;
    key[static_cast<std::size_t>(j)] = static_cast<std::int32_t>(k);
    ++start[k + 1];
  }
  for (std::size_t k = 0; k < total; ++k) start[k + 1] += start[k];
  std::vector<std::int32_t> order(static_cast<std::size_t>(n));
  {
    std::vector<std::int32_t> fill(start.begin(), start.end() - 1);
    for (Eigen::Index j = 0; j < n; ++j) {
      order[static_cast<std::size_t>(
          fill[static_cast<std::size_t>(key[static_cast<std::size_t>(j)])]++)] =
          static_cast<std::int32_t>(j);
    }
  }
  std::vector<std::int32_t> cand;
  for (Eigen::Index i = 0; i < t; ++i) {
    const float cx = centres(i, 0), cy = centres(i, 1), cz = centres(i, 2);
    const int gx = cell_of(cx, 0), gy = cell_of(cy, 1), gz = cell_of(cz, 2);
    cand.clear();
    for (int x = std::max(gx - 1, 0); x <= std::min(gx + 1, dims[0] - 1); ++x) {
      for (int y = std::max(gy - 1, 0); y <= std::min(gy + 1, dims[1] - 1); ++y) {
        for (int z = std::max(gz - 1, 0); z <= std::min(gz + 1, dims[2] - 1); ++z) {
          const std::size_t k = (static_cast<std::size_t>(x) * static_cast<std::size_t>(dims[1]) +
                                 static_cast<std::size_t>(y)) *
                                    static_cast<std::size_t>(dims[2]) +
                                static_cast<std::size_t>(z);
          for (std::int32_t q = start[k]; q < start[k + 1]; ++q) {
            const std::int32_t j = order[static_cast<std::size_t>(q)];
            const float dx = cx - p(j, 0), dy = cy - p(j, 1), dz = cz - p(j, 2);
            const float xx = dx * dx, yy = dy * dy, zz = dz * dz;
            if ((xx + yy) + zz < r2) cand.push_back(j);
          }
        }
      }
    }
    const auto keep = std::min<std::size_t>(cand.size(), static_cast<std::size_t>(s));
    std::partial_sort(cand.begin(), cand.begin() + static_cast<std::ptrdiff_t>(keep), cand.end());
    for (std::size_t q = 0; q < keep; ++q) take(i, cand[q]);
    begin[static_cast<std::size_t>(i) + 1] = rows;
  }
  grouped.conservativeResize(rows, 3);
  return grouped;
}

// The 3 nearest tokens of point (x, y, z) (lowest index first on ties) and their squared
// distances; k = min(3, tokens) entries are valid.
DS3D_NO_FP_CONTRACT void three_nn(const Mat& tokens, float x, float y, float z, Eigen::Index k,
                                  Eigen::Index idx[3], float dist[3]) {
  for (int m = 0; m < 3; ++m) {
    idx[m] = 0;
    dist[m] = INFINITY;
  }
  for (Eigen::Index j = 0; j < tokens.rows(); ++j) {
    const float dx = x - tokens(j, 0), dy = y - tokens(j, 1), dz = z - tokens(j, 2);
    const float xx = dx * dx, yy = dy * dy, zz = dz * dz;
    const float d2 = (xx + yy) + zz;
    if (d2 < dist[k - 1]) {  // insert, keeping earlier (lower-index) entries first on ties
      Eigen::Index m = k - 1;
      while (m > 0 && d2 < dist[m - 1]) {
        dist[m] = dist[m - 1];
        idx[m] = idx[m - 1];
        --m;
      }
      dist[m] = d2;
      idx[m] = j;
    }
  }
}

int get_int(const detail::JsonValue& o, const char* key) {
  const auto v = o.at(key).as_int();
  DS3D_CHECK_AS(IoError, v >= -2147483647 && v <= 2147483647, "config key '", key,
                "' out of range");
  return static_cast<int>(v);
}
float get_float(const detail::JsonValue& o, const char* key) {
  const double v = o.at(key).as_number();
  DS3D_CHECK_AS(IoError, std::isfinite(v), "config key '", key, "' is not finite");
  return static_cast<float>(v);
}

}  // namespace

struct SparseDetector::Weights {
  std::vector<Linear> sa_mlp;
  std::vector<EncLayer> enc;
  Linear proj0, proj1;
  Mat gauss_b;  // [3, d/2]
  Linear qproj0, qproj1;
  std::vector<DecLayer> dec;
  Norm dec_norm;
  Linear head0_all;             // the 5 heads' first layers stacked: [5 h, d]
  std::array<Linear, 5> head1;  // [h, h]
  std::array<Linear, 5> head2;  // [out, h]
  Linear part0, part1;
};

DetectorConfig DetectorConfig::from_json(std::string_view json) {
  detail::JsonValue o;
  try {
    o = detail::parse_json(json);
  } catch (const IoError& e) {
    throw IoError(std::string("ds3d::DetectorConfig::from_json: ") + e.what());
  }
  DetectorConfig c;
  try {
    c.profile = o.at("profile").as_string();
    c.num_centres = get_int(o, "num_centres");
    c.sa_radius = get_float(o, "sa_radius");
    c.sa_samples = get_int(o, "sa_samples");
    c.sa_mlp.clear();
    for (const auto& v : o.at("sa_mlp").as_array()) {
      const auto x = v.as_int();
      DS3D_CHECK_AS(IoError, x > 0 && x < 65536, "sa_mlp width out of range");
      c.sa_mlp.push_back(static_cast<int>(x));
    }
    c.d_model = get_int(o, "d_model");
    c.num_heads = get_int(o, "num_heads");
    c.enc_layers = get_int(o, "enc_layers");
    c.enc_ffn = get_int(o, "enc_ffn");
    c.dec_layers = get_int(o, "dec_layers");
    c.dec_ffn = get_int(o, "dec_ffn");
    c.num_queries = get_int(o, "num_queries");
    c.num_classes = get_int(o, "num_classes");
    c.class_names.clear();
    for (const auto& v : o.at("class_names").as_array()) c.class_names.push_back(v.as_string());
    c.num_angle_bins = get_int(o, "num_angle_bins");
    c.head_hidden = get_int(o, "head_hidden");
    c.part_hidden = get_int(o, "part_hidden");
    c.layer_norm_eps = get_float(o, "layer_norm_eps");
    c.min_points_in_box = get_int(o, "min_points_in_box");
    c.nms_iou = get_float(o, "nms_iou");
    c.score_threshold = get_float(o, "score_threshold");
    c.min_size_extent = get_float(o, "min_size_extent");
    c.fps_padding_norm2 = get_float(o, "fps_padding_norm2");
    DS3D_CHECK_AS(IoError, o.at("bn_folded").as_bool(), "bn_folded must be true");
    DS3D_CHECK_AS(IoError, o.at("in_proj").as_string() == "packed_qkv",
                  "in_proj must be 'packed_qkv'");
  } catch (const IoError& e) {
    throw IoError(std::string("ds3d::DetectorConfig::from_json: ") + e.what());
  }
  c.validate();
  return c;
}

void DetectorConfig::validate() const {
  auto check = [](bool ok, const char* key, auto value) {
    DS3D_CHECK_AS(IoError, ok, "ds3d::DetectorConfig: ", key, " out of range (got ", value, ")");
  };
  constexpr int kMax = 1 << 16;
  check(num_centres > 0 && num_centres <= kMax, "num_centres", num_centres);
  check(sa_radius > 0.0F && std::isfinite(sa_radius), "sa_radius", sa_radius);
  check(sa_samples > 0 && sa_samples <= 4096, "sa_samples", sa_samples);
  check(!sa_mlp.empty() && sa_mlp.size() <= 16, "sa_mlp size", sa_mlp.size());
  check(d_model > 0 && d_model <= 8192 && d_model % 2 == 0, "d_model", d_model);
  check(num_heads > 0 && d_model % num_heads == 0, "num_heads", num_heads);
  check(sa_mlp.back() == d_model, "sa_mlp last width", sa_mlp.back());
  check(enc_layers >= 0 && enc_layers <= 64, "enc_layers", enc_layers);
  check(dec_layers > 0 && dec_layers <= 64, "dec_layers", dec_layers);
  check(enc_ffn > 0 && enc_ffn <= kMax, "enc_ffn", enc_ffn);
  check(dec_ffn > 0 && dec_ffn <= kMax, "dec_ffn", dec_ffn);
  check(num_queries > 0 && num_queries <= kMax, "num_queries", num_queries);
  check(num_classes > 0 && num_classes <= 4096, "num_classes", num_classes);
  check(class_names.size() == static_cast<std::size_t>(num_classes), "class_names size",
        class_names.size());
  check(num_angle_bins > 0 && num_angle_bins <= 360, "num_angle_bins", num_angle_bins);
  check(head_hidden > 0 && head_hidden <= kMax, "head_hidden", head_hidden);
  check(part_hidden > 0 && part_hidden <= kMax, "part_hidden", part_hidden);
  check(layer_norm_eps > 0.0F, "layer_norm_eps", layer_norm_eps);
  check(min_points_in_box >= 0, "min_points_in_box", min_points_in_box);
  check(nms_iou >= 0.0F && nms_iou <= 1.0F, "nms_iou", nms_iou);
  check(score_threshold >= 0.0F && score_threshold < 1.0F, "score_threshold", score_threshold);
  check(min_size_extent > 0.0F, "min_size_extent", min_size_extent);
  check(fps_padding_norm2 >= 0.0F, "fps_padding_norm2", fps_padding_norm2);
}

std::string DetectorConfig::to_json() const {
  auto ints = [](const std::vector<int>& v) {
    std::string s = "[";
    for (std::size_t i = 0; i < v.size(); ++i) {
      if (i) s += ',';
      s += std::to_string(v[i]);
    }
    s += ']';
    return s;
  };
  std::string names = "[";
  for (std::size_t i = 0; i < class_names.size(); ++i) {
    if (i) names += ',';
    names += '"';
    names += detail::json_escape(class_names[i]);
    names += '"';
  }
  names += "]";
  auto num = [](float v) { return detail::json_number(static_cast<double>(v)); };
  return "{\"profile\":\"" + detail::json_escape(profile) +
         "\",\"num_centres\":" + std::to_string(num_centres) + ",\"sa_radius\":" + num(sa_radius) +
         ",\"sa_samples\":" + std::to_string(sa_samples) + ",\"sa_mlp\":" + ints(sa_mlp) +
         ",\"d_model\":" + std::to_string(d_model) + ",\"num_heads\":" + std::to_string(num_heads) +
         ",\"enc_layers\":" + std::to_string(enc_layers) +
         ",\"enc_ffn\":" + std::to_string(enc_ffn) +
         ",\"dec_layers\":" + std::to_string(dec_layers) +
         ",\"dec_ffn\":" + std::to_string(dec_ffn) +
         ",\"num_queries\":" + std::to_string(num_queries) +
         ",\"num_classes\":" + std::to_string(num_classes) + ",\"class_names\":" + names +
         ",\"num_angle_bins\":" + std::to_string(num_angle_bins) +
         ",\"head_hidden\":" + std::to_string(head_hidden) +
         ",\"part_hidden\":" + std::to_string(part_hidden) +
         ",\"layer_norm_eps\":" + num(layer_norm_eps) +
         ",\"min_points_in_box\":" + std::to_string(min_points_in_box) +
         ",\"nms_iou\":" + num(nms_iou) + ",\"score_threshold\":" + num(score_threshold) +
         ",\"min_size_extent\":" + num(min_size_extent) +
         ",\"fps_padding_norm2\":" + num(fps_padding_norm2) +
         ",\"bn_folded\":true,\"in_proj\":\"packed_qkv\",\"format_version\":1}";
}

DetectorConfig DetectorConfig::make_profile(std::string_view name) {
  DS3D_CHECK(name == "fast" || name == "quality",
             "ds3d::DetectorConfig::make_profile: name must be 'fast' or 'quality' (got '", name,
             "')");
  DetectorConfig c;
  c.profile = std::string(name);
  c.num_centres = name == "fast" ? 384 : 512;
  c.sa_mlp = {32, 64, 128};
  c.class_names = {"person"};
  return c;
}

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

  // ---- encoder ----------------------------------------------------------------------------
  Mat enc = feats;
  for (const auto& l : w.enc) {
    Mat y = layer_norm(enc, l.n1, c.layer_norm_eps);
    enc += attention(y, y, y, l.self_attn, c.num_heads, threads);
    y = layer_norm(enc, l.n2, c.layer_norm_eps);
    enc += linear(linear_relu(y, l.l1), l.l2);
  }
  const Mat memory = linear_relu(linear_relu(enc, w.proj0), w.proj1);  // [t, d]

  // ---- queries and positional embeddings ---------------------------------------------------
  const Eigen::Index nq = std::min<Eigen::Index>(c.num_queries, t);
  out.query_indices = farthest_point_sample(centres, nq, c.fps_padding_norm2);
  Mat qxyz(nq, 3);  // [nq, 3]
  for (Eigen::Index i = 0; i < nq; ++i)
    qxyz.row(i) = centres.row(out.query_indices[static_cast<std::size_t>(i)]);
  const RowVec pe_extent = extent.cwiseMax(1e-6F);
  auto fourier = [&](const Mat& pts) {  // [m, 3] -> [m, d]
    Mat xh(pts.rows(), 3);
    for (Eigen::Index i = 0; i < pts.rows(); ++i) {
      xh.row(i) = ((pts.row(i) - scene_min).array() / pe_extent.array()) *
                  static_cast<float>(2.0 * std::numbers::pi);
    }
    const Mat u = xh * w.gauss_b;  // [m, d/2]
    Mat e(pts.rows(), d);
    e.leftCols(d / 2) = u.array().sin();
    e.rightCols(d / 2) = u.array().cos();
    return e;
  };
  const Mat qpos = linear_relu(linear_relu(fourier(qxyz), w.qproj0), w.qproj1);  // [nq, d]
  const Mat mpos = fourier(centres);                                             // [t, d]
  const Mat mem_k = memory + mpos;

  // ---- decoder ---------------------------------------------------------------------------------
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
  const Mat hin = layer_norm(tgt, w.dec_norm, c.layer_norm_eps);  // [nq, d]

  // ---- heads and box decoding ----------------------------------------------------------------
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
  for (const std::size_t i : postprocess(xyz, out.proposals)) out.boxes.push_back(out.proposals[i]);

  // ---- part head (spec §6.3 option A) ----------------------------------------------------------
  if (options.part_logits) {
    // Linear in the interpolated features, so project tokens first: G = enc W0a^T  [t,
    // part_hidden].
    const Mat g = enc * w.part0.w.leftCols(d).transpose();
    const Mat wxyz = w.part0.w.rightCols(3);  // [part_hidden, 3]
    out.part_logits.resize(n, 4);
    const Eigen::Index k = std::min<Eigen::Index>(3, t);
    Mat hidden(n, c.part_hidden);
    for (Eigen::Index i = 0; i < n; ++i) {
      Eigen::Index idx[3];
      float dist[3];
      three_nn(centres, p(i, 0), p(i, 1), p(i, 2), k, idx, dist);
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

// ---- detector input (htx spec §6.1) -------------------------------------------------------

void DetectorInputParams::validate() const {
  DS3D_CHECK(num_points >= 1, "ds3d::DetectorInputParams: num_points must be >= 1 (got ",
             num_points, ")");
}

Eigen::Matrix3f upright_rotation(const Eigen::Vector3d& up_cam) {
  DS3D_CHECK(up_cam.allFinite() && up_cam.norm() > 0.0,
             "ds3d::upright_rotation: up_cam must be finite and non-zero (got ", up_cam.transpose(),
             ")");
  Eigen::Matrix3d swap;  // camera (x right, y down, z fwd) -> upright (X right, Y fwd, Z up)
  swap << 1, 0, 0, 0, 0, 1, 0, -1, 0;
  const Eigen::Vector3d n = (swap * up_cam).normalized();
  DS3D_CHECK(n.z() > 0.0, "ds3d::upright_rotation: up_cam points below the horizon (got ",
             up_cam.transpose(), ")");
  // Rows of the rotation (in the swapped frame): Z = n, Y = the optical axis (swapped: +Y)
  // projected onto the floor, X = Y x Z; the same convention as the trainer
  // (python/ds3d/htx/data.py gravity_rotation). n.z > 0 keeps the projection non-degenerate.
  const Eigen::Vector3d fwd = (Eigen::Vector3d::UnitY() - n.y() * n).normalized();
  Eigen::Matrix3d rows;
  rows.row(0) = fwd.cross(n);
  rows.row(1) = fwd;
  rows.row(2) = n;
  return (rows * swap).cast<float>();
}

DetectorInput make_detector_input(Eigen::Ref<const Points3f> cloud_cam,
                                  const Eigen::Matrix3f& R_up_cam,
                                  const DetectorInputParams& params) {
  params.validate();
  const auto n = static_cast<std::size_t>(cloud_cam.rows());
  for (std::size_t i = 0; i < n; ++i) {
    DS3D_CHECK(cloud_cam.row(static_cast<Eigen::Index>(i)).allFinite(),
               "ds3d::make_detector_input: cloud_cam row ", i, " is not finite");
  }
  DetectorInput out;
  out.R_up_cam = R_up_cam;
  if (n == 0) return out;
  // SplitMix64 (Steele et al. 2014): tiny, and the same stream on every platform, which
  // std::uniform_int_distribution does not promise.
  std::uint64_t state = params.seed;
  const auto next = [&state](std::uint64_t bound) {
    state += 0x9E3779B97F4A7C15ULL;
    std::uint64_t z = state;
    z = (z ^ (z >> 30U)) * 0xBF58476D1CE4E5B9ULL;
    z = (z ^ (z >> 27U)) * 0x94D049BB133111EBULL;
    return (z ^ (z >> 31U)) % bound;  // bias < bound / 2^64
  };
  const auto m = static_cast<std::size_t>(params.num_points);
  std::vector<std::uint32_t> rows(std::max(n, m));
  std::iota(rows.begin(), rows.begin() + static_cast<std::ptrdiff_t>(n), 0U);
  for (std::size_t i = n; i < m; ++i) rows[i] = static_cast<std::uint32_t>(next(n));
  // Partial Fisher-Yates: the first m entries become a uniform random draw in random order.
  for (std::size_t i = 0; i < m; ++i) {
    const std::size_t j = i + static_cast<std::size_t>(next(rows.size() - i));
    std::swap(rows[i], rows[j]);
  }
  rows.resize(m);
  out.points.resize(static_cast<Eigen::Index>(m), 3);
  for (std::size_t i = 0; i < m; ++i) {
    out.points.row(static_cast<Eigen::Index>(i)) =
        (R_up_cam * cloud_cam.row(static_cast<Eigen::Index>(rows[i])).transpose()).transpose();
  }
  out.rows = std::move(rows);
  return out;
}

}  // namespace ds3d
