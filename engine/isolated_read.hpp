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

// Runs `produce` in a forked child process (its stderr discarded, so what the library prints on
// the way down stays off the terminal), then `consume` here on every byte it wrote. An InputError
// that `produce` throws is thrown here with the same message, any other exception as a
// std::runtime_error with its text. When the child dies instead (a signal: an assertion's abort, a
// segmentation fault) or exits without an answer, an InputError names `path` and says that
// `library` crashed reading it. A failed fork or answer buffer is a std::runtime_error (not the
// file's fault).
//
// The answer goes through an anonymous in-memory file (memfd), so its size is not limited by a
// pipe and the child never waits for this process. The child is a fork of a possibly
// multi-threaded process: `produce` must not need a lock that another thread may hold (reading a
// file with ITK and GDCM takes none that outlives a call; ITK's thread pool re-creates its threads
// after a fork).
void run_isolated_read(const std::string& path, const std::string& library,
                       const std::function<void(const IsolatedWrite&)>& produce,
                       const std::function<void(std::string_view)>& consume);

}  // namespace fluoro
