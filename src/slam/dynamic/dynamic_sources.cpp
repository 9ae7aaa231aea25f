// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// The default HTx weights lookup and make_dynamic_source.
#include "ds3d/slam/dynamic/dynamic_sources.hpp"

#include <sstream>
#include <system_error>
#include <utility>

#include "ds3d/errors.hpp"

namespace ds3d::slam {

std::vector<std::filesystem::path> default_weights_candidates() {
  std::vector<std::filesystem::path> out;
#ifdef DS3D_SOURCE_DIR
  out.push_back(std::filesystem::path(DS3D_SOURCE_DIR) / "models" / kDefaultHtxWeights);
#endif
#ifdef DS3D_INSTALL_DATADIR
  out.push_back(std::filesystem::path(DS3D_INSTALL_DATADIR) / "models" / kDefaultHtxWeights);
#endif
  std::error_code ec;
  const auto exe = std::filesystem::read_symlink("/proc/self/exe", ec);
  if (!ec && !exe.empty()) {
    out.push_back(exe.parent_path().parent_path() / "share" / "ds3d" / "models" /
                  kDefaultHtxWeights);
  }
  return out;
}

std::filesystem::path find_default_weights() {
  const auto candidates = default_weights_candidates();
  std::ostringstream tried;
  for (const auto& p : candidates) {
    std::error_code ec;
    if (std::filesystem::is_regular_file(p, ec)) return p;
    tried << (tried.tellp() > 0 ? ", " : "") << p.string();
  }
  throw IoError(
      detail::concat("ds3d::slam::find_default_weights: no HTx weights file found (tried ",
                     tried.str(), "); pass one with --weights PATH"));
}

namespace {

// In "file:PATH+B" or "mask:DIR+B" the path ends at the first '+' that B follows as a source name
// (geometric, htx, file:, mask:), unless the whole rest of the string names an existing file or
// folder (a path with '+' in it). Returns the position of that '+', or npos: one source.
std::size_t path_source_end(const std::string& spec) {
  if (spec.rfind("file:", 0) != 0 && spec.rfind("mask:", 0) != 0) return std::string::npos;
  std::error_code ec;
  if (std::filesystem::exists(spec.substr(5), ec)) return std::string::npos;
  for (std::size_t plus = spec.find('+', 5); plus != std::string::npos;
       plus = spec.find('+', plus + 1)) {
    const std::string rest = spec.substr(plus + 1);
    for (const char* head : {"geometric", "htx", "file:", "mask:"}) {
      const std::string h(head);
      const bool name = h.back() != ':';
      if (rest.rfind(h, 0) == 0 && (!name || rest.size() == h.size() || rest[h.size()] == '+')) {
        return plus;
      }
    }
  }
  return std::string::npos;
}

}  // namespace

std::shared_ptr<DynamicObjectSource> make_dynamic_source(const std::string& spec,
                                                         const DynamicSourceOptions& options) {
  constexpr const char* kKnown =
      "none, geometric, htx, file:PATH, mask:DIR or A+B (e.g. htx+geometric); gates are a separate "
      "setting (SlamConfig::gate, --gate motion|evidence)";
  if (spec == "none") return std::make_shared<NoDynamicObjects>();
  if (spec == "geometric") return std::make_shared<GeometricMotionSource>(options.geometric);
  if (const std::size_t plus = path_source_end(spec); plus != std::string::npos) {
    return std::make_shared<CompositeSource>(make_dynamic_source(spec.substr(0, plus), options),
                                             make_dynamic_source(spec.substr(plus + 1), options));
  }
  if (spec.rfind("file:", 0) == 0) {
    const std::string path = spec.substr(5);
    DS3D_CHECK(!path.empty(), "ds3d::slam::make_dynamic_source: 'file:' needs a path (got '", spec,
               "')");
    return std::make_shared<FileSource>(path, options.file);
  }
  if (spec.rfind("mask:", 0) == 0) {
    const std::string dir = spec.substr(5);
    DS3D_CHECK(!dir.empty(), "ds3d::slam::make_dynamic_source: 'mask:' needs a folder (got '", spec,
               "')");
    return std::make_shared<MaskSource>(dir, options.file.max_dt);
  }
  if (spec == "htx") {
    const std::filesystem::path weights =
        options.weights.empty() ? find_default_weights() : options.weights;
    std::error_code ec;
    DS3D_CHECK_AS(IoError, std::filesystem::is_regular_file(weights, ec),
                  "ds3d::slam::make_dynamic_source: HTx weights file '", weights.string(),
                  "' does not exist or is not a file");
    auto detector = std::make_shared<const SparseDetector>(SparseDetector::load(weights));
    return std::make_shared<HtxSource>(std::move(detector), options.htx);
  }
  if (const auto plus = spec.find('+'); plus != std::string::npos) {
    const std::string a = spec.substr(0, plus);
    const std::string b = spec.substr(plus + 1);
    // Both names are checked before either source is built (an htx source loads its weights).
    const auto simple = [](const std::string& x) {
      return x == "geometric" || x == "htx" ||
             ((x.rfind("file:", 0) == 0 || x.rfind("mask:", 0) == 0) && x.size() > 5);
    };
    DS3D_CHECK(simple(a) && (simple(b) || b.find('+') != std::string::npos),
               "ds3d::slam::make_dynamic_source: '", spec,
               "' must join two sources other than "
               "none (expected ",
               kKnown, ")");
    return std::make_shared<CompositeSource>(make_dynamic_source(a, options),
                                             make_dynamic_source(b, options));
  }
  throw InvalidArgument(detail::concat("ds3d::slam::make_dynamic_source: unknown source '", spec,
                                       "' (expected ", kKnown, ")"));
}

}  // namespace ds3d::slam
