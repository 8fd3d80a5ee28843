#pragma once
// Reading through a library that can end the process. Debian's GDCM keeps its assertions, so a
// malformed DICOM file that reaches one aborts the program that reads it: the CI fuzz runs found
// one such file after another, and engine/dicom_file_check.hpp refuses those found, but GDCM has
// hundreds of assertions. A bad file must give one line and exit code 2 (docs/cli.md), never a
// crash, so those reads run in a child process: a crash there is the file's fault, reported as
// such, and the program goes on.
#include <cstddef>
#include <functional>
#include <string>
#include <string_view>

namespace fluoro {

// Where the child writes its answer: raw bytes, appended.
using IsolatedWrite = std::function<void(const void* bytes, size_t size)>;

// Runs `produce` in a forked child process, then `consume` here on every byte it wrote. An
// InputError that `produce` throws is thrown here with the same message, any other exception as a
// std::runtime_error with its text. A child that crashes (a signal: an assertion's abort, a
// segmentation fault) is an InputError naming `path` that says `library` crashed reading it: the
// file's fault. What is not the file's fault is a std::runtime_error, after what the child printed
// is copied to this process's stderr: a child killed from outside (SIGKILL: the out-of-memory
// killer), one that exits non-zero (a sanitizer's report in sanitizer builds, a fuzzer's
// out-of-memory exit, no memory for its answer), a failed fork.
//
// The answer goes through an anonymous in-memory file (memfd), so its size is not limited by a
// pipe and the child never waits for this process; the child's stderr goes to another, so what
// a library prints on its way down stays off the terminal. The fork holds LibraryCallsPaused
// (engine/library_output.hpp): no other thread is then inside a reader's library calls, whose
// locks the child would inherit held. Other locks another thread may hold at the fork (code
// outside the readers that calls ITK, an allocator's in sanitizer builds) could still stop the
// child, and this call would wait for it: `produce` should call the reading library only.
// Must not be called while this thread holds a CapturedLibraryOutput. With SIGCHLD ignored, the
// default action is restored for the call's duration (else the child's status is lost).
void run_isolated_read(const std::string& path, const std::string& library,
                       const std::function<void(const IsolatedWrite&)>& produce,
                       const std::function<void(std::string_view)>& consume);

}  // namespace fluoro
