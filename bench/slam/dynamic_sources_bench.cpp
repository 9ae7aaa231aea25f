// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// HdbscanMasker::mask (include/ds3d/dynamic_sources.hpp) per frame on a generated walking
// sequence (ds3d::synth walking_xyz, 640x480, two walkers, 30 frames): ORB features (1000) are
// extracted beforehand; the objects are the image boxes of the generator's walkers (bounding
// rectangle of each human_id), as a perfect 2-D detector would report them. One iteration masks
// the whole sequence with a fresh masker (its carried regions start empty).
// BM_HdbscanMaskerMaskSegmented: the same frames with segmented 3-D boxes instead (each walker's
// axis-aligned camera-frame box of its pixels, flagged in boxes_3d_segmented) and the walkers'
// pixels back-projected on a 4-pixel grid as DynamicObjects::foreground_points, as a perfect
// part head would report them: the cost of the segmentation check on top of the filter. With
// argument 1 the other pixels with depth on an 8-pixel grid (≈ 4,000 points, about the
// network's ≈ 3,000) come as DynamicObjects::background_points: the nearest-neighbour label
// transfer (a second KD-tree and query per checked keypoint). With argument 2 the same objects
// with DynamicObjects::segment_outside_boxes: every keypoint outside the boxes is checked
// against the segmentation too (two KD-tree queries each, and a depth window for those without
// depth).
#include <benchmark/benchmark.h>

#include <algorithm>
#include <cstdint>
#include <vector>

#include <opencv2/core/utility.hpp>
#include <opencv2/imgproc.hpp>

#include "ds3d/slam/dynamic/dynamic_sources.hpp"
#include "ds3d/slam/orb_features.hpp"
#include "ds3d/slam/synth.hpp"

namespace {

struct Prepared {
  ds3d::slam::FrameInput input;
  ds3d::slam::OrbFeatures features;
  ds3d::slam::DynamicObjects objects;
  ds3d::slam::DynamicObjects segmented;
  ds3d::slam::DynamicObjects segmented_bg;   // segmented + background_points
  ds3d::slam::DynamicObjects segmented_all;  // segmented_bg + segment_outside_boxes
};

// Appends the walker on `m` to `o` as a segmented 3-D box and its foreground points.
void add_segmented(ds3d::slam::DynamicObjects& o, const cv::Mat& m, const cv::Mat& depth,
                   const ds3d::PinholeCamera& cam) {
  std::vector<Eigen::Vector3f> pts;
  for (int y = 0; y < m.rows; y += 4) {
    for (int x = 0; x < m.cols; x += 4) {
      const auto d = depth.at<std::uint16_t>(y, x);
      if (m.at<std::uint8_t>(y, x) == 0U || d == 0U) continue;
      pts.push_back(cam.back_project(x, y, d / cam.depth_scale).cast<float>());
    }
  }
  if (pts.empty()) return;
  Eigen::Vector3f lo = pts[0];
  Eigen::Vector3f hi = pts[0];
  for (const auto& p : pts) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  Eigen::Matrix<float, 8, 3> c;
  for (int i = 0; i < 8; ++i) {
    c.row(i) << ((i & 1) ? hi.x() : lo.x()), ((i & 2) ? hi.y() : lo.y()),
        ((i & 4) ? hi.z() : lo.z());
  }
  o.boxes_3d.push_back(c);
  o.boxes_3d_margin.push_back(0.15F);
  o.segmentation.boxes_3d_segmented.push_back(1);
  const Eigen::Index n = o.segmentation.foreground_points.rows();
  o.segmentation.foreground_points.conservativeResize(n + static_cast<Eigen::Index>(pts.size()), 3);
  for (std::size_t k = 0; k < pts.size(); ++k) {
    o.segmentation.foreground_points.row(n + static_cast<Eigen::Index>(k)) = pts[k].transpose();
  }
}

const std::vector<Prepared>& prepared() {
  static const std::vector<Prepared> p = [] {
    cv::setNumThreads(1);
    ds3d::synth::SynthOptions o;
    o.scenario = ds3d::synth::Scenario::kWalkingXyz;
    o.num_frames = 30;
    const ds3d::synth::SyntheticScene scene(o);
    const ds3d::slam::OrbExtractor ex;
    std::vector<Prepared> out;
    for (std::size_t i = 0; i < scene.size(); ++i) {
      const auto f = scene.render(i);
      Prepared q;
      q.input.index = i;
      q.input.timestamp = f.timestamp;
      q.input.rgb = f.rgb;
      q.input.depth = f.depth;
      q.features = ex.extract(f.rgb, f.depth, o.camera);
      for (int id = 1; id <= 4; ++id) {
        cv::Mat m = f.human_id == id;
        if (cv::countNonZero(m) == 0) continue;
        q.objects.boxes_2d.push_back(cv::Rect2f(cv::boundingRect(m)));
        q.objects.scores.push_back(0.9F);
        add_segmented(q.segmented, m, f.depth, o.camera);
      }
      q.segmented_bg = q.segmented;
      std::vector<Eigen::Vector3f> bg;
      for (int y = 0; y < f.depth.rows; y += 8) {
        for (int x = 0; x < f.depth.cols; x += 8) {
          const auto d = f.depth.at<std::uint16_t>(y, x);
          if (f.human_id.at<std::uint8_t>(y, x) != 0U || d == 0U) continue;
          bg.push_back(o.camera.back_project(x, y, d / o.camera.depth_scale).cast<float>());
        }
      }
      q.segmented_bg.segmentation.background_points.resize(static_cast<Eigen::Index>(bg.size()), 3);
      for (std::size_t k = 0; k < bg.size(); ++k) {
        q.segmented_bg.segmentation.background_points.row(static_cast<Eigen::Index>(k)) =
            bg[k].transpose();
      }
      q.segmented_all = q.segmented_bg;
      q.segmented_all.segmentation.segment_outside_boxes = true;
      out.push_back(std::move(q));
    }
    return out;
  }();
  return p;
}

void BM_HdbscanMaskerMask(benchmark::State& state) {
  const ds3d::PinholeCamera cam = ds3d::synth::SynthOptions{}.camera;
  const auto& frames = prepared();
  std::int64_t dynamic = 0;
  for (auto _ : state) {
    ds3d::slam::HdbscanMasker masker;
    dynamic = 0;
    for (const auto& f : frames) {
      const auto m = masker.mask(f.input, cam, f.features, f.objects);
      dynamic += masker.last_result().num_dynamic;
      benchmark::DoNotOptimize(m.data());
    }
  }
  const auto n = static_cast<std::int64_t>(frames.size());
  state.counters["dynamic_kp_per_frame"] = static_cast<double>(dynamic) / static_cast<double>(n);
  state.SetItemsProcessed(state.iterations() * n);
}
BENCHMARK(BM_HdbscanMaskerMask)->Unit(benchmark::kMillisecond);

void BM_HdbscanMaskerMaskSegmented(benchmark::State& state) {
  const ds3d::PinholeCamera cam = ds3d::synth::SynthOptions{}.camera;
  const auto& frames = prepared();
  std::int64_t dynamic = 0;
  std::int64_t vetoed = 0;
  std::int64_t fg = 0;
  for (auto _ : state) {
    ds3d::slam::HdbscanMasker masker;
    dynamic = 0;
    vetoed = 0;
    fg = 0;
    for (const auto& f : frames) {
      const auto& objects = state.range(0) == 2   ? f.segmented_all
                            : state.range(0) == 1 ? f.segmented_bg
                                                  : f.segmented;
      const auto m = masker.mask(f.input, cam, f.features, objects);
      dynamic += std::count(m.begin(), m.end(), std::uint8_t{1});
      vetoed += static_cast<std::int64_t>(masker.last_vetoed());
      fg += f.segmented.segmentation.foreground_points.rows();
      benchmark::DoNotOptimize(m.data());
    }
  }
  const auto n = static_cast<double>(frames.size());
  state.counters["dynamic_kp_per_frame"] = static_cast<double>(dynamic) / n;
  state.counters["vetoed_kp_per_frame"] = static_cast<double>(vetoed) / n;
  state.counters["foreground_points_per_frame"] = static_cast<double>(fg) / n;
  state.SetItemsProcessed(state.iterations() * static_cast<std::int64_t>(frames.size()));
}
BENCHMARK(BM_HdbscanMaskerMaskSegmented)->Arg(0)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond);

// image_boxes() of four 3-D boxes (projection of 8 corners each): the per-frame glue cost.
void BM_ImageBoxes3d(benchmark::State& state) {
  const ds3d::PinholeCamera cam = ds3d::synth::SynthOptions{}.camera;
  ds3d::slam::DynamicObjects o;
  for (int k = 0; k < 4; ++k) {
    Eigen::Matrix<float, 8, 3> c;
    for (int i = 0; i < 8; ++i) {
      c.row(i) << -0.3F + 0.4F * static_cast<float>(k) + ((i & 1) ? 0.5F : 0.0F),
          (i & 2) ? 0.8F : -0.9F, 2.0F + static_cast<float>(k) * 0.5F + ((i & 4) ? 0.4F : 0.0F);
    }
    o.boxes_3d.push_back(c);
  }
  for (auto _ : state) benchmark::DoNotOptimize(ds3d::slam::image_boxes(o, cam));
  state.SetItemsProcessed(state.iterations() * 4);
}
BENCHMARK(BM_ImageBoxes3d);

}  // namespace
