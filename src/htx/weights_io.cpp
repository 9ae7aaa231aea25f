// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
#include "ds3d/htx/weights_io.hpp"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <fstream>
#include <limits>
#include <sstream>
#include <utility>

#include "ds3d/detail/json.hpp"
#include "ds3d/detail/sha256.hpp"
#include "ds3d/errors.hpp"

namespace ds3d {
namespace {

static_assert(std::endian::native == std::endian::little,
              "weights_io assumes a little-endian host (the file format is little-endian)");

constexpr std::uint64_t kMaxHeader = 100ULL * 1024ULL * 1024ULL;

struct DTypeInfo {
  const char* name;
  DType type;
  std::size_t size;
};
constexpr DTypeInfo kDTypes[] = {{"F32", DType::kF32, 4},   {"F16", DType::kF16, 2},
                                 {"BF16", DType::kBF16, 2}, {"F64", DType::kF64, 8},
                                 {"I64", DType::kI64, 8},   {"I32", DType::kI32, 4},
                                 {"I16", DType::kI16, 2},   {"I8", DType::kI8, 1},
                                 {"U8", DType::kU8, 1},     {"BOOL", DType::kBool, 1}};

std::size_t dtype_size(DType t) {
  for (const auto& d : kDTypes) {
    if (d.type == t) return d.size;
  }
  return 0;
}
const char* dtype_name(DType t) {
  for (const auto& d : kDTypes) {
    if (d.type == t) return d.name;
  }
  return "?";
}

[[noreturn]] void fail(const std::string& source, const std::string& what) {
  throw IoError("ds3d::WeightsFile: " + source + ": " + what);
}

}  // namespace

std::string shape_string(const std::vector<std::int64_t>& shape) {
  std::ostringstream os;
  os << '[';
  for (std::size_t i = 0; i < shape.size(); ++i) os << (i ? ", " : "") << shape[i];
  os << ']';
  return os.str();
}

std::int64_t TensorView::numel() const {
  std::int64_t n = 1;
  for (const auto s : shape) n *= s;
  return n;
}

WeightsFile WeightsFile::read(const std::filesystem::path& path) {
  const std::string src = path.string();
  std::error_code ec;
  const auto st = std::filesystem::status(path, ec);
  if (ec || !std::filesystem::exists(st)) fail(src, "cannot open file");
  // A device or pipe (/dev/urandom, a FIFO) would be read without end.
  if (!std::filesystem::is_regular_file(st)) fail(src, "not a regular file");
  const std::uintmax_t size = std::filesystem::file_size(path, ec);
  std::ifstream in(path, std::ios::binary);
  if (ec || !in) fail(src, "cannot open file");
  // The header length first, so that a corrupt one is refused before the file is loaded.
  std::uint64_t n = 0;
  if (size >= 8 && in.read(reinterpret_cast<char*>(&n), 8) && n > kMaxHeader) {
    fail(src, detail::concat("header length ", n, " exceeds the 100 MB limit"));
  }
  in.clear();
  in.seekg(0);
  std::string bytes(static_cast<std::size_t>(size), '\0');
  in.read(bytes.data(), static_cast<std::streamsize>(size));
  if (in.bad() || static_cast<std::uintmax_t>(in.gcount()) != size) fail(src, "read error");
  return parse(std::move(bytes), src);
}

WeightsFile WeightsFile::parse(std::string bytes, std::string source) {
  WeightsFile w;
  w.source_ = std::move(source);
  w.bytes_ = std::move(bytes);
  const std::string& src = w.source_;
  const std::size_t file_size = w.bytes_.size();
  if (file_size < 8)
    fail(src,
         detail::concat("file has ", file_size, " bytes, fewer than the 8-byte header length"));
  std::uint64_t n = 0;
  std::memcpy(&n, w.bytes_.data(), 8);
  if (n > kMaxHeader) fail(src, detail::concat("header length ", n, " exceeds the 100 MB limit"));
  if (n > file_size - 8) {
    fail(src, detail::concat("header length ", n, " exceeds the file size ", file_size, " - 8"));
  }
  w.data_start_ = 8 + static_cast<std::size_t>(n);
  const std::size_t data_size = file_size - w.data_start_;
  const std::string_view header(w.bytes_.data() + 8, static_cast<std::size_t>(n));
  detail::JsonValue root;
  try {
    root = detail::parse_json(header);
  } catch (const IoError& e) {
    fail(src, std::string("invalid JSON header: ") + e.what());
  }
  if (!root.is_object()) fail(src, "JSON header is not an object");

  std::vector<std::pair<std::size_t, std::string>> by_begin;
  for (const auto& [name, entry] : root.as_object()) {
    if (name == "__metadata__") {
      if (!entry.is_object()) fail(src, "__metadata__ is not an object");
      for (const auto& [k, v] : entry.as_object()) {
        if (!v.is_string()) fail(src, "__metadata__ value of '" + k + "' is not a string");
        w.metadata_.emplace(k, v.as_string());
      }
      continue;
    }
    const std::string where = "tensor '" + name + "': ";
    if (!entry.is_object()) fail(src, where + "entry is not an object");
    for (const auto& [k, v] : entry.as_object()) {
      (void)v;
      if (k != "dtype" && k != "shape" && k != "data_offsets")
        fail(src, where + "unknown key '" + k + "'");
    }
    if (!entry.contains("dtype") || !entry.contains("shape") || !entry.contains("data_offsets")) {
      fail(src, where + "needs dtype, shape and data_offsets");
    }
    TensorView t;
    const auto& dt = entry.at("dtype");
    if (!dt.is_string()) fail(src, where + "dtype is not a string");
    bool known = false;
    for (const auto& d : kDTypes) {
      if (dt.as_string() == d.name) {
        t.dtype = d.type;
        known = true;
      }
    }
    if (!known) fail(src, where + "unknown dtype '" + dt.as_string() + "'");
    const auto& sh = entry.at("shape");
    if (!sh.is_array()) fail(src, where + "shape is not an array");
    // Element count with overflow checks: every dimension and the product stay below 2^62.
    constexpr std::int64_t kLimit = std::int64_t{1} << 62;
    std::int64_t numel = 1;
    for (const auto& dim : sh.as_array()) {
      if (!dim.is_number()) fail(src, where + "shape has a non-number");
      const double d = dim.as_number();
      if (!(d >= 0.0) || d != std::floor(d) || d >= static_cast<double>(kLimit)) {
        fail(src, where + detail::concat("shape dimension ", d, " is not a non-negative integer"));
      }
      const auto di = static_cast<std::int64_t>(d);
      if (di != 0 && numel > kLimit / di) fail(src, where + "shape product overflows");
      numel *= di;
      t.shape.push_back(di);
    }
    const auto& off = entry.at("data_offsets");
    if (!off.is_array() || off.size() != 2 || !off.at(0).is_number() || !off.at(1).is_number()) {
      fail(src, where + "data_offsets must be an array of two integers");
    }
    const double b = off.at(0).as_number();
    const double e = off.at(1).as_number();
    for (const double v : {b, e}) {
      if (!(v >= 0.0) || v != std::floor(v) || v > static_cast<double>(data_size)) {
        fail(src,
             where + detail::concat("data_offsets [", b, ", ", e,
                                    "] out of range of the data buffer (", data_size, " bytes)"));
      }
    }
    if (e < b) fail(src, where + detail::concat("data_offsets end ", e, " < begin ", b));
    t.begin = static_cast<std::size_t>(b);
    t.end = static_cast<std::size_t>(e);
    const std::size_t es = dtype_size(t.dtype);
    if (static_cast<std::uint64_t>(numel) > std::numeric_limits<std::uint64_t>::max() / es ||
        static_cast<std::uint64_t>(numel) * es != t.end - t.begin) {
      fail(src, where + detail::concat("shape ", shape_string(t.shape), " x ", dtype_name(t.dtype),
                                       " (", es, " bytes) does not match the ", t.end - t.begin,
                                       " bytes of data_offsets"));
    }
    by_begin.emplace_back(t.begin, name);
    w.tensors_.emplace(name, std::move(t));
  }
  // Non-overlapping and no holes: sorted by (begin, end), each tensor starts where the last ended.
  std::sort(by_begin.begin(), by_begin.end(), [&](const auto& x, const auto& y) {
    const auto& tx = w.tensors_.find(x.second)->second;
    const auto& ty = w.tensors_.find(y.second)->second;
    return std::tie(tx.begin, tx.end, x.second) < std::tie(ty.begin, ty.end, y.second);
  });
  std::size_t cursor = 0;
  std::string prev;
  for (const auto& [begin, name] : by_begin) {
    const auto& t = w.tensors_.find(name)->second;
    if (begin < cursor) {
      fail(src, "tensor '" + name + "': data_offsets overlap those of tensor '" + prev + "'");
    }
    if (begin > cursor) {
      fail(src, "tensor '" + name +
                    detail::concat("': hole in the data buffer before it (bytes ", cursor, "..",
                                   begin, ")"));
    }
    cursor = t.end;
    prev = name;
  }
  if (cursor != data_size) {
    fail(src, detail::concat("data buffer has ", data_size, " bytes but tensors cover ", cursor));
  }
  w.verify_checksum();
  return w;
}

void WeightsFile::verify_checksum() {
  const auto it = metadata_.find(kChecksumKey);
  if (it == metadata_.end()) return;
  const std::string actual =
      detail::sha256_hex(std::string_view(bytes_).substr(data_start_, bytes_.size() - data_start_));
  if (it->second != actual) {
    fail(source_, detail::concat("__metadata__ ", kChecksumKey, " is '", it->second,
                                 "' but the tensor bytes hash to '", actual,
                                 "': the file is corrupted or was edited after export"));
  }
  has_checksum_ = true;
}

std::vector<std::string> WeightsFile::names() const {
  std::vector<std::string> out;
  out.reserve(tensors_.size());
  for (const auto& kv : tensors_) out.push_back(kv.first);
  return out;
}

bool WeightsFile::contains(std::string_view name) const {
  return tensors_.find(name) != tensors_.end();
}

const TensorView& WeightsFile::tensor(std::string_view name) const {
  const auto it = tensors_.find(name);
  if (it == tensors_.end()) fail(source_, "missing tensor '" + std::string(name) + "'");
  return it->second;
}

std::vector<float> WeightsFile::f32(std::string_view name,
                                    const std::vector<std::int64_t>& expected_shape) const {
  const TensorView& t = tensor(name);
  const std::string where = "tensor '" + std::string(name) + "': ";
  if (t.dtype != DType::kF32)
    fail(source_, where + "dtype " + dtype_name(t.dtype) + ", expected F32");
  if (t.shape != expected_shape) {
    fail(source_,
         where + "shape " + shape_string(t.shape) + ", expected " + shape_string(expected_shape));
  }
  std::vector<float> out(static_cast<std::size_t>(t.numel()));
  if (!out.empty()) std::memcpy(out.data(), bytes_.data() + data_start_ + t.begin, t.end - t.begin);
  for (std::size_t i = 0; i < out.size(); ++i) {
    if (!std::isfinite(out[i]))
      fail(source_, where + detail::concat("element ", i, " is not finite"));
    if (!(std::abs(out[i]) <= kMaxAbsValue)) {
      fail(source_, where + detail::concat("element ", i, " = ", out[i],
                                           " is beyond the supported range |w| <= ", kMaxAbsValue,
                                           " (a corrupted value?)"));
    }
  }
  return out;
}

const std::string& WeightsFile::metadata(std::string_view key) const {
  const auto it = metadata_.find(key);
  if (it == metadata_.end()) fail(source_, "__metadata__ has no key '" + std::string(key) + "'");
  return it->second;
}

std::string serialize_safetensors(const std::vector<NamedTensor>& tensors,
                                  std::map<std::string, std::string> metadata) {
  std::string data;
  for (const auto& t : tensors) {
    data.append(reinterpret_cast<const char*>(t.data.data()), t.data.size() * sizeof(float));
  }
  metadata.emplace(WeightsFile::kChecksumKey, detail::sha256_hex(data));
  std::string header = "{";
  bool first = true;
  {
    header += "\"__metadata__\":{";
    for (const auto& [k, v] : metadata) {
      if (!first) header += ',';
      header += '"';
      header += detail::json_escape(k);
      header += "\":\"";
      header += detail::json_escape(v);
      header += '"';
      first = false;
    }
    header += "}";
  }
  std::size_t offset = 0;
  std::map<std::string, int> seen;
  for (const auto& t : tensors) {
    std::int64_t numel = 1;
    for (const auto s : t.shape) numel *= s;
    DS3D_CHECK(numel >= 0 && static_cast<std::size_t>(numel) == t.data.size(),
               "ds3d::serialize_safetensors: tensor '", t.name, "' has ", t.data.size(),
               " values for shape ", shape_string(t.shape));
    DS3D_CHECK(seen.emplace(t.name, 0).second, "ds3d::serialize_safetensors: duplicate tensor '",
               t.name, "'");
    std::string shape = "[";
    for (std::size_t i = 0; i < t.shape.size(); ++i) {
      if (i) shape += ',';
      shape += std::to_string(t.shape[i]);
    }
    shape += "]";
    const std::size_t bytes = t.data.size() * sizeof(float);
    if (header.size() > 1) header += ',';
    header += '"';
    header += detail::json_escape(t.name);
    header += "\":{\"dtype\":\"F32\",\"shape\":";
    header += shape;
    header += ",\"data_offsets\":[";
    header += std::to_string(offset);
    header += ',';
    header += std::to_string(offset + bytes);
    header += "]}";
    offset += bytes;
  }
  header += "}";
  while ((8 + header.size()) % 8 != 0) header += ' ';
  std::string out(8, '\0');
  const std::uint64_t n = header.size();
  std::memcpy(out.data(), &n, 8);
  out += header;
  out += data;
  return out;
}

}  // namespace ds3d
