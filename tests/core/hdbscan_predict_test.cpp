// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// HdbscanPredictor against the golden prediction outputs of the reference hdbscan 0.8.43
// (tests/data/hdbscan_predict, compared as its README prescribes), plus numpy's argsort order,
// bad input, no-cluster fits and thread independence.
#include "ds3d/cluster/hdbscan_predict.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <map>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "ds3d/detail/numpy_argsort.hpp"
#include "support/files.hpp"

namespace {

namespace fs = std::filesystem;
using ds3d::HdbscanParams;
using ds3d::HdbscanPredictor;
using ds3d::RowMatrixXd;

RowMatrixXd read_csv(const fs::path& p) {
  std::vector<std::vector<double>> rows;
  for (const auto& line : ds3d::test::read_lines(p)) {
    std::stringstream ss(line);
    std::vector<double> r;
    for (std::string f; std::getline(ss, f, ',');) r.push_back(std::strtod(f.c_str(), nullptr));
    if (!r.empty()) rows.push_back(r);
  }
  RowMatrixXd m(static_cast<Eigen::Index>(rows.size()),
                rows.empty() ? 0 : static_cast<Eigen::Index>(rows[0].size()));
  for (Eigen::Index i = 0; i < m.rows(); ++i) {
    for (Eigen::Index j = 0; j < m.cols(); ++j) {
      m(i, j) = rows[static_cast<std::size_t>(i)][static_cast<std::size_t>(j)];
    }
  }
  return m;
}

std::vector<int> read_labels(const fs::path& p) {
  std::vector<int> v;
  for (const auto& l : ds3d::test::read_lines(p)) v.push_back(std::stoi(l));
  return v;
}

/// Our label -> the reference's, from the fit (every label must map one to one).
std::map<int, int> label_map(const std::vector<std::int32_t>& ours, const std::vector<int>& ref) {
  std::map<int, int> m;
  for (std::size_t i = 0; i < ours.size(); ++i) {
    if (ours[i] >= 0) m.emplace(ours[i], ref[i]);
  }
  return m;
}

void expect_matrix_near(const RowMatrixXd& ours, const std::map<int, int>& to_ref,
                        const RowMatrixXd& ref, const char* what) {
  ASSERT_EQ(ours.rows(), ref.rows()) << what;
  ASSERT_EQ(ours.cols(), ref.cols()) << what;
  ASSERT_TRUE(ours.allFinite()) << what;
  for (Eigen::Index i = 0; i < ours.rows(); ++i) {
    for (const auto& [l, r] : to_ref) {
      ASSERT_NEAR(ours(i, l), ref(i, r), 1e-9) << what << " row " << i << " label " << l;
    }
  }
}

class PredictFixture : public ::testing::TestWithParam<std::string> {};

TEST_P(PredictFixture, MatchesReference) {
  const fs::path dir = ds3d::test::data_path("hdbscan_predict/" + GetParam());
  const auto params = ds3d::test::read_json(dir / "params.json");
  HdbscanParams p;
  p.min_cluster_size = static_cast<int>(params.at("min_cluster_size").as_int());
  p.min_samples =
      params.at("min_samples").is_null() ? 0 : static_cast<int>(params.at("min_samples").as_int());
  p.algorithm = ds3d::MstAlgorithm::kPrims;
  p.reference_tie_order = true;
  const RowMatrixXd train = read_csv(dir / "train.csv");
  const RowMatrixXd query = read_csv(dir / "query.csv");
  const auto fit = ds3d::hdbscan(train, p);
  const auto ref_fit = read_labels(dir / "fit_labels.txt");
  ASSERT_EQ(fit.labels.size(), ref_fit.size());
  const auto to_ref = label_map(fit.labels, ref_fit);
  ASSERT_EQ(to_ref.size(), static_cast<std::size_t>(fit.num_clusters));
  for (std::size_t i = 0; i < ref_fit.size(); ++i) {
    ASSERT_EQ(fit.labels[i] >= 0 ? to_ref.at(fit.labels[i]) : -1, ref_fit[i]) << "train " << i;
  }
  const HdbscanPredictor pred(train, fit, p);
  const auto r = pred.approximate_predict(query);
  const auto ref_labels = read_labels(dir / "predict_labels.txt");
  const auto ref_prob = ds3d::test::read_lines(dir / "predict_probabilities.txt");
  ASSERT_EQ(r.labels.size(), ref_labels.size());
  for (std::size_t i = 0; i < r.labels.size(); ++i) {
    EXPECT_EQ(r.labels[i] >= 0 ? to_ref.at(r.labels[i]) : -1, ref_labels[i]) << "query " << i;
    EXPECT_NEAR(r.probabilities[i], std::strtod(ref_prob[i].c_str(), nullptr), 1e-9) << i;
  }
  expect_matrix_near(pred.membership_vector(query), to_ref,
                     read_csv(dir / "membership_vectors.csv"), "membership_vector");
  if (fs::exists(dir / "all_points_membership_vectors.csv")) {
    expect_matrix_near(pred.all_points_membership_vectors(), to_ref,
                       read_csv(dir / "all_points_membership_vectors.csv"),
                       "all_points_membership_vectors");
  }
}

INSTANTIATE_TEST_SUITE_P(HdbscanPredict, PredictFixture,
                         ::testing::Values("predict_s300_n800_d2_mcs15_ms10_eom",
                                           "predict_s301_n1500_d3_mcs15_ms10_eom",
                                           "predict_s303_n600_d2_mcs25_ms5_eom",
                                           "predict_s304_n2000_d3_mcs15_ms10_eom",
                                           "predict_s306_n1200_d4_mcs20_ms10_eom",
                                           "predict_s307_n700_d3_mcs12_msNone_eom"));

RowMatrixXd blobs(int per_blob, std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> g(0.0, 0.3);
  RowMatrixXd x(3 * per_blob, 3);
  for (int i = 0; i < x.rows(); ++i) {
    const double c = 4.0 * (i / per_blob);
    x.row(i) << c + g(rng), g(rng), -c + g(rng);
  }
  return x;
}

TEST(HdbscanPredict, FittedPointsPredictTheirOwnClusters) {
  const RowMatrixXd x = blobs(60, 3);
  HdbscanParams p;
  p.min_cluster_size = 10;
  const auto fit = ds3d::hdbscan(x, p);
  ASSERT_EQ(fit.num_clusters, 3);
  const HdbscanPredictor pred(x, fit, p, 2);
  EXPECT_EQ(pred.num_labels(), 3);
  EXPECT_EQ(pred.size(), 180U);
  EXPECT_EQ(pred.dim(), 3U);
  EXPECT_EQ(pred.min_samples(), 10);
  const auto r = pred.approximate_predict(x);
  int same = 0;
  for (std::size_t i = 0; i < fit.labels.size(); ++i) same += r.labels[i] == fit.labels[i];
  EXPECT_GT(same, 170);
  const RowMatrixXd m = pred.all_points_membership_vectors();
  ASSERT_TRUE(m.allFinite());
  EXPECT_TRUE((m.rowwise().sum().array() <= 1.0 + 1e-12).all());
  for (int l = 0; l < 3; ++l) EXPECT_FALSE(pred.exemplars(l).empty());
  // Identical for any thread count.
  const HdbscanPredictor one(x, fit, p, 1);
  EXPECT_EQ(one.core_distances(), pred.core_distances());
  EXPECT_EQ(one.approximate_predict(x).probabilities, r.probabilities);
}

TEST(HdbscanPredict, NoClusterPredictsNoise) {
  RowMatrixXd x(4, 2);
  x << 0, 0, 1, 0, 0, 1, 1, 1;
  HdbscanParams p;
  p.min_cluster_size = 5;
  const auto fit = ds3d::hdbscan(x, p);
  const HdbscanPredictor pred(x, fit, p);
  const auto r = pred.approximate_predict(x);
  EXPECT_EQ(r.labels, std::vector<std::int32_t>(4, -1));
  EXPECT_EQ(r.probabilities, std::vector<double>(4, 0.0));
  EXPECT_EQ(pred.membership_vector(x).cols(), 0);
  const RowMatrixXd empty(0, 2);
  const HdbscanPredictor none(empty, ds3d::hdbscan(empty, p), p);
  EXPECT_TRUE(none.approximate_predict(x).labels == std::vector<std::int32_t>(4, -1));
}

TEST(HdbscanPredict, RejectsBadInput) {
  const RowMatrixXd x = blobs(20, 5);
  HdbscanParams p;
  p.min_cluster_size = 10;
  const auto fit = ds3d::hdbscan(x, p);
  EXPECT_THROW(HdbscanPredictor(x.topRows(10), fit, p), ds3d::InvalidArgument);
  EXPECT_THROW(HdbscanPredictor(x, fit, p, -1), ds3d::InvalidArgument);
  const HdbscanPredictor pred(x, fit, p);
  EXPECT_THROW((void)pred.approximate_predict(RowMatrixXd::Zero(2, 2)), ds3d::InvalidArgument);
  RowMatrixXd bad = x.topRows(2);
  bad(1, 2) = std::nan("");
  try {
    (void)pred.membership_vector(bad);
    FAIL() << "no throw";
  } catch (const ds3d::InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("row 1 column 2"), std::string::npos) << e.what();
  }
  EXPECT_THROW((void)pred.exemplars(7), ds3d::InvalidArgument);
}

TEST(NumpyArgsort, OrdersTiesLikeNumpy) {
  // np.argsort([1,1,1,0,0,2,1,1,0,1,1,1,1,1,1,1,1,1,1,1,0,0,1]) with numpy 1.24.
  const std::vector<double> v = {1, 1, 1, 0, 0, 2, 1, 1, 0, 1, 1, 1,
                                 1, 1, 1, 1, 1, 1, 1, 1, 0, 0, 1};
  const std::vector<std::size_t> expected = {20, 3,  4,  8, 21, 0, 19, 18, 17, 16, 15, 14,
                                             13, 11, 10, 9, 7,  6, 2,  1,  12, 22, 5};
  EXPECT_EQ(ds3d::detail::numpy_argsort(v), expected);
  std::mt19937 rng(1);
  std::vector<double> w(5000);
  for (auto& a : w) a = static_cast<double>(rng() % 40);
  const auto idx = ds3d::detail::numpy_argsort(w);
  for (std::size_t i = 1; i < idx.size(); ++i) ASSERT_LE(w[idx[i - 1]], w[idx[i]]);
}

}  // namespace
