#pragma once
// The libraries the readers use (ITK, its MetaIO, NIfTI and VNL, libtiff) print their own warnings
// and errors to stderr, some before throwing, some instead of failing. A bad input must give one
// line (docs/cli.md), so the readers keep those messages from the terminal and turn them into the
// InputError they owe the user.
#include <sstream>
#include <string>

namespace fluoro {

// Once per process: ITK's output window (itkWarningMacro and friends) drops its text and the
// NIfTI library and ITK's libtiff stop printing. Idempotent and thread-safe; every reader calls it.
void quiet_library_output();

// While alive, std::cerr and std::clog (where MetaIO and VNL print) go to a buffer. Guards are
// serialised by a process-wide mutex, as the streams are global: a reader holds one only around
// the library calls. Output another thread writes to std::cerr meanwhile lands in the buffer.
class CapturedLibraryOutput {
 public:
  CapturedLibraryOutput();
  ~CapturedLibraryOutput();
  CapturedLibraryOutput(const CapturedLibraryOutput&) = delete;
  CapturedLibraryOutput& operator=(const CapturedLibraryOutput&) = delete;
  // The first non-empty line the libraries printed, or "" when they were silent.
  std::string first_line() const;

 private:
  std::ostringstream buffer_;
  std::streambuf* cerr_;
  std::streambuf* clog_;
};

// While alive, holds the lock every CapturedLibraryOutput takes, so no other thread is inside a
// reader's library calls: a fork made meanwhile (engine/isolated_read.hpp) gives the child no
// library lock held by a thread it does not have (a TIFF frame read on one thread while a DICOM
// frame forked on another hung the child for good). Not while this thread holds a capture.
class LibraryCallsPaused {
 public:
  LibraryCallsPaused();
  ~LibraryCallsPaused();
  LibraryCallsPaused(const LibraryCallsPaused&) = delete;
  LibraryCallsPaused& operator=(const LibraryCallsPaused&) = delete;
};

}  // namespace fluoro
