// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
#include "ds3d/detail/json.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <string>

namespace {

using ds3d::detail::parse_json;

TEST(Json, ParsesNestedDocument) {
  const auto v = parse_json(R"({"a": [1, 2.5, -3e2], "b": {"c": "x\u00e9\n"}, "t": true,
                               "n": null, "nan": NaN, "inf": -Infinity})");
  EXPECT_EQ(v.at("a").size(), 3U);
  EXPECT_EQ(v.at("a").at(2).as_number(), -300.0);
  EXPECT_EQ(v.at("a").at(0).as_int(), 1);
  EXPECT_EQ(v.at("b").at("c").as_string(), "x\xc3\xa9\n");
  EXPECT_TRUE(v.at("t").as_bool());
  EXPECT_TRUE(v.at("n").is_null());
  EXPECT_TRUE(std::isnan(v.at("nan").as_number()));
  EXPECT_EQ(v.at("inf").as_number(), -HUGE_VAL);
}

TEST(Json, SurrogatePairs) {
  EXPECT_EQ(parse_json(R"("\ud83d\ude00")").as_string(), "\xf0\x9f\x98\x80");
  EXPECT_THROW((void)parse_json(R"("\ud83d")"), ds3d::IoError);
}

TEST(Json, RejectsMalformedInput) {
  for (const std::string bad :
       {"", "{", "[1,]", "{\"a\" 1}", "{\"a\":1,\"a\":2}", "01x", "\"abc", "tru", "[1] 2",
        "\"\xff\"", "\"\xc0\x80\"", "{\"a\":-}", "1.", "1e"}) {
    EXPECT_THROW((void)parse_json(bad), ds3d::IoError) << bad;
  }
}

TEST(Json, RejectsDeepNesting) {
  EXPECT_THROW((void)parse_json(std::string(1000, '[') + std::string(1000, ']')), ds3d::IoError);
}

TEST(Json, AccessorsThrowIoErrorOnTypeMismatch) {
  const auto v = parse_json(R"({"a": 1.5})");
  EXPECT_THROW((void)v.at("missing"), ds3d::IoError);
  EXPECT_THROW((void)v.at("a").as_string(), ds3d::IoError);
  EXPECT_THROW((void)v.at("a").as_int(), ds3d::IoError);
}

TEST(Json, EscapeAndNumber) {
  EXPECT_EQ(ds3d::detail::json_escape("a\"b\\c\n\x01"), "a\\\"b\\\\c\\n\\u0001");
  EXPECT_EQ(ds3d::detail::json_number(0.1), "0.10000000000000001");
  EXPECT_EQ(ds3d::detail::json_number(std::nan("")), "null");
}

}  // namespace
