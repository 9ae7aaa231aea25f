// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// SlamConfig and its key table (include/ds3d/slam/config.hpp): text round trips of every key,
// errors naming key and value, YAML/JSON files, the gate, the docs' key list and ds3d-slam's
// --config / --set / --dump-config.
#include "ds3d/slam/config.hpp"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <set>
#include <string>

#include "ds3d/errors.hpp"
#include "support/cli.hpp"
#include "support/files.hpp"

namespace {

namespace fs = std::filesystem;
using ds3d::slam::SlamConfig;

fs::path write_file(const std::string& name, const std::string& text) {
  const fs::path p = fs::temp_directory_path() / name;
  std::ofstream(p) << text;
  return p;
}

TEST(SlamConfig, EveryKeyRoundTripsItsDefault) {
  const auto& keys = ds3d::slam::config_keys();
  ASSERT_GT(keys.size(), 90U);
  std::set<std::string> names;
  for (const auto& k : keys) {
    EXPECT_TRUE(names.insert(k.name).second) << "duplicate key " << k.name;
    EXPECT_NE(k.name.find('.'), std::string::npos) << k.name;
    EXPECT_FALSE(k.help.empty()) << k.name;
    SlamConfig c;
    const std::string v = c.get(k.name);
    c.set(k.name, v);
    EXPECT_EQ(c.get(k.name), v) << k.name;
  }
  EXPECT_NO_THROW(SlamConfig{}.validate());
}

TEST(SlamConfig, SetChangesTheField) {
  SlamConfig c;
  c.set("htx.min_score", "0.4");
  c.set("frontend.fuse_neighbors", "true");
  c.set("frontend.orb.num_features", "1200");
  c.set("dynamic.source", "htx+geometric");
  c.set("dynamic.gate", "evidence");
  c.set("pipeline.threaded", "off");
  EXPECT_EQ(c.htx.min_score, 0.4F);
  EXPECT_TRUE(c.frontend.fuse_neighbors);
  EXPECT_EQ(c.frontend.orb.num_features, 1200);
  EXPECT_EQ(c.dynamic, "htx+geometric");
  EXPECT_EQ(c.gate, ds3d::slam::Gate::kEvidence);
  EXPECT_FALSE(c.pipeline.threaded);
  EXPECT_EQ(c.get("htx.min_score"), "0.4");
}

TEST(SlamConfig, BadKeysAndValuesNameThem) {
  SlamConfig c;
  auto message = [&](const char* key, const char* value) -> std::string {
    try {
      c.set(key, value);
    } catch (const ds3d::InvalidArgument& e) {
      return e.what();
    }
    return "";
  };
  EXPECT_NE(message("htx.min_scor", "1").find("htx.min_scor"), std::string::npos);
  const std::string m = message("htx.min_score", "abc");
  EXPECT_NE(m.find("htx.min_score"), std::string::npos) << m;
  EXPECT_NE(m.find("abc"), std::string::npos) << m;
  EXPECT_FALSE(message("frontend.local_window", "1.5").empty());
  EXPECT_FALSE(message("frontend.local_window", "99999999999").empty());  // beyond int
  EXPECT_FALSE(message("frontend.bf", "1e999").empty());
  EXPECT_FALSE(message("htx.segment", "maybe").empty());
  EXPECT_FALSE(message("dynamic.gate", "always").empty());
  EXPECT_THROW((void)c.get("no.key"), ds3d::InvalidArgument);
  c.set("htx.min_score", "2");  // parses; the range is validate()'s
  EXPECT_THROW(c.validate(), ds3d::InvalidArgument);
}

TEST(SlamConfig, FilesNestedDottedAndJson) {
  SlamConfig c;
  const auto yaml = write_file("ds3d_config_test.yaml",
                               "dynamic:\n  source: htx\n  gate: motion\n"
                               "htx:\n  min_score: 0.45\n  report_floor: true\n"
                               "frontend.orb.num_features: 900\n"
                               "frontend:\n  local_ba:\n    iterations_first: 4\n");
  ds3d::slam::apply_config_file(c, yaml);
  EXPECT_EQ(c.dynamic, "htx");
  EXPECT_EQ(c.gate, ds3d::slam::Gate::kMotion);
  EXPECT_EQ(c.htx.min_score, 0.45F);
  EXPECT_TRUE(c.htx.report_floor);
  EXPECT_EQ(c.frontend.orb.num_features, 900);
  EXPECT_EQ(c.frontend.local_ba.iterations_first, 4);
  SlamConfig j;
  ds3d::slam::apply_config_file(
      j, write_file("ds3d_config_test.json",
                    R"({"htx": {"detect_every": 3}, "filter.min_samples": 5})"));
  EXPECT_EQ(j.htx.detect_every, 3);
  EXPECT_EQ(j.filter.min_samples, 5);
  // errors name the file
  SlamConfig e;
  try {
    ds3d::slam::apply_config_file(e, write_file("ds3d_config_bad.yaml", "htx:\n  min_score: x\n"));
    ADD_FAILURE() << "no error";
  } catch (const ds3d::InvalidArgument& ex) {
    EXPECT_NE(std::string(ex.what()).find("ds3d_config_bad.yaml"), std::string::npos) << ex.what();
  }
  EXPECT_THROW(ds3d::slam::apply_config_file(e, write_file("ds3d_config_bad2.yaml", "a: [1, 2\n")),
               ds3d::IoError);
  EXPECT_THROW(ds3d::slam::apply_config_file(e, "/nonexistent/run.yaml"), ds3d::IoError);
}

TEST(SlamConfig, DumpReadsBackAsTheSameConfig) {
  SlamConfig c;
  c.set("htx.min_score", "0.35");
  c.set("dynamic.source", "file:/tmp/x y.jsonl");
  const auto p = write_file("ds3d_config_dump.yaml", ds3d::slam::dump_config(c));
  SlamConfig d;
  ds3d::slam::apply_config_file(d, p);
  for (const auto& k : ds3d::slam::config_keys()) EXPECT_EQ(d.get(k.name), c.get(k.name)) << k.name;
}

TEST(SlamConfig, GateNeedsASource) {
  SlamConfig c;
  c.dynamic = "none";
  c.gate = ds3d::slam::Gate::kMotion;
  EXPECT_THROW((void)ds3d::slam::make_dynamic_source(c), ds3d::InvalidArgument);
  c.dynamic = "geometric";
  EXPECT_EQ(ds3d::slam::make_dynamic_source(c)->name(), "geometric&geometric");
  SlamConfig none;
  none.dynamic = "none";
  EXPECT_EQ(ds3d::slam::make_masker(none), nullptr);
  // The default source is geometric, which the box filter follows.
  EXPECT_EQ(SlamConfig{}.dynamic, "geometric");
  EXPECT_NE(ds3d::slam::make_masker(SlamConfig{}), nullptr);
}

// docs/configuration.md lists every key with its default (generated by
// scripts/gen-config-doc.sh from ds3d::slam::config_markdown()).
TEST(SlamConfig, DocsListEveryKey) {
  const std::string doc =
      ds3d::test::read_file(fs::path(DS3D_SOURCE_DIR) / "docs" / "configuration.md");
  ASSERT_FALSE(doc.empty());
  EXPECT_NE(doc.find(ds3d::slam::config_markdown()), std::string::npos)
      << "docs/configuration.md is out of date: run scripts/gen-config-doc.sh";
}

ds3d::test::ToolResult run_cli(const std::string& args) {
  return ds3d::test::run_tool("ds3d-slam", args);
}

TEST(Ds3dSlamCli, ConfigSetAndDump) {
  if (!fs::exists(fs::path(DS3D_BINARY_DIR) / "bin" / "ds3d-slam")) GTEST_SKIP() << "not built";
  auto r = run_cli("--dump-config");
  ASSERT_EQ(r.code, 0) << r.output;
  EXPECT_EQ(r.output, ds3d::slam::dump_config());
  const auto yaml = write_file("ds3d_cli_config.yaml", "htx:\n  min_score: 0.45\n");
  r = run_cli("--config '" + yaml.string() +
              "' --set htx.detect_every=3 --dynamic htx --dump-config");
  ASSERT_EQ(r.code, 0) << r.output;
  EXPECT_NE(r.output.find("  min_score: 0.45  #"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("  detect_every: 3  #"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("  source: \"htx\"  #"), std::string::npos) << r.output;
  // --set after --config wins; the later of two settings wins
  r = run_cli("--config '" + yaml.string() +
              "' --set htx.min_score=0.2 --set htx.min_score=0.25 "
              "--dump-config");
  EXPECT_NE(r.output.find("  min_score: 0.25  #"), std::string::npos) << r.output;
  EXPECT_EQ(run_cli("--set nope=1 --dump-config").code, 2);
  EXPECT_EQ(run_cli("--config /nonexistent.yaml --dump-config").code, 2);
  // --help: every option of the usage text, at most 17 besides --help and --version (tuning
  // belongs in config keys; the options pick input, outputs and how the input is played)
  r = run_cli("--help");
  ASSERT_EQ(r.code, 0);
  std::set<std::string> options;
  const std::string usage = r.output.substr(0, r.output.find("\nTracks"));
  for (std::size_t p = usage.find("--"); p != std::string::npos; p = usage.find("--", p + 2)) {
    const std::size_t e = usage.find_first_of(" ]|\n", p);
    options.insert(usage.substr(p, e - p));
  }
  EXPECT_EQ(options.erase("--help") + options.erase("--version"), 2U) << r.output;
  EXPECT_LE(options.size(), 17U) << r.output;  // besides --help and --version
  EXPECT_TRUE(options.count("--config") == 1 && options.count("--set") == 1 &&
              options.count("--dump-config") == 1);
}

}  // namespace
