// SWEEP.json's numbers (docs/cli.md): whole numbers within their ranges and at most ten million
// runs in all, read without undefined behaviour (fuzz_sweep_config cast 1e300 to int) and refused
// as bad input naming the file otherwise.
#include <gtest/gtest.h>

#include <string>

#include "engine/error.hpp"
#include "pipelines/sweep/sweep.hpp"
#include "tests/cli_fixture.hpp"

namespace fluoro {
namespace {

class SweepConfigTest : public test::CliTest {
 protected:
  SweepConfig read(const std::string& json) {
    write_text("sweep.json", json);
    return read_sweep_config(path("sweep.json"));
  }
  void expect_refused(const std::string& json, const std::string& words) {
    write_text("sweep.json", json);
    try {
      read_sweep_config(path("sweep.json"));
      ADD_FAILURE() << "accepted: " << json;
    } catch (const InputError& e) {
      const std::string what = e.what();
      EXPECT_NE(what.find(path("sweep.json")), std::string::npos) << what;
      EXPECT_NE(what.find(words), std::string::npos) << what;
      EXPECT_EQ(what.find('\n'), std::string::npos) << what;
    }
  }
};

TEST_F(SweepConfigTest, WholeNumbersAreReadAndFractionsOrHugeValuesRefused) {
  const SweepConfig c = read(R"({"phantom": {"kind": "femur", "size": 128.0, "seed": 9}, "c_arm": {"pixels": 256},
                                 "runs_per_distance": 7, "seed": 3})");
  EXPECT_EQ(c.phantom.size, 128);
  EXPECT_EQ(c.phantom.seed, 9u);
  EXPECT_EQ(c.c_arm.pixels, 256);
  EXPECT_EQ(c.runs_per_distance, 7);
  EXPECT_EQ(c.seed, 3u);
  expect_refused(R"({"phantom": {"kind": "femur", "size": 128.5}})", "\"size\" must be a whole number from 8 to 2048");
  expect_refused(R"({"phantom": {"kind": "femur", "size": 1e300}})", "\"size\"");
  expect_refused(R"({"phantom": {"kind": "femur", "seed": -1}})", "\"seed\"");
  expect_refused(R"({"phantom": {"kind": "femur"}, "c_arm": {"pixels": 3e40}})", "\"pixels\"");
  expect_refused(R"({"phantom": {"kind": "femur"}, "runs_per_distance": 0})", "\"runs_per_distance\"");
  expect_refused(R"({"phantom": {"kind": "femur"}, "runs_per_distance": 1e19})", "\"runs_per_distance\"");
  expect_refused(R"({"phantom": {"kind": "femur"}, "seed": 1e300})", "\"seed\"");
  expect_refused(R"({"phantom": {"kind": "femur"}, "physics": {"photons": 1e19}})", "\"photons\"");
  expect_refused(R"({"phantom": {"kind": "femur"}, "noise": 1e39})", "\"noise\"");
}

TEST_F(SweepConfigTest, AtMostTenMillionRuns) {
  // 10,000 distance bins (1 to 10,000 mm) x 1,000 runs: exactly the limit; one run a bin more is over it.
  const std::string bins = R"({"phantom": {"kind": "femur"}, "distances_mm": {"from": 1, "to": 10000, "step": 1}, )";
  const SweepConfig c = read(bins + R"("runs_per_distance": 1000})");
  EXPECT_EQ(sweep_distance_bins(c), 10000);
  expect_refused(bins + R"("runs_per_distance": 1001})", "more than 10 million runs");
  SweepConfig over = c;
  over.runs_per_distance = 1001;
  EXPECT_THROW(plan_sweep(over), std::invalid_argument);
  SweepConfig small = c;
  small.to_mm = 3;
  small.runs_per_distance = 2;
  EXPECT_EQ(plan_sweep(small).size(), 6u);
}

// "correlation_polish": the three modes by name, and true / false as before the automatic mode.
TEST_F(SweepConfigTest, TheCorrelationPolishByNameOrAsABoolean) {
  const std::string femur = R"({"phantom": {"kind": "femur"})";
  EXPECT_EQ(read(femur + "}").correlation_polish, CorrelationPolish::when_needed);
  EXPECT_EQ(read(femur + R"(, "correlation_polish": "auto"})").correlation_polish, CorrelationPolish::when_needed);
  EXPECT_EQ(read(femur + R"(, "correlation_polish": "on"})").correlation_polish, CorrelationPolish::always);
  EXPECT_EQ(read(femur + R"(, "correlation_polish": "off"})").correlation_polish, CorrelationPolish::off);
  EXPECT_EQ(read(femur + R"(, "correlation_polish": true})").correlation_polish, CorrelationPolish::always);
  EXPECT_EQ(read(femur + R"(, "correlation_polish": false})").correlation_polish, CorrelationPolish::off);
  expect_refused(femur + R"(, "correlation_polish": "sometimes"})", "\"correlation_polish\" must be");
  expect_refused(femur + R"(, "correlation_polish": 1})", "\"correlation_polish\" must be");
}

}  // namespace
}  // namespace fluoro
