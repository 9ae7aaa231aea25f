// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
#pragma once
/// @file weights_io.hpp
/// @brief A reader for safetensors-layout weight files that trusts nothing (htx spec §7).
///
/// Layout: 8-byte little-endian unsigned header length N; N bytes of UTF-8 JSON (an object
/// mapping tensor names to {"dtype", "shape", "data_offsets": [begin, end)} plus an optional
/// "__metadata__" object of string values); then the data buffer, tensors in C order,
/// little-endian, back to back. Every defect (short file, header length beyond the file or over
/// 100 MB, invalid UTF-8 or JSON, unknown dtype, negative or huge shapes, offsets out of range,
/// overlapping or leaving holes, byte length != product(shape) x dtype size, non-finite float
/// values or values beyond |w| <= 1e4) is a ds3d::IoError whose message names the source and the
/// tensor.
///
/// Integrity: the exporters (ds3d.htx.export, serialize_safetensors) store the SHA-256 of the
/// whole data buffer as 64 lowercase hex digits in `__metadata__["tensors_sha256"]`. The reader
/// recomputes it and rejects a file whose value differs (one flipped bit is enough); a file
/// without the key (exported before checksums) is accepted, has_checksum() is then false, and
/// the tools print one warning. The range bound 1e4 is about 800 x the largest |w| of the
/// shipped model (12.3), so it only catches corrupted values (e.g. a flipped exponent bit).
/// Compiled in ds3d::slam (src/htx/weights_io.cpp); needs no OpenCV.

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <map>
#include <string>
#include <string_view>
#include <vector>

#include "ds3d/detail/abi_guard.hpp"

namespace ds3d {

/// Element types of the safetensors format.
enum class DType : std::uint8_t { kF32, kF16, kBF16, kF64, kI64, kI32, kI16, kI8, kU8, kBool };

/// One tensor as stored in the file.
struct TensorView {
  DType dtype = DType::kF32;        ///< element type as stored
  std::vector<std::int64_t> shape;  ///< empty for a 0-d tensor (one element)
  std::size_t begin = 0;            ///< byte offset into WeightsFile::data
  std::size_t end = 0;              ///< one past the last byte
  /// Number of elements: the product of shape (1 for a 0-d tensor).
  [[nodiscard]] std::int64_t numel() const;
};

/// A parsed and validated weights file (owns its bytes).
class WeightsFile {
 public:
  /// Reads and validates a file. @throws ds3d::IoError naming the path and the defect (missing,
  /// not a regular file such as a device or pipe, header length over 100 MB, bad layout).
  /// @note O(file size); the whole file is read into memory.
  [[nodiscard]] static WeightsFile read(const std::filesystem::path& path);
  /// Validates an in-memory image of a file; `source` names it in error messages.
  /// @throws ds3d::IoError. @note Used by the libFuzzer target tests/fuzz/weights_io_fuzz.cpp.
  [[nodiscard]] static WeightsFile parse(std::string bytes, std::string source = "<memory>");

  /// Tensor names in lexicographic order.
  [[nodiscard]] std::vector<std::string> names() const;
  /// True if the file has a tensor called `name`.
  [[nodiscard]] bool contains(std::string_view name) const;
  /// The entry of `name`. @throws ds3d::IoError if absent.
  [[nodiscard]] const TensorView& tensor(std::string_view name) const;
  /// F32 tensor `name` copied out, checked against `expected_shape` (shape mismatch, wrong
  /// dtype, missing tensor and non-finite values are ds3d::IoError naming the tensor and both
  /// shapes). @note O(numel).
  [[nodiscard]] std::vector<float> f32(std::string_view name,
                                       const std::vector<std::int64_t>& expected_shape) const;
  /// `__metadata__` (string values only; empty if absent).
  [[nodiscard]] const std::map<std::string, std::string, std::less<>>& metadata() const noexcept {
    return metadata_;
  }
  /// Metadata value. @throws ds3d::IoError naming the key if absent.
  [[nodiscard]] const std::string& metadata(std::string_view key) const;
  /// Where the file came from (path or the `source` given to parse()).
  [[nodiscard]] const std::string& source() const noexcept { return source_; }
  /// True when the metadata carried tensors_sha256 and it matched (parse() throws otherwise).
  [[nodiscard]] bool has_checksum() const noexcept { return has_checksum_; }

  /// Metadata key of the data buffer's SHA-256 (hex).
  static constexpr const char* kChecksumKey = "tensors_sha256";
  /// Largest |value| f32() accepts.
  static constexpr float kMaxAbsValue = 1e4F;

 private:
  void verify_checksum();
  bool has_checksum_ = false;
  std::string source_;
  std::string bytes_;
  std::size_t data_start_ = 0;
  std::map<std::string, TensorView, std::less<>> tensors_;
  std::map<std::string, std::string, std::less<>> metadata_;
};

/// One float32 tensor to write.
struct NamedTensor {
  std::string name;                 ///< tensor name, unique within a file
  std::vector<std::int64_t> shape;  ///< empty for a 0-d tensor
  std::vector<float> data;          ///< product(shape) values, C order
};

/// Serialises tensors (F32) and string metadata into the safetensors layout (header padded with
/// spaces to 8-byte alignment), the inverse of WeightsFile::parse. The data buffer's SHA-256 is
/// added as metadata "tensors_sha256" unless `metadata` already has that key.
/// @throws ds3d::InvalidArgument if a tensor's data size does not match its shape or a name
/// repeats.
[[nodiscard]] std::string serialize_safetensors(const std::vector<NamedTensor>& tensors,
                                                std::map<std::string, std::string> metadata);

/// Human-readable shape "[a, b]" (for error messages).
[[nodiscard]] std::string shape_string(const std::vector<std::int64_t>& shape);

}  // namespace ds3d
