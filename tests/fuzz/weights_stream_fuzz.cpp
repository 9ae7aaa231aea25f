// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// libFuzzer target: weights loaded from a file stream (WeightsFile::read,
// SparseDetector::load), with the checksum and range checks. Any input must load or throw
// ds3d::IoError / ds3d::InvalidArgument; a file that loads with a checksum must be rejected
// after any single flipped bit of its tensor bytes. Run with `make fuzz`.
#include <unistd.h>

#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>

#include "ds3d/errors.hpp"
#include "ds3d/htx/sparse_detector.hpp"
#include "ds3d/htx/weights_io.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static const std::filesystem::path path =
      std::filesystem::temp_directory_path() /
      ("ds3d_weights_fuzz_" + std::to_string(::getpid()) + ".safetensors");
  const std::string bytes(reinterpret_cast<const char*>(data), size);
  std::ofstream(path, std::ios::binary | std::ios::trunc) << bytes;
  bool checksum = false;
  try {
    const auto w = ds3d::WeightsFile::read(path);
    checksum = w.has_checksum();
    (void)ds3d::SparseDetector::load(path);
  } catch (const ds3d::IoError&) {
  } catch (const ds3d::InvalidArgument&) {
  }
  if (!checksum) return 0;
  std::uint64_t n = 0;
  std::memcpy(&n, bytes.data(), 8);
  const std::size_t start = 8 + static_cast<std::size_t>(n);
  if (start >= bytes.size()) return 0;
  std::string flipped = bytes;
  const std::size_t bit = (size * 2654435761U) % ((bytes.size() - start) * 8);
  flipped[start + bit / 8] = static_cast<char>(flipped[start + bit / 8] ^ (1 << (bit % 8)));
  try {
    (void)ds3d::WeightsFile::parse(flipped, "fuzz");
  } catch (const ds3d::IoError&) {
    return 0;
  }
  std::abort();  // a flipped bit passed the checksum
}
