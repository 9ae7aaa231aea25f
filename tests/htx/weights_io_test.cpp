// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
#include "ds3d/htx/weights_io.hpp"

#include <gtest/gtest.h>

#include <cstring>
#include <filesystem>
#include <limits>
#include <random>
#include <string>

#include "ds3d/detail/sha256.hpp"
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

TEST(WeightsIo, Sha256KnownVectors) {
  using ds3d::detail::sha256_hex;
  EXPECT_EQ(sha256_hex(""), "e3b0c44298fc1c149afbf4c8996fb92427ae41e4649b934ca495991b7852b855");
  EXPECT_EQ(sha256_hex("abc"), "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");
  EXPECT_EQ(sha256_hex("abcdbcdecdefdefgefghfghighijhijkijkljklmklmnlmnomnopnopq"),
            "248d6a61d20638b8e5c026930c3e6039a33ce45964ff2167f6ecedd419db06c1");
  ds3d::detail::Sha256 h;  // one million 'a', fed in uneven pieces
  for (int i = 0; i < 10000; ++i) h.update(std::string(i % 2 == 0 ? 37 : 163, 'a'));
  EXPECT_EQ(h.hex(), "cdc76e5c9914fb9281a1c7e284d73e67f1809a48a497200e046d39ccc7112cd0");
}

// Offset of the data buffer of a safetensors image.
std::size_t data_start(const std::string& bytes) {
  std::uint64_t n = 0;
  std::memcpy(&n, bytes.data(), 8);
  return 8 + static_cast<std::size_t>(n);
}

TEST(WeightsIo, ChecksumWrittenAndVerified) {
  const std::string bytes = ds3d::serialize_safetensors({{"a", {3}, {0.5F, -1.0F, 2.0F}}}, {});
  const auto w = WeightsFile::parse(bytes);
  EXPECT_TRUE(w.has_checksum());
  EXPECT_EQ(w.metadata(WeightsFile::kChecksumKey).size(), 64U);
  // Files exported before checksums load, with has_checksum() false (the tools warn).
  const auto old = WeightsFile::read(ds3d::test::data_path("htx/tiny_weights.safetensors"));
  EXPECT_FALSE(old.has_checksum());
  // A checksum that does not match: rejected, naming the source.
  const std::string wrong = ds3d::serialize_safetensors(
      {{"a", {1}, {1.0F}}}, {{WeightsFile::kChecksumKey, std::string(64, '0')}});
  expect_io_error(wrong, "test: __metadata__ tensors_sha256 is '000");
}

TEST(WeightsIo, FlippedBitsAreCaught) {
  std::vector<float> values(64);
  for (std::size_t i = 0; i < values.size(); ++i) values[i] = 0.01F * static_cast<float>(i) - 0.3F;
  const std::string good = ds3d::serialize_safetensors({{"w", {64}, values}}, {});
  const std::size_t start = data_start(good);
  // One flipped exponent bit (bit 30 of element 7: 0.4 becomes ~1.4e38).
  std::string bad = good;
  bad[start + 7 * 4 + 3] = static_cast<char>(bad[start + 7 * 4 + 3] ^ 0x40);
  expect_io_error(bad, "tensors_sha256");
  // 100 random single-bit flips anywhere in the tensor bytes.
  std::mt19937_64 rng(7);
  std::uniform_int_distribution<std::size_t> bit(0, (good.size() - start) * 8 - 1);
  for (int k = 0; k < 100; ++k) {
    const std::size_t b = bit(rng);
    std::string flipped = good;
    flipped[start + b / 8] = static_cast<char>(flipped[start + b / 8] ^ (1 << (b % 8)));
    EXPECT_THROW((void)WeightsFile::parse(flipped, "test"), IoError) << "bit " << b;
  }
  // Without a checksum the range check still catches the exponent flip.
  const std::string old =
      ds3d::serialize_safetensors({{"w", {64}, values}}, {{WeightsFile::kChecksumKey, "x"}});
  std::string unchecked = old;
  // Drop the checksum: rewrite the key so that the file carries none.
  const std::size_t key = unchecked.find(WeightsFile::kChecksumKey);
  ASSERT_NE(key, std::string::npos);
  unchecked[key] = 'T';
  const std::size_t ustart = data_start(unchecked);
  unchecked[ustart + 7 * 4 + 3] = static_cast<char>(unchecked[ustart + 7 * 4 + 3] ^ 0x40);
  const auto w = WeightsFile::parse(unchecked, "test");
  EXPECT_FALSE(w.has_checksum());
  try {
    (void)w.f32("w", {64});
    ADD_FAILURE() << "no range error";
  } catch (const IoError& e) {
    EXPECT_NE(std::string(e.what()).find("tensor 'w': element 7 = "), std::string::npos)
        << e.what();
    EXPECT_NE(std::string(e.what()).find("|w| <= 10000"), std::string::npos) << e.what();
  }
}

TEST(WeightsIo, ShippedModelCarriesItsChecksum) {
  const auto path = std::filesystem::path(DS3D_SOURCE_DIR) / "models" / "htx_lite_fast.safetensors";
  const auto w = WeightsFile::read(path);
  EXPECT_TRUE(w.has_checksum());
  EXPECT_EQ(w.metadata(WeightsFile::kChecksumKey),
            "94dc8d38137665f63eb794e19b5b597e33889c809703489dbc2700201ac64ae4");
}

}  // namespace
