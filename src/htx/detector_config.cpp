// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// DetectorConfig: the exporter's JSON metadata, its checks and the built-in profiles.
#include "ds3d/htx/sparse_detector.hpp"

#include <cmath>
#include <string>
#include <vector>

#include "ds3d/detail/json.hpp"
#include "ds3d/errors.hpp"

namespace ds3d {

namespace {

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

}  // namespace ds3d
