// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
#pragma once
// Line and number reading shared by the TUM list/trajectory readers and camera.txt. It follows
// what the TUM benchmark scripts (associate.py, evaluate_ate.py, evaluate_rpe.py) do in Python 3
// text mode: universal newlines, ',' and TAB become spaces, a line is a comment only when its
// first character is '#', tokens are split on ' ' and stripped, numbers follow Python's float().
// Also the atomic file writer (temp file + rename). Not API.

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <limits>
#include <optional>
#include <random>
#include <sstream>
#include <string>
#include <string_view>
#include <system_error>
#include <vector>

#include "ds3d/errors.hpp"

namespace ds3d::detail {

/// One non-comment, non-empty line: its 1-based number and its tokens.
struct TextLine {
  std::size_t number = 0;
  std::vector<std::string_view> tokens;
};

[[nodiscard]] inline bool is_py_space(char c) {
  // ASCII characters that Python's str.strip() removes.
  return c == ' ' || c == '\t' || c == '\n' || c == '\r' || c == '\v' || c == '\f' ||
         (c >= '\x1c' && c <= '\x1f');
}

/// Splits `text` like the TUM scripts: lines end at "\r\n", "\r" or "\n"; a line that is empty
/// or whose first character is '#' is skipped; ',' and TAB separate like ' '. The returned views
/// point into `text`. Lines whose tokens are all empty are returned with no tokens.
[[nodiscard]] inline std::vector<TextLine> split_tum_lines(std::string_view text) {
  std::vector<TextLine> out;
  std::size_t pos = 0;
  std::size_t number = 0;
  while (pos <= text.size()) {
    std::size_t end = pos;
    while (end < text.size() && text[end] != '\n' && text[end] != '\r') ++end;
    const std::string_view line = text.substr(pos, end - pos);
    ++number;
    if (end < text.size() && text[end] == '\r' && end + 1 < text.size() && text[end + 1] == '\n') {
      pos = end + 2;
    } else {
      pos = end + 1;
    }
    if (line.empty() || line.front() == '#') continue;
    TextLine tl;
    tl.number = number;
    std::size_t i = 0;
    while (i < line.size()) {
      std::size_t j = i;
      while (j < line.size() && line[j] != ' ' && line[j] != ',' && line[j] != '\t') ++j;
      std::string_view tok = line.substr(i, j - i);
      while (!tok.empty() && is_py_space(tok.front())) tok.remove_prefix(1);
      while (!tok.empty() && is_py_space(tok.back())) tok.remove_suffix(1);
      if (!tok.empty()) tl.tokens.push_back(tok);
      i = j + 1;
    }
    out.push_back(std::move(tl));
    if (end >= text.size()) break;
  }
  return out;
}

/// Parses a token with the grammar of Python's float(): optional sign, decimal digits with
/// single '_' between digits, optional fraction and exponent, or inf/infinity/nan (any case).
/// Hexadecimal and partial numbers are rejected. Returns nullopt when the token is not a number.
[[nodiscard]] inline std::optional<double> parse_py_float(std::string_view tok) {
  std::string clean;
  clean.reserve(tok.size());
  std::size_t i = 0;
  const auto lower = [](char c) { return (c >= 'A' && c <= 'Z') ? static_cast<char>(c + 32) : c; };
  if (i < tok.size() && (tok[i] == '+' || tok[i] == '-')) clean += tok[i++];
  {
    std::string rest;
    for (std::size_t k = i; k < tok.size(); ++k) rest += lower(tok[k]);
    if (rest == "inf" || rest == "infinity") {
      const double v = std::numeric_limits<double>::infinity();
      return (!clean.empty() && clean[0] == '-') ? -v : v;
    }
    if (rest == "nan") return std::numeric_limits<double>::quiet_NaN();
  }
  // digits with underscores only between digits
  const auto digits = [&](bool& any) {
    any = false;
    while (i < tok.size()) {
      const char c = tok[i];
      if (c >= '0' && c <= '9') {
        clean += c;
        any = true;
        ++i;
      } else if (c == '_' && any && i + 1 < tok.size() && tok[i + 1] >= '0' && tok[i + 1] <= '9') {
        ++i;
      } else {
        break;
      }
    }
  };
  bool int_digits = false;
  bool frac_digits = false;
  digits(int_digits);
  if (i < tok.size() && tok[i] == '.') {
    clean += '.';
    ++i;
    digits(frac_digits);
  }
  if (!int_digits && !frac_digits) return std::nullopt;
  if (i < tok.size() && (tok[i] == 'e' || tok[i] == 'E')) {
    clean += 'e';
    ++i;
    if (i < tok.size() && (tok[i] == '+' || tok[i] == '-')) clean += tok[i++];
    bool exp_digits = false;
    digits(exp_digits);
    if (!exp_digits) return std::nullopt;
  }
  if (i != tok.size()) return std::nullopt;
  errno = 0;
  char* endp = nullptr;
  const double v = std::strtod(clean.c_str(), &endp);
  if (endp != clean.c_str() + clean.size()) return std::nullopt;
  return v;  // overflow gives +-inf and underflow a denormal/0, as Python's float()
}

/// Reads a whole file in binary; throws IoError naming `function` and the path.
[[nodiscard]] inline std::string read_text_file(const std::filesystem::path& path,
                                                const char* function) {
  std::error_code ec;
  DS3D_CHECK_AS(IoError, std::filesystem::is_regular_file(path, ec), function,
                ": not a readable file: '", path.string(), "'");
  std::ifstream in(path, std::ios::binary);
  DS3D_CHECK_AS(IoError, in.good(), function, ": cannot open '", path.string(), "'");
  std::ostringstream ss;
  ss << in.rdbuf();
  DS3D_CHECK_AS(IoError, !in.bad(), function, ": read error on '", path.string(), "'");
  return ss.str();
}

/// Flushes a written file's data to the storage device (fsync); false when that fails.
[[nodiscard]] inline bool sync_file(const std::filesystem::path& path) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) return false;
  const bool ok = ::fsync(fd) == 0;
  return ::close(fd) == 0 && ok;
}

/// Writes `content` to a temporary file beside `path`, flushes it to the device (fsync), then
/// renames it over `path`, so a reader never sees a half-written file, not even after a power
/// cut. Throws IoError naming `function` and the path.
inline void write_file_atomically(const std::filesystem::path& path, std::string_view content,
                                  const char* function) {
  namespace fs = std::filesystem;
  const fs::path dir = path.has_parent_path() ? path.parent_path() : fs::path(".");
  std::error_code ec;
  DS3D_CHECK_AS(IoError, fs::is_directory(dir, ec), function, ": directory does not exist: '",
                dir.string(), "'");
  thread_local std::mt19937_64 rng(std::random_device{}());
  std::string name(1, '.');
  name.append(path.filename().string());
  name.append(".tmp");
  name.append(std::to_string(rng() % 1000000000ULL));
  const fs::path tmp = dir / name;
  {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    DS3D_CHECK_AS(IoError, out.good(), function, ": cannot create '", tmp.string(), "'");
    out.write(content.data(), static_cast<std::streamsize>(content.size()));
    out.close();
    if (!out.good() || !sync_file(tmp)) {
      fs::remove(tmp, ec);
      throw IoError(concat(function, ": write failed on '", tmp.string(), "'"));
    }
  }
  fs::rename(tmp, path, ec);
  if (ec) {
    std::error_code ec2;
    fs::remove(tmp, ec2);
    throw IoError(concat(function, ": cannot rename '", tmp.string(), "' to '", path.string(),
                         "': ", ec.message()));
  }
}

}  // namespace ds3d::detail

namespace ds3d::detail {

/// One entry of a TUM list file (rgb.txt, depth.txt): a stamp and the rest of its tokens.
struct TumListEntry {
  double timestamp = 0;
  std::vector<std::string> values;
};

/// Parses a TUM list file as associate.py's read_file_list(): lines with fewer than 2 tokens are
/// ignored, a repeated stamp keeps its later line, the result is sorted by stamp. When
/// `duplicates` is given, the stamp of every line replaced by a later one is appended to it.
/// Throws IoError naming `function`, `source` and the line for a stamp that is not a finite number.
[[nodiscard]] inline std::vector<TumListEntry> parse_tum_list(
    std::string_view text, std::string_view source, const char* function,
    std::vector<double>* duplicates = nullptr) {
  std::vector<TumListEntry> out;
  for (const auto& line : split_tum_lines(text)) {
    if (line.tokens.size() < 2) continue;
    const auto t = parse_py_float(line.tokens[0]);
    DS3D_CHECK_AS(IoError, t.has_value() && std::isfinite(*t), function, ": ", source, " line ",
                  line.number, ": timestamp '", line.tokens[0], "' is not a finite number");
    TumListEntry e;
    e.timestamp = *t;
    for (std::size_t k = 1; k < line.tokens.size(); ++k) e.values.emplace_back(line.tokens[k]);
    out.push_back(std::move(e));
  }
  std::stable_sort(out.begin(), out.end(), [](const TumListEntry& a, const TumListEntry& b) {
    return a.timestamp < b.timestamp;
  });
  std::vector<TumListEntry> unique;
  unique.reserve(out.size());
  for (std::size_t i = 0; i < out.size(); ++i) {
    if (i + 1 < out.size() && out[i + 1].timestamp == out[i].timestamp) {
      if (duplicates != nullptr) duplicates->push_back(out[i].timestamp);
      continue;
    }
    unique.push_back(std::move(out[i]));
  }
  return unique;
}

}  // namespace ds3d::detail
