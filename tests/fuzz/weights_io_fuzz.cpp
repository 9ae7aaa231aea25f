// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// libFuzzer target for the weights reader (src/htx/weights_io.cpp) and the detector's loader:
// any input must either parse or throw ds3d::IoError / ds3d::InvalidArgument, never crash,
// hang or read out of bounds. Build (clang, with ASan + UBSan):
//   clang++ -std=c++20 -O1 -g -fsanitize=fuzzer,address,undefined -Iinclude -I/usr/include/eigen3 \
//     tests/fuzz/weights_io_fuzz.cpp src/htx/*.cpp -o
//     build/weights_io_fuzz
//   build/weights_io_fuzz -max_len=65536 tests/data/htx   # seed corpus: the committed fixtures
#include <cstddef>
#include <cstdint>
#include <string>

#include "ds3d/errors.hpp"
#include "ds3d/htx/sparse_detector.hpp"
#include "ds3d/htx/weights_io.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  try {
    const auto w =
        ds3d::WeightsFile::parse(std::string(reinterpret_cast<const char*>(data), size), "fuzz");
    for (const auto& name : w.names()) (void)w.tensor(name).numel();
    (void)ds3d::SparseDetector::from_weights(w);
  } catch (const ds3d::IoError&) {
  } catch (const ds3d::InvalidArgument&) {
  }
  return 0;
}
