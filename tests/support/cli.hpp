// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// Runs one of the project's command-line tools from the build tree (tests of their options).
#pragma once

#include <sys/wait.h>

#include <cstdio>
#include <filesystem>
#include <string>

namespace ds3d::test {

/// Exit code (-1: did not exit normally) and stdout + stderr of one tool run.
struct ToolResult {
  int code = -1;
  std::string output;
};

/// The path of build/bin/`tool` (DS3D_BINARY_DIR).
inline std::filesystem::path tool_path(const std::string& tool) {
  return std::filesystem::path(DS3D_BINARY_DIR) / "bin" / tool;
}

/// Runs `tool args` through the shell (args are shell words), capturing stdout and stderr.
inline ToolResult run_tool(const std::string& tool, const std::string& args) {
  ToolResult r;
  FILE* p = ::popen((tool_path(tool).string() + " " + args + " 2>&1").c_str(), "r");
  if (p == nullptr) return r;
  char buf[4096];
  for (std::size_t n; (n = std::fread(buf, 1, sizeof(buf), p)) > 0;) r.output.append(buf, n);
  const int status = ::pclose(p);
  r.code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return r;
}

}  // namespace ds3d::test
