// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// run_pipeline: the stages of SlamFrontend in threads connected by bounded queues.
#include <algorithm>
#include <condition_variable>
#include <deque>
#include <exception>
#include <mutex>
#include <optional>
#include <thread>
#include <utility>

#include "ds3d/errors.hpp"
#include "ds3d/slam/slam_frontend.hpp"

namespace ds3d::slam {
namespace {

// Bounded FIFO; close() wakes everybody, pop() then drains what is left and returns nullopt.
template <class T>
class BoundedQueue {
 public:
  explicit BoundedQueue(std::size_t capacity) : capacity_(capacity) {}
  bool push(T v) {
    std::unique_lock<std::mutex> lock(m_);
    not_full_.wait(lock, [&] { return closed_ || q_.size() < capacity_; });
    if (closed_) return false;
    q_.push_back(std::move(v));
    not_empty_.notify_one();
    return true;
  }
  std::optional<T> pop() {
    std::unique_lock<std::mutex> lock(m_);
    not_empty_.wait(lock, [&] { return closed_ || !q_.empty(); });
    if (q_.empty()) return std::nullopt;
    T v = std::move(q_.front());
    q_.pop_front();
    not_full_.notify_one();
    return v;
  }
  void close() {
    const std::lock_guard<std::mutex> lock(m_);
    closed_ = true;
    not_empty_.notify_all();
    not_full_.notify_all();
  }

 private:
  std::size_t capacity_;
  std::deque<T> q_;
  bool closed_ = false;
  std::mutex m_;
  std::condition_variable not_empty_;
  std::condition_variable not_full_;
};

// First exception of any stage; the others stop at their next queue operation.
class ErrorSlot {
 public:
  void set(std::exception_ptr e) {
    const std::lock_guard<std::mutex> lock(m_);
    if (!e_) e_ = std::move(e);
  }
  void rethrow() {
    if (e_) std::rethrow_exception(e_);
  }

 private:
  std::mutex m_;
  std::exception_ptr e_;
};

// Joins what the extract stage made of a frame (its input, features, spare features and
// extraction times) into the frame that went through prepare (and maybe detect).
void take_extraction(PreparedFrame& into, PreparedFrame from) {
  into.input = std::move(from.input);
  into.features = std::move(from.features);
  into.spare = std::move(from.spare);
  into.times.extract_ms = from.times.extract_ms;
  into.times.extract_cpu_ms = from.times.extract_cpu_ms;
}

}  // namespace

std::vector<TrackResult> run_pipeline(SlamFrontend& slam,
                                      const std::function<std::optional<FrameInput>()>& next,
                                      const std::function<void(const TrackResult&)>& on_result,
                                      const PipelineOptions& options) {
  options.validate();
  std::vector<TrackResult> results;
  if (!options.threaded) {
    while (auto in = next()) {
      PreparedFrame pf = slam.extract(std::move(*in));
      slam.detect_dynamic(pf);
      slam.filter_dynamic(pf);
      results.push_back(slam.track_prepared(std::move(pf)));
      if (on_result) on_result(results.back());
    }
    slam.finish();
    return results;
  }

  const auto cap = static_cast<std::size_t>(options.queue_capacity);
  // reader → {extract, prepare → detect} → filter → track (caller's thread). prepare runs the
  // frame-independent part of the source (DynamicObjectSource::prepare) ahead of detect. A
  // source that reads the frame's ORB corners (uses_orb_corners) detects after extraction
  // instead: reader → {extract, prepare} → detect → filter → track.
  const bool corners_first = slam.dynamic_source().uses_orb_corners();
  BoundedQueue<FrameInput> to_extract(cap);
  BoundedQueue<FrameInput> to_prepare(cap);
  BoundedQueue<PreparedFrame> prepared(cap);
  BoundedQueue<PreparedFrame> extracted(cap);
  BoundedQueue<PreparedFrame> detected(cap);
  BoundedQueue<PreparedFrame> filtered(cap);
  ErrorSlot error;
  auto close_all = [&] {
    to_extract.close();
    to_prepare.close();
    prepared.close();
    extracted.close();
    detected.close();
    filtered.close();
  };
  auto guarded = [&](auto&& body) {
    return [&, body]() mutable {
      try {
        body();
      } catch (...) {
        error.set(std::current_exception());
        close_all();
      }
    };
  };
  std::thread reader(guarded([&] {
    while (auto in = next()) {
      if (!to_prepare.push(*in) || !to_extract.push(std::move(*in))) return;
    }
    to_extract.close();
    to_prepare.close();
  }));
  std::thread extractor(guarded([&] {
    while (auto in = to_extract.pop()) {
      if (!extracted.push(slam.extract(std::move(*in)))) return;
    }
    extracted.close();
  }));
  std::thread preparer(guarded([&] {
    while (auto in = to_prepare.pop()) {
      PreparedFrame tmp;
      tmp.input = std::move(*in);
      slam.prepare_dynamic(tmp);
      if (!prepared.push(std::move(tmp))) return;
    }
    prepared.close();
  }));
  std::thread detector(guarded([&] {
    while (auto pf = prepared.pop()) {
      if (corners_first) {
        auto ex = extracted.pop();
        if (!ex) return;
        take_extraction(*pf, std::move(*ex));
      }
      slam.detect_dynamic(*pf);
      if (!detected.push(std::move(*pf))) return;
    }
    detected.close();
  }));
  // The next frame with its extraction and its objects (nothing at the end).
  const auto next_detected = [&]() -> std::optional<PreparedFrame> {
    if (corners_first) return detected.pop();
    auto ex = extracted.pop();
    if (!ex) return std::nullopt;
    auto pf = detected.pop();
    if (pf) take_extraction(*pf, std::move(*ex));
    return pf;
  };
  std::thread filter(guarded([&] {
    while (auto pf = next_detected()) {
      slam.filter_dynamic(*pf);
      if (!filtered.push(std::move(*pf))) return;
    }
    filtered.close();
  }));
  try {
    while (auto pf = filtered.pop()) {
      results.push_back(slam.track_prepared(std::move(*pf)));
      if (on_result) on_result(results.back());
    }
  } catch (...) {
    error.set(std::current_exception());
    close_all();
  }
  reader.join();
  extractor.join();
  preparer.join();
  detector.join();
  filter.join();
  error.rethrow();
  slam.finish();
  return results;
}

std::vector<TrackResult> run_dataset(SlamFrontend& slam, const RgbdDataset& dataset,
                                     std::size_t max_frames,
                                     const std::function<void(const TrackResult&)>& on_result,
                                     const PipelineOptions& options) {
  const std::size_t n = max_frames == 0 ? dataset.size() : std::min(max_frames, dataset.size());
  std::size_t i = 0;
  const auto next = [&]() -> std::optional<FrameInput> {
    if (i >= n) return std::nullopt;
    return to_frame_input(dataset.frame(i++));
  };
  return run_pipeline(slam, next, on_result, options);
}

}  // namespace ds3d::slam
