// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// Private to src/slam/config*.cpp: the text forms of config fields and the key-row builder.
#pragma once

#include <charconv>
#include <cmath>
#include <filesystem>
#include <string>
#include <string_view>
#include <type_traits>
#include <utility>

#include "ds3d/errors.hpp"
#include "ds3d/slam/config.hpp"

namespace ds3d::slam::detail_config {

inline constexpr const char* kSet = "ds3d::slam::SlamConfig::set";

[[noreturn]] inline void bad_value(std::string_view key, std::string_view value,
                                   const char* expected) {
  throw InvalidArgument(
      ds3d::detail::concat(kSet, ": ", key, " expects ", expected, " (got '", value, "')"));
}

template <class T>
std::string to_text(const T& v) {
  if constexpr (std::is_same_v<T, bool>) {
    return v ? "true" : "false";
  } else if constexpr (std::is_same_v<T, std::string>) {
    return v;
  } else if constexpr (std::is_same_v<T, std::filesystem::path>) {
    return v.string();
  } else if constexpr (std::is_same_v<T, Gate>) {
    return to_string(v);
  } else {
    char buf[64];
    const auto r = std::to_chars(buf, buf + sizeof(buf), v);  // shortest round-trip form
    return {buf, r.ptr};
  }
}

template <class T>
T from_text(std::string_view key, std::string_view s) {
  if constexpr (std::is_same_v<T, bool>) {
    if (s == "true" || s == "1" || s == "yes" || s == "on") return true;
    if (s == "false" || s == "0" || s == "no" || s == "off") return false;
    bad_value(key, s, "true or false");
  } else if constexpr (std::is_same_v<T, std::string> || std::is_same_v<T, std::filesystem::path>) {
    return T(std::string(s));
  } else if constexpr (std::is_same_v<T, Gate>) {
    try {
      return parse_gate(s);
    } catch (const InvalidArgument&) {
      bad_value(key, s, "none, motion or evidence");
    }
  } else {
    T v{};
    const auto* first = s.data();
    if (!s.empty() && s.front() == '+') ++first;  // from_chars takes no leading '+'
    const auto r = std::from_chars(first, s.data() + s.size(), v);
    if (s.empty() || r.ec != std::errc() || r.ptr != s.data() + s.size()) {
      bad_value(key, s, std::is_integral_v<T> ? "an integer in range" : "a number");
    }
    if constexpr (std::is_floating_point_v<T>) {
      if (!std::isfinite(v) && s.find_first_of("iI") == std::string_view::npos) {
        bad_value(key, s, "a number in range");  // overflow to inf; "inf" itself is allowed
      }
    }
    return v;
  }
}

template <class T>
const char* type_name() {
  if constexpr (std::is_same_v<T, bool>) return "bool";
  if constexpr (std::is_integral_v<T>) return "int";
  if constexpr (std::is_floating_point_v<T>) return "number";
  return "string";
}

// One row: `access` returns a reference to the field of a (const or mutable) SlamConfig.
template <class Access>
ConfigKey key(std::string name, Access access, std::string help) {
  using T = std::remove_cvref_t<decltype(access(std::declval<SlamConfig&>()))>;
  ConfigKey k;
  k.type = type_name<T>();
  k.help = std::move(help);
  k.get = [access](const SlamConfig& c) { return to_text<T>(access(c)); };
  k.set = [access, name](SlamConfig& c, std::string_view s) { access(c) = from_text<T>(name, s); };
  k.name = std::move(name);
  return k;
}

/// Every key, section by section (src/slam/config_keys.cpp).
std::vector<ConfigKey> make_config_keys();

}  // namespace ds3d::slam::detail_config
