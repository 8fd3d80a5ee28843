#pragma once
// Running the fluoro program in tests: a fresh temporary directory per test, the program's exit
// code and output, and the two error contracts every subcommand keeps (docs/cli.md): bad input is
// one line, exit 2 and no output; readable input that defeats the method is exit 3 with the result
// file written as "failed".
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "engine/json_io.hpp"
#include "engine/sha256.hpp"
#include "engine/version.hpp"

namespace fluoro::test {

struct CliResult {
  int code;
  std::string out, err;
};

class CliTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = std::filesystem::temp_directory_path() /
           ("fluoro_cli_" + std::to_string(::getpid()) + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->test_suite_name() + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    std::filesystem::remove_all(dir_);
    std::filesystem::create_directories(dir_);
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }

  std::string path(const std::string& name) const { return (dir_ / name).string(); }

  // Runs `fluoro ARGS`; env: assignments for the program's environment ("NAME=value ...").
  CliResult run(const std::string& args, const std::string& env = "") const {
    const std::string out = path("stdout.txt"), err = path("stderr.txt");
    const int status = std::system(
        (env + (env.empty() ? "" : " ") + std::string(FLUORO_CLI) + " " + args + " >" + out + " 2>" + err).c_str());
    return {WIFEXITED(status) ? WEXITSTATUS(status) : -1, slurp(out), slurp(err)};
  }
  static std::string slurp(const std::string& p) {
    std::ifstream f(p);
    std::stringstream s;
    s << f.rdbuf();
    return s.str();
  }
  void write_text(const std::string& name, const std::string& text) const { std::ofstream(path(name)) << text; }

  // Exit 2 with one line naming `names`; `output` (a file name in the directory), if given, not written.
  void expect_bad_input(const CliResult& r, const std::string& names, const std::string& output = "") const {
    EXPECT_EQ(r.code, 2) << r.err;
    EXPECT_NE(r.err.find(names), std::string::npos) << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
    if (!output.empty()) {
      EXPECT_FALSE(std::filesystem::exists(path(output))) << output;
    }
  }
  // Exit 3 with one line, the result file written with status "failed" and a reason, and none of `absent`.
  nlohmann::json expect_failed(const CliResult& r, const std::string& output,
                               const std::vector<std::string>& absent = {}) const {
    EXPECT_EQ(r.code, 3) << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
    const nlohmann::json doc = read_json(path(output));
    EXPECT_EQ(doc["status"], "failed");
    EXPECT_TRUE(doc["reason"].is_string());
    for (const auto& key : absent) EXPECT_FALSE(doc.contains(key)) << key;
    return doc;
  }

  // The result's "provenance" (docs/cli.md): this version, the command, its settings, the thread
  // limit, and every file of its "inputs" with the SHA-256 of its bytes now.
  static void expect_provenance(const nlohmann::json& doc, const std::string& command) {
    ASSERT_TRUE(doc.contains("provenance")) << command;
    const nlohmann::json& p = doc["provenance"];
    EXPECT_EQ(p["program"], "fluoro");
    EXPECT_EQ(p["version"], FLUORO_VERSION);
    EXPECT_EQ(p["command"], command);
    EXPECT_TRUE(p["settings"].is_object()) << command;
    EXPECT_GE(p["threads"].get<int>(), 1);
    EXPECT_TRUE(p["arguments"].is_array() && !p["arguments"].empty());
    ASSERT_TRUE(p["inputs"].is_array() && !p["inputs"].empty()) << command;
    size_t files = 0;
    const std::function<void(const nlohmann::json&)> count = [&](const nlohmann::json& j) {
      if (j.is_object() && j.contains("path")) ++files;
      else if (j.is_structured())
        for (const auto& item : j) count(item);
    };
    count(doc["inputs"]);
    EXPECT_EQ(p["inputs"].size(), files) << command << ": every input is digested";
    for (const auto& f : p["inputs"]) {
      const std::string file = f["path"].get<std::string>();
      if (std::filesystem::is_regular_file(file)) {
        EXPECT_EQ(f["sha256"], sha256_file(file)) << file;
      }
    }
  }

  std::filesystem::path dir_;
};

}  // namespace fluoro::test
