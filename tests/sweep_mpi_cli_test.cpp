// `fluoro sweep` over the ranks of an MPI job gives the rows a single process gives (order aside,
// timings aside), resumes the same way, and a program built without MPI refuses to be started as
// several ranks instead of running the whole sweep on each into the same file.
#include <gtest/gtest.h>

#include <algorithm>
#include <sstream>
#include <string>
#include <vector>

#include "tests/cli_fixture.hpp"

namespace fluoro {
namespace {

using test::CliResult;

class SweepMpi : public test::CliTest {
 protected:
  void SetUp() override {
    CliTest::SetUp();
    write_text("sweep.json", R"({"phantom": {"kind": "femur", "size": 64}, "c_arm": {"pixels": 160, "pixel_mm": 1.9},
      "distances_mm": {"from": 4, "to": 4}, "runs_per_distance": 3, "contours": "automatic"})");
  }
  // The rows of a runs file without its timing columns (seconds, coarse_seconds, fine_seconds),
  // sorted by run.
  std::vector<std::string> rows_without_timings(const std::string& name) const {
    std::istringstream in(slurp(path(name)));
    std::vector<std::string> rows;
    std::string line;
    while (std::getline(in, line)) {
      std::vector<std::string> f;
      std::istringstream s(line);
      std::string field;
      while (std::getline(s, field, ',')) f.push_back(field);
      if (f.size() != 22) {
        ADD_FAILURE() << name << ": malformed line " << line;
        continue;
      }
      f.erase(f.begin() + 14, f.begin() + 17);
      std::string joined;
      for (const auto& x : f) joined += x + ",";
      rows.push_back(joined);
    }
    std::sort(rows.begin(), rows.end());
    return rows;
  }
};

#if FLUORO_HAVE_MPI
// Open MPI refuses to start as root unless told; CI containers run as root.
const std::string kMpirun = std::string("OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 ") + FLUORO_MPIEXEC +
                            " --oversubscribe -n ";

TEST_F(SweepMpi, ThreeRanksWriteTheRowsOfOneProcessAndResume) {
  const std::string sweep = " sweep --config " + path("sweep.json") + " --out ";
  const CliResult one = run(sweep + path("one.csv"));
  ASSERT_EQ(one.code, 0) << one.err;
  const CliResult three = run(sweep + path("three.csv"), kMpirun + "3");
  ASSERT_EQ(three.code, 0) << three.err;
  EXPECT_NE(three.out.find("3 runs, 100.0% success"), std::string::npos) << three.out;
  EXPECT_NE(three.out.find("on 3 MPI ranks"), std::string::npos) << three.out;
  const std::vector<std::string> expected = rows_without_timings("one.csv");
  ASSERT_EQ(expected.size(), 4u);  // header and three runs
  EXPECT_EQ(rows_without_timings("three.csv"), expected);
  // Resume over two ranks: a row cut short (a rank or the job stopped while writing) is redone.
  std::string csv = slurp(path("three.csv"));
  csv.resize(csv.size() - 25);
  write_text("three.csv", csv);
  const CliResult resumed = run(sweep + path("three.csv"), kMpirun + "2");
  ASSERT_EQ(resumed.code, 0) << resumed.err;
  EXPECT_NE(resumed.err.find("2 already in"), std::string::npos) << resumed.err;
  EXPECT_EQ(rows_without_timings("three.csv"), expected);
}
#else
TEST_F(SweepMpi, AProgramWithoutMpiRefusesToRunAsSeveralRanks) {
  const CliResult r = run("sweep --config " + path("sweep.json") + " --out " + path("runs.csv"), "OMPI_COMM_WORLD_SIZE=3");
  expect_bad_input(r, "built without MPI", "runs.csv");
}
#endif

}  // namespace
}  // namespace fluoro
