// Reads through a library that can end the process run in a child process
// (engine/isolated_read.hpp): what the child answers comes back whole, its InputError and other
// exceptions come back as themselves, its crash (an abort, a segmentation fault) is a one-line
// InputError naming the file, and what is not the file's fault (an exit, a kill, a sanitizer's
// report) an internal error; this process goes on.
#include <gtest/gtest.h>

#include <unistd.h>

#include <chrono>
#include <condition_variable>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <functional>
#include <mutex>
#include <numeric>
#include <stdexcept>
#include <string>
#include <string_view>
#include <thread>
#include <vector>

#include "engine/error.hpp"
#include "engine/isolated_read.hpp"
#include "engine/library_output.hpp"

namespace fluoro {
namespace {

const std::string kPath = "/data/ct.dcm";

// The InputError's message, or "" when `produce` gave none.
std::string input_error_of(const std::function<void(const IsolatedWrite&)>& produce) {
  try {
    run_isolated_read(kPath, "TheLibrary", produce, [](std::string_view) {});
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

TEST(IsolatedRead, TheChildsBytesComeBackWhole) {
  // 48 MiB: more than a pipe holds, so the child must not wait for the parent.
  std::vector<float> values(12u << 20);
  std::iota(values.begin(), values.end(), 0.0f);
  const std::string head = "head";
  std::vector<float> got;
  std::string got_head;
  run_isolated_read(
      kPath, "TheLibrary",
      [&](const IsolatedWrite& write) {
        write(head.data(), head.size());
        write(values.data(), values.size() * sizeof(float));
      },
      [&](std::string_view bytes) {
        ASSERT_EQ(bytes.size(), head.size() + values.size() * sizeof(float));
        got_head = std::string(bytes.substr(0, head.size()));
        got.resize(values.size());
        std::memcpy(got.data(), bytes.data() + head.size(), values.size() * sizeof(float));
      });
  EXPECT_EQ(got_head, head);
  EXPECT_EQ(got, values);
}

TEST(IsolatedRead, AnEmptyAnswerIsAnAnswer) {
  bool consumed = false;
  run_isolated_read(kPath, "TheLibrary", [](const IsolatedWrite&) {},
                    [&](std::string_view bytes) { consumed = bytes.empty(); });
  EXPECT_TRUE(consumed);
}

TEST(IsolatedRead, TheChildsInputErrorComesBackAsItWas) {
  // Written in part before the error, and longer than its message: the part is dropped.
  const std::string message = input_error_of([](const IsolatedWrite& write) {
    const std::string partial(4096, 'v');
    write(partial.data(), partial.size());
    throw_input_error(kPath, "cannot read DICOM header");
  });
  EXPECT_EQ(message, kPath + ": cannot read DICOM header");
}

TEST(IsolatedRead, AnotherExceptionComesBackAsARuntimeError) {
  try {
    run_isolated_read(kPath, "TheLibrary", [](const IsolatedWrite&) { throw std::logic_error("a bug"); },
                      [](std::string_view) {});
    ADD_FAILURE() << "no exception";
  } catch (const InputError& e) {
    ADD_FAILURE() << "an InputError: " << e.what();
  } catch (const std::runtime_error& e) {
    EXPECT_EQ(std::string(e.what()), "a bug");
  }
}

TEST(IsolatedRead, AnAbortIsTheFilesFault) {
  // What the library prints as it goes down stays in the child (its stderr is discarded).
  testing::internal::CaptureStderr();
  const std::string message = input_error_of([](const IsolatedWrite& write) {
    write("partial", 7);
    std::fputs("Assertion `TagField != Tag(0x7fe0,0x0010)' failed.\n", stderr);
    std::abort();
  });
  EXPECT_EQ(testing::internal::GetCapturedStderr(), "");
  EXPECT_EQ(message, kPath + ": TheLibrary crashed reading it (Aborted): a malformed file");
}

TEST(IsolatedRead, ASegmentationFaultIsTheFilesFault) {
  const std::string message = input_error_of([](const IsolatedWrite&) { std::raise(SIGSEGV); });
  EXPECT_EQ(message, kPath + ": TheLibrary crashed reading it (Segmentation fault): a malformed file");
}

// Not the file's fault: the child's exit (its own code on a failed answer, a sanitizer's, a
// fuzzer's out-of-memory exit) and a SIGKILL (the out-of-memory killer) are internal errors.
std::string runtime_error_of(const std::function<void(const IsolatedWrite&)>& produce) {
  try {
    run_isolated_read(kPath, "TheLibrary", produce, [](std::string_view) {});
  } catch (const InputError& e) {
    ADD_FAILURE() << "blamed on the file: " << e.what();
  } catch (const std::runtime_error& e) {
    return e.what();
  }
  return "";
}

TEST(IsolatedRead, AnExitIsNotBlamedOnTheFile) {
  EXPECT_EQ(runtime_error_of([](const IsolatedWrite& write) {
              write("partial", 7);
              ::_exit(3);
            }),
            "reading in a child process: the child ended with exit status 3 reading " + kPath);
}

TEST(IsolatedRead, AKillIsNotBlamedOnTheFile) {
  EXPECT_EQ(runtime_error_of([](const IsolatedWrite&) { std::raise(SIGKILL); }),
            "reading in a child process: the child was killed (out of memory?) reading " + kPath);
}

#if defined(__has_feature)
#if __has_feature(address_sanitizer)
// The sanitizer pass: a memory error in the child is a finding, not a malformed file, and its
// report reaches this process's stderr.
TEST(IsolatedRead, ASanitizerReportIsNotBlamedOnTheFile) {
  testing::internal::CaptureStderr();
  const std::string message = runtime_error_of([](const IsolatedWrite&) {
    std::vector<char> bytes(8);
    volatile size_t past = bytes.size();
    bytes.data()[past] = 1;  // heap-buffer-overflow
  });
  const std::string printed = testing::internal::GetCapturedStderr();
  EXPECT_EQ(message, "reading in a child process: the child met a sanitizer report reading " + kPath);
  EXPECT_NE(printed.find("heap-buffer-overflow"), std::string::npos) << printed;
}
#endif
#endif

TEST(IsolatedRead, AForkWaitsForOtherThreadsLibraryCalls) {
  // Another thread inside a reader's library calls (holding the output capture, as a TIFF frame's
  // read does) while this one forks: the child must not inherit that lock held, or its own
  // capture waits forever (before the fix this test hung).
  std::mutex m;
  std::condition_variable cv;
  bool holding = false;
  std::thread other([&] {
    CapturedLibraryOutput busy;
    {
      std::lock_guard lock(m);
      holding = true;
    }
    cv.notify_one();
    std::this_thread::sleep_for(std::chrono::milliseconds(200));
  });
  {
    std::unique_lock lock(m);
    cv.wait(lock, [&] { return holding; });
  }
  std::string bytes;
  run_isolated_read(
      kPath, "TheLibrary",
      [](const IsolatedWrite& write) {
        CapturedLibraryOutput quiet;
        write("read", 4);
      },
      [&](std::string_view b) { bytes = b; });
  other.join();
  EXPECT_EQ(bytes, "read");
}

TEST(IsolatedRead, ThisProcessGoesOnAfterAChildDies) {
  for (int n = 0; n < 3; ++n) {
    EXPECT_NE(input_error_of([](const IsolatedWrite&) { std::abort(); }), "");
    std::string bytes;
    run_isolated_read(kPath, "TheLibrary", [](const IsolatedWrite& write) { write("ok", 2); },
                      [&](std::string_view b) { bytes = b; });
    EXPECT_EQ(bytes, "ok");
  }
}

}  // namespace
}  // namespace fluoro
