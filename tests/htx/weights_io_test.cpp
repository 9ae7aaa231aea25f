// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
#include "ds3d/htx/weights_io.hpp"

#include <gtest/gtest.h>

#include <cstring>
#include <limits>
#include <string>

#include "ds3d/errors.hpp"
#include "support/files.hpp"

namespace {

using ds3d::IoError;
using ds3d::WeightsFile;

// A file with a hand-written header (data buffer of `data_bytes` zero bytes).
std::string file_with_header(const std::string& header, std::size_t data_bytes) {
  std::string out(8, '\0');
  const std::uint64_t n = header.size();
  std::memcpy(out.data(), &n, 8);
  return out + header + std::string(data_bytes, '\0');
}

// Expects parse() to throw IoError whose message contains `needle`.
void expect_io_error(const std::string& bytes, const std::string& needle) {
  try {
    (void)WeightsFile::parse(bytes, "test");
    ADD_FAILURE() << "no exception; expected one containing '" << needle << "'";
  } catch (const IoError& e) {
    EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << e.what();
  }
}

TEST(WeightsIo, RoundTrip) {
  const std::string bytes = ds3d::serialize_safetensors(
      {{"a", {2, 3}, {1, 2, 3, 4, 5, 6}}, {"s", {}, {2.5F}}, {"e", {0}, {}}},
      {{"format", "x"}, {"k\"ey", "v\n"}});
  std::uint64_t header_len = 0;
  std::memcpy(&header_len, bytes.data(), 8);
  EXPECT_EQ((8 + header_len) % 8, 0U);  // data buffer starts 8-byte aligned
  const auto w = WeightsFile::parse(bytes);
  EXPECT_EQ(w.names(), (std::vector<std::string>{"a", "e", "s"}));
  EXPECT_EQ(w.f32("a", {2, 3}), (std::vector<float>{1, 2, 3, 4, 5, 6}));
  EXPECT_EQ(w.f32("s", {}), (std::vector<float>{2.5F}));
  EXPECT_TRUE(w.f32("e", {0}).empty());
  EXPECT_EQ(w.metadata("k\"ey"), "v\n");
  EXPECT_THROW((void)w.metadata("nope"), IoError);
}

TEST(WeightsIo, ReadsFilesWrittenByPython) {
  const auto w = WeightsFile::read(ds3d::test::data_path("htx/tiny_weights.safetensors"));
  EXPECT_EQ(w.metadata("format"), "ds3d-htx");
  EXPECT_TRUE(w.contains("pos_embedding.gauss_B"));
  EXPECT_THROW((void)WeightsFile::read(ds3d::test::data_path("htx/missing.safetensors")), IoError);
}

TEST(WeightsIo, RejectsShortFileAndBadHeaderLength) {
  expect_io_error("", "fewer than the 8-byte");
  expect_io_error(std::string(7, '\0'), "fewer than the 8-byte");
  std::string big = file_with_header("{}", 0);
  const std::uint64_t huge = 1ULL << 40;
  std::memcpy(big.data(), &huge, 8);
  expect_io_error(big, "100 MB");
  std::string over = file_with_header("{}", 0);
  const std::uint64_t n = 3;
  std::memcpy(over.data(), &n, 8);
  expect_io_error(over, "exceeds the file size");
}

// A device or FIFO never ends: refused by its file type before anything is read.
TEST(WeightsIo, RefusesFilesThatAreNotRegular) {
  for (const char* path : {"/dev/urandom", "/dev/zero", "/tmp"}) {
    try {
      (void)WeightsFile::read(path);
      FAIL() << path;
    } catch (const IoError& e) {
      EXPECT_NE(std::string(e.what()).find(std::string(path) + ": not a regular file"),
                std::string::npos)
          << e.what();
    }
  }
}

TEST(WeightsIo, RejectsBadJson) {
  expect_io_error(file_with_header("{\"a\":", 0), "invalid JSON");
  expect_io_error(file_with_header("[1]", 0), "not an object");
  expect_io_error(file_with_header("{\"a\xff\":1}", 0), "invalid JSON");  // invalid UTF-8
  expect_io_error(file_with_header("{\"__metadata__\":{\"k\":1}}", 0), "not a string");
}

TEST(WeightsIo, RejectsBadEntries) {
  const std::string ok = R"({"t":{"dtype":"F32","shape":[2],"data_offsets":[0,8]}})";
  EXPECT_NO_THROW((void)WeightsFile::parse(file_with_header(ok, 8)));
  expect_io_error(file_with_header(R"({"t":{"dtype":"F99","shape":[2],"data_offsets":[0,8]}})", 8),
                  "tensor 't': unknown dtype");
  expect_io_error(file_with_header(R"({"t":{"dtype":"F32","shape":[-2],"data_offsets":[0,8]}})", 8),
                  "tensor 't': shape dimension");
  expect_io_error(file_with_header(R"({"t":{"dtype":"F32","shape":[3],"data_offsets":[0,8]}})", 8),
                  "tensor 't': shape [3] x F32");
  expect_io_error(file_with_header(R"({"t":{"dtype":"F32","shape":[2],"data_offsets":[0,16]}})", 8),
                  "tensor 't': data_offsets [0, 16] out of range");
  expect_io_error(file_with_header(R"({"t":{"dtype":"F32","shape":[2],"data_offsets":[8,0]}})", 8),
                  "end 0 < begin 8");
  expect_io_error(file_with_header(R"({"t":{"dtype":"F32","shape":[2]}})", 8),
                  "needs dtype, shape");
  expect_io_error(
      file_with_header(R"({"t":{"dtype":"F32","shape":[2],"data_offsets":[0,8],"x":1}})", 8),
      "unknown key 'x'");
  expect_io_error(
      file_with_header(
          R"({"t":{"dtype":"F32","shape":[4611686018427387904,4],"data_offsets":[0,8]}})", 8),
      "tensor 't'");
}

TEST(WeightsIo, RejectsOverlapsAndHoles) {
  expect_io_error(file_with_header(R"({"a":{"dtype":"F32","shape":[2],"data_offsets":[0,8]},)"
                                   R"("b":{"dtype":"F32","shape":[2],"data_offsets":[4,12]}})",
                                   12),
                  "tensor 'b': data_offsets overlap those of tensor 'a'");
  expect_io_error(file_with_header(R"({"a":{"dtype":"F32","shape":[1],"data_offsets":[0,4]},)"
                                   R"("b":{"dtype":"F32","shape":[1],"data_offsets":[8,12]}})",
                                   12),
                  "tensor 'b': hole");
  expect_io_error(file_with_header(R"({"a":{"dtype":"F32","shape":[1],"data_offsets":[0,4]}})", 8),
                  "tensors cover 4");
}

TEST(WeightsIo, CheckedAccess) {
  std::string bytes = ds3d::serialize_safetensors({{"a", {2}, {1.0F, 2.0F}}}, {});
  const auto w = WeightsFile::parse(bytes);
  try {
    (void)w.f32("a", {3});
    ADD_FAILURE();
  } catch (const IoError& e) {
    EXPECT_NE(std::string(e.what()).find("tensor 'a': shape [2], expected [3]"), std::string::npos)
        << e.what();
  }
  EXPECT_THROW((void)w.f32("b", {2}), IoError);
  // A NaN weight never reaches the detector.
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const auto bad = WeightsFile::parse(ds3d::serialize_safetensors({{"a", {2}, {1.0F, nan}}}, {}));
  EXPECT_THROW((void)bad.f32("a", {2}), IoError);
  EXPECT_THROW((void)ds3d::serialize_safetensors({{"a", {3}, {1.0F}}}, {}), ds3d::InvalidArgument);
}

TEST(WeightsIo, AnyTruncationIsAnError) {
  const std::string bytes =
      ds3d::test::read_file(ds3d::test::data_path("htx/tiny_weights.safetensors"));
  for (std::size_t cut :
       {std::size_t{0}, std::size_t{5}, std::size_t{100}, bytes.size() / 2, bytes.size() - 1}) {
    EXPECT_THROW((void)WeightsFile::parse(bytes.substr(0, cut)), IoError) << cut;
  }
}

}  // namespace
