// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// Rendering one frame: z-buffer rasteriser, colour with grain, Kinect-like depth.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <vector>

#include <opencv2/core.hpp>

#include "synth_impl.hpp"

namespace ds3d::synth {

void SyntheticScene::Impl::draw_triangle(const CVert* v, const cv::Mat& tex, float shade,
                                         std::uint8_t human, std::uint8_t part, Buffers& b) const {
  const auto& c = opt.camera;
  const auto fx = static_cast<float>(c.fx);
  const auto fy = static_cast<float>(c.fy);
  const auto cx = static_cast<float>(c.cx);
  const auto cy = static_cast<float>(c.cy);
  float sx[3], sy[3], iz[3], uz[3], vz[3];
  for (int k = 0; k < 3; ++k) {
    iz[k] = 1.0F / v[k].p.z();
    sx[k] = fx * v[k].p.x() * iz[k] + cx;
    sy[k] = fy * v[k].p.y() * iz[k] + cy;
    uz[k] = v[k].uv.x() * iz[k];
    vz[k] = v[k].uv.y() * iz[k];
  }
  const float area = (sx[1] - sx[0]) * (sy[2] - sy[0]) - (sx[2] - sx[0]) * (sy[1] - sy[0]);
  if (!(std::abs(area) > 1e-9F)) return;
  const int x0 = std::max(0, static_cast<int>(std::ceil(std::min({sx[0], sx[1], sx[2]}))));
  const int x1 =
      std::min(c.width - 1, static_cast<int>(std::floor(std::max({sx[0], sx[1], sx[2]}))));
  const int y0 = std::max(0, static_cast<int>(std::ceil(std::min({sy[0], sy[1], sy[2]}))));
  const int y1 =
      std::min(c.height - 1, static_cast<int>(std::floor(std::max({sy[0], sy[1], sy[2]}))));
  if (x0 > x1 || y0 > y1) return;
  const float inv_area = 1.0F / area;
  // Edge functions w_k(x, y) = A_k x + B_k y + C_k, normalised so that w0 + w1 + w2 = 1.
  float ea[3], eb[3], ec[3];
  for (int k = 0; k < 3; ++k) {
    const int i = (k + 1) % 3;
    const int j = (k + 2) % 3;
    ea[k] = (sy[i] - sy[j]) * inv_area;
    eb[k] = (sx[j] - sx[i]) * inv_area;
    ec[k] = (sx[i] * sy[j] - sx[j] * sy[i]) * inv_area;
  }
  const std::uint8_t s8 = static_cast<std::uint8_t>(std::clamp(shade * 256.0F, 0.0F, 255.0F));
  for (int y = y0; y <= y1; ++y) {
    auto* zrow = b.zbuf.ptr<float>(y);
    auto* crow = b.color.ptr<cv::Vec3b>(y);
    auto* hrow = b.human.ptr<std::uint8_t>(y);
    auto* prow = b.part.ptr<std::uint8_t>(y);
    const auto fyv = static_cast<float>(y);
    // Solve w_k(x) >= 0 for the span of this row instead of testing every pixel of the box.
    float lo = static_cast<float>(x0);
    float hi = static_cast<float>(x1);
    for (int k = 0; k < 3; ++k) {
      const float c0 = eb[k] * fyv + ec[k];
      if (ea[k] > 0) {
        lo = std::max(lo, -c0 / ea[k]);
      } else if (ea[k] < 0) {
        hi = std::min(hi, -c0 / ea[k]);
      } else if (c0 < 0) {
        hi = -1;
      }
    }
    if (!(lo <= hi)) continue;
    const int xa = std::max(x0, static_cast<int>(std::ceil(lo)));
    const int xb = std::min(x1, static_cast<int>(std::floor(hi)));
    for (int x = xa; x <= xb; ++x) {
      const auto fxv = static_cast<float>(x);
      const float w0 = ea[0] * fxv + eb[0] * fyv + ec[0];
      const float w1 = ea[1] * fxv + eb[1] * fyv + ec[1];
      const float w2 = 1.0F - w0 - w1;
      const float invz = w0 * iz[0] + w1 * iz[1] + w2 * iz[2];
      const float z = 1.0F / invz;
      if (!(z < zrow[x]) || z < kNear) continue;
      zrow[x] = z;
      const float u = (w0 * uz[0] + w1 * uz[1] + w2 * uz[2]) * z;
      const float vv = (w0 * vz[0] + w1 * vz[1] + w2 * vz[2]) * z;
      const int tu = static_cast<int>(std::floor(u)) & (kTex - 1);
      const int tv = static_cast<int>(std::floor(vv)) & (kTex - 1);
      const cv::Vec3b t = tex.at<cv::Vec3b>(tv, tu);
      crow[x] = cv::Vec3b(static_cast<std::uint8_t>((t[0] * s8) >> 8U),
                          static_cast<std::uint8_t>((t[1] * s8) >> 8U),
                          static_cast<std::uint8_t>((t[2] * s8) >> 8U));
      hrow[x] = human;
      prow[x] = part;
    }
  }
}

void SyntheticScene::Impl::draw_mesh(const Mesh& m, const Eigen::Isometry3f& T_cam_world,
                                     Buffers& b) const {
  std::vector<Eigen::Vector3f> pc(m.pos.size());
  for (std::size_t i = 0; i < m.pos.size(); ++i) pc[i] = T_cam_world * m.pos[i];
  const cv::Mat& tex = textures[static_cast<std::size_t>(m.material)];
  for (const auto& t : m.tris) {
    const Eigen::Vector3f& a = m.pos[t[0]];
    Eigen::Vector3f nrm = (m.pos[t[1]] - a).cross(m.pos[t[2]] - a);
    const float nn = nrm.norm();
    if (!(nn > 1e-12F)) continue;
    nrm /= nn;
    // Two-sided Lambert with ambient light.
    const float shade = 0.55F + 0.4F * std::abs(nrm.dot(light.cast<float>()));
    CVert in[3];
    int n_in = 0;
    for (int k = 0; k < 3; ++k) {
      in[k] = {pc[t[static_cast<std::size_t>(k)]], m.uv[t[static_cast<std::size_t>(k)]]};
      if (in[k].p.z() >= kNear) ++n_in;
    }
    if (n_in == 0) continue;
    if (n_in == 3) {
      draw_triangle(in, tex, shade, m.human, m.part, b);
      continue;
    }
    // Clip against z = near (Sutherland-Hodgman), then fan-triangulate.
    CVert poly[4];
    int np = 0;
    for (int k = 0; k < 3; ++k) {
      const CVert& p = in[k];
      const CVert& q = in[(k + 1) % 3];
      const bool pin = p.p.z() >= kNear;
      const bool qin = q.p.z() >= kNear;
      if (pin) poly[np++] = p;
      if (pin != qin) {
        const float s = (kNear - p.p.z()) / (q.p.z() - p.p.z());
        poly[np++] = {p.p + s * (q.p - p.p), p.uv + s * (q.uv - p.uv)};
      }
    }
    for (int k = 1; k + 1 < np; ++k) {
      const CVert tri[3] = {poly[0], poly[k], poly[k + 1]};
      draw_triangle(tri, tex, shade, m.human, m.part, b);
    }
  }
}

SynthFrame SyntheticScene::Impl::render(std::size_t i) const {
  const auto& cam = opt.camera;
  SynthFrame f;
  f.index = i;
  f.timestamp = opt.start_time + static_cast<double>(i) / opt.fps;
  const double t = static_cast<double>(i) / opt.fps;
  f.T_world_cam = camera_pose(f.timestamp);
  const Eigen::Isometry3f T_cw = f.T_world_cam.inverse().cast<float>();
  Buffers b;
  b.zbuf =
      cv::Mat(cam.height, cam.width, CV_32F, cv::Scalar(std::numeric_limits<float>::infinity()));
  b.color = cv::Mat(cam.height, cam.width, CV_8UC3, cv::Scalar(0, 0, 0));
  b.human = cv::Mat::zeros(cam.height, cam.width, CV_8U);
  b.part = cv::Mat::zeros(cam.height, cam.width, CV_8U);
  // Humans first: they are near, so the z-test rejects most room pixels behind them early.
  std::vector<Mesh> hm;
  for (std::size_t k = 0; k < humans.size(); ++k) human_meshes(k, t, hm);
  for (const Mesh& m : hm) draw_mesh(m, T_cw, b);
  for (const Mesh& m : static_meshes) draw_mesh(m, T_cw, b);
  for (std::size_t k = 0; k < humans.size(); ++k) f.boxes.push_back(box_of(k, t, hm));

  f.rgb = b.color;
  f.human_id = b.human;
  f.part_id = b.part;
  cv::compare(b.human, 0, f.dynamic_mask, cv::CMP_GT);
  f.depth_true = cv::Mat::zeros(cam.height, cam.width, CV_32F);
  f.depth = cv::Mat::zeros(cam.height, cam.width, CV_16U);
  const std::uint64_t frame_seed = mix(noise_seed ^ mix(i));
  const double baseline_fx = 0.075 * cam.fx;  // Kinect: 7.5 cm baseline
  for (int y = 0; y < cam.height; ++y) {
    const float* z = b.zbuf.ptr<float>(y);
    float* zt = f.depth_true.ptr<float>(y);
    std::uint16_t* d = f.depth.ptr<std::uint16_t>(y);
    const std::uint8_t* hrow = b.human.ptr<std::uint8_t>(y);
    cv::Vec3b* crow = f.rgb.ptr<cv::Vec3b>(y);
    for (int x = 0; x < cam.width; ++x) {
      if (!std::isfinite(z[x])) continue;
      zt[x] = z[x];
      if (hrow[x] > 0) ++f.boxes[hrow[x] - 1U].visible_pixels;
      const std::uint64_t h =
          mix(frame_seed + static_cast<std::uint64_t>(y) * 65536U + static_cast<std::uint64_t>(x));
      // Sensor grain on the colour image (+-3 levels).
      const int grain = static_cast<int>(h & 7U) - 3;
      for (int ch = 0; ch < 3; ++ch) {
        crow[x][ch] = cv::saturate_cast<std::uint8_t>(crow[x][ch] + grain);
      }
      double zz = z[x];
      if (opt.depth_noise) {
        if (zz > 4.5) continue;  // beyond the sensor's range: no depth
        // Hole at a depth discontinuity (the projector/camera shadow), most of the time.
        float jump = 0;
        if (x > 0 && std::isfinite(z[x - 1])) jump = std::max(jump, std::abs(z[x - 1] - z[x]));
        if (x + 1 < cam.width && std::isfinite(z[x + 1]))
          jump = std::max(jump, std::abs(z[x + 1] - z[x]));
        if (y > 0) {
          const float zu = b.zbuf.ptr<float>(y - 1)[x];
          if (std::isfinite(zu)) jump = std::max(jump, std::abs(zu - z[x]));
        }
        if (jump > 0.04F * z[x] && ((h >> 3U) & 0xFFU) < 205U) continue;  // 80 %
        // Gaussian noise, sigma = 1.425e-3 z^2: sum of four 12-bit uniforms (Irwin-Hall,
        // variance 4/12, rescaled), one hash per pixel instead of log/cos.
        const double sum4 = static_cast<double>(((h >> 12U) & 0xFFFU) + ((h >> 24U) & 0xFFFU) +
                                                ((h >> 36U) & 0xFFFU) + ((h >> 48U) & 0xFFFU)) /
                            4096.0;
        const double gauss = (sum4 - 2.0) * 1.7320508075688772;
        zz += 1.425e-3 * zz * zz * gauss;
        // Disparity quantised to 1/8 pixel.
        const double disp = std::round(baseline_fx / zz * 8.0) / 8.0;
        if (disp <= 0) continue;
        zz = baseline_fx / disp;
      }
      const double units = std::round(zz * cam.depth_scale);
      if (units >= 1 && units <= 65535) d[x] = static_cast<std::uint16_t>(units);
    }
  }
  if (crowd()) motion_blur(f);
  return f;
}

}  // namespace ds3d::synth
