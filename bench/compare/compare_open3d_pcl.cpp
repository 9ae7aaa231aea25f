// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// ds3d vs Open3D 0.16 vs PCL 1.13 on the rendered room frames (~300k and ~1M points), single
// thread, medians measured in the same run (wall and thread-CPU time); prints one Markdown table
// with ratios and a check column (voxels, kept points, inliers of the returned plane counted in
// double with < t).
// Usage: compare_open3d_pcl [--sizes 300000,1000000] [--reps N] [--slow-reps N]
//                           [--ops voxel,radius,plane]
#include <omp.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <functional>
#include <string>
#include <vector>

#include <open3d/geometry/PointCloud.h>
#include <pcl/filters/radius_outlier_removal.h>
#include <pcl/filters/voxel_grid.h>
#include <pcl/point_types.h>
#include <pcl/sample_consensus/method_types.h>
#include <pcl/sample_consensus/model_types.h>
#include <pcl/segmentation/sac_segmentation.h>

#include "ds3d_side.hpp"

namespace {

struct Timed {
  double ms = 0;      ///< median wall time
  double cpu_ms = 0;  ///< median CPU time of the calling thread (all three run single-threaded)
  double check = 0;
};

double thread_cpu_ms() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) * 1e3 + static_cast<double>(ts.tv_nsec) * 1e-6;
}

/// Median wall and thread-CPU times of `reps` runs after one warm-up; fn returns the check value.
/// On a loaded machine the CPU time excludes the time the scheduler gave to other processes.
Timed measure(int reps, const std::function<double()>& fn) {
  Timed t;
  t.check = fn();
  std::vector<double> ms;
  std::vector<double> cpu;
  for (int r = 0; r < reps; ++r) {
    const double c0 = thread_cpu_ms();
    const auto t0 = std::chrono::steady_clock::now();
    t.check = fn();
    ms.push_back(
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
    cpu.push_back(thread_cpu_ms() - c0);
  }
  std::sort(ms.begin(), ms.end());
  std::sort(cpu.begin(), cpu.end());
  t.ms = ms[ms.size() / 2];
  t.cpu_ms = cpu[cpu.size() / 2];
  return t;
}

double plane_inliers(const std::vector<float>& xyz, const Eigen::Vector4d& pl, double t) {
  return ds3d_side::plane_inliers(xyz, {pl[0], pl[1], pl[2], pl[3]}, t);
}

}  // namespace

int main(int argc, char** argv) {
  std::vector<std::int64_t> sizes{300'000, 1'000'000};
  int reps = 5;
  int slow_reps = 3;
  std::string ops = "voxel,radius,plane";
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string a = argv[i];
    if (a == "--sizes") {
      sizes.clear();
      std::string s = argv[i + 1];
      for (std::size_t pos = 0; pos < s.size();) {
        const std::size_t end = s.find(',', pos);
        sizes.push_back(std::stoll(s.substr(pos, end - pos)));
        pos = end == std::string::npos ? s.size() : end + 1;
      }
    } else if (a == "--reps") {
      reps = std::stoi(argv[i + 1]);
    } else if (a == "--slow-reps") {
      slow_reps = std::stoi(argv[i + 1]);
    } else if (a == "--ops") {
      ops = argv[i + 1];
    }
  }
  omp_set_num_threads(1);  // single-thread comparison: Open3D's plane and radius use OpenMP

  std::printf(
      "| op | points | ds3d ms | Open3D ms | PCL ms | Open3D / ds3d | PCL / ds3d | CPU ms ds3d / "
      "Open3D / PCL | CPU Open3D / ds3d, PCL / ds3d | check ds3d / Open3D / PCL |\n");
  std::printf("|---|---|---|---|---|---|---|---|---|---|\n");
  for (const std::int64_t size : sizes) {
    const std::vector<float> pts = ds3d_side::room_cloud(size);
    const std::size_t np = pts.size() / 3;
    open3d::geometry::PointCloud o3d;
    o3d.points_.reserve(np);
    pcl::PointCloud<pcl::PointXYZ>::Ptr pc(new pcl::PointCloud<pcl::PointXYZ>);
    pc->reserve(np);
    for (std::size_t i = 0; i < np; ++i) {
      o3d.points_.emplace_back(pts[3 * i], pts[3 * i + 1], pts[3 * i + 2]);
      pc->push_back(pcl::PointXYZ(pts[3 * i], pts[3 * i + 1], pts[3 * i + 2]));
    }
    pc->is_dense = true;
    const long n = static_cast<long>(np);
    auto row = [&](const char* op, const Timed& a, const Timed& b, const Timed& c) {
      std::printf(
          "| %s | %ld | %.1f | %.1f | %.1f | %.1f× | %.1f× | %.1f / %.1f / %.1f | %.1f×, %.1f× | "
          "%.0f / %.0f / %.0f |\n",
          op, n, a.ms, b.ms, c.ms, b.ms / a.ms, c.ms / a.ms, a.cpu_ms, b.cpu_ms, c.cpu_ms,
          b.cpu_ms / a.cpu_ms, c.cpu_ms / a.cpu_ms, a.check, b.check, c.check);
      std::fflush(stdout);
    };

    auto wanted = [&](const char* op) { return ops.find(op) != std::string::npos; };
    for (const double leaf : {0.01, 0.05}) {
      if (!wanted("voxel")) break;
      const Timed a = measure(reps, [&] { return ds3d_side::voxel_count(pts, leaf); });
      const Timed b = measure(
          reps, [&] { return static_cast<double>(o3d.VoxelDownSample(leaf)->points_.size()); });
      const Timed c = measure(reps, [&] {
        pcl::VoxelGrid<pcl::PointXYZ> vg;
        vg.setInputCloud(pc);
        const auto l = static_cast<float>(leaf);
        vg.setLeafSize(l, l, l);
        pcl::PointCloud<pcl::PointXYZ> out;
        vg.filter(out);
        return static_cast<double>(out.size());
      });
      row(leaf == 0.01 ? "voxel 0.01 m" : "voxel 0.05 m", a, b, c);
      // The per-frame use: scratch buffers kept across calls.
      const Timed w = measure(reps, [&] { return ds3d_side::voxel_count_workspace(pts, leaf); });
      row("voxel (ds3d, reused workspace)", w, b, c);
    }
    if (wanted("radius")) {
      const Timed a = measure(slow_reps, [&] { return ds3d_side::radius_kept(pts, false); });
      const Timed b = measure(slow_reps, [&] {
        return static_cast<double>(std::get<1>(o3d.RemoveRadiusOutliers(16, 0.05)).size());
      });
      const Timed c = measure(slow_reps, [&] {
        pcl::RadiusOutlierRemoval<pcl::PointXYZ> ror;
        ror.setInputCloud(pc);
        ror.setRadiusSearch(0.05);
        ror.setMinNeighborsInRadius(16);
        pcl::PointCloud<pcl::PointXYZ> out;
        ror.filter(out);
        return static_cast<double>(out.size());
      });
      row("radius R 0.05 m, k 16", a, b, c);
      const Timed t = measure(slow_reps, [&] { return ds3d_side::radius_kept(pts, true); });
      row("radius (ds3d kKdTree)", t, b, c);
    }
    if (wanted("plane")) {
      const Timed a = measure(
          slow_reps, [&] { return ds3d_side::plane_inliers(pts, ds3d_side::ransac(pts), 0.01); });
      const Timed b = measure(slow_reps, [&] {
        const auto [pl, inl] = o3d.SegmentPlane(0.01, 3, 1000, 1.0);
        return plane_inliers(pts, pl, 0.01);
      });
      const Timed c = measure(slow_reps, [&] {
        pcl::SACSegmentation<pcl::PointXYZ> seg;
        seg.setModelType(pcl::SACMODEL_PLANE);
        seg.setMethodType(pcl::SAC_RANSAC);
        seg.setDistanceThreshold(0.01);
        seg.setMaxIterations(1000);
        seg.setProbability(1.0);
        seg.setInputCloud(pc);
        pcl::ModelCoefficients coef;
        pcl::PointIndices inl;
        seg.segment(inl, coef);
        if (coef.values.size() != 4) return 0.0;
        return plane_inliers(
            pts, Eigen::Vector4d(coef.values[0], coef.values[1], coef.values[2], coef.values[3]),
            0.01);
      });
      row("plane 1000 it, t 0.01", a, b, c);
    }
  }
  return 0;
}
