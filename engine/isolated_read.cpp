#include "engine/isolated_read.hpp"

#include <fcntl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <csignal>
#include <cstdio>
#include <cstring>
#include <exception>
#include <stdexcept>

#include "engine/error.hpp"
#include "engine/library_output.hpp"

#if defined(__has_feature)
#if __has_feature(address_sanitizer) || __has_feature(undefined_behavior_sanitizer)
#define FLUORO_SANITIZED 1
#endif
#endif
#if defined(__SANITIZE_ADDRESS__)
#define FLUORO_SANITIZED 1
#endif
#ifdef FLUORO_SANITIZED
#include <sanitizer/common_interface_defs.h>
#endif

namespace fluoro {
namespace {

// The answer's first byte says what follows.
constexpr char kValue = 'V';       // the bytes `produce` wrote
constexpr char kInputError = 'E';  // an InputError's message
constexpr char kOtherError = 'X';  // another exception's text

// The child's own exit codes for what is not the file's fault.
constexpr int kAnswerNotWritten = 70;  // the in-memory file refused the answer (no memory)
constexpr int kSanitizerReport = 71;   // a sanitizer reported an error (sanitizer builds)

[[noreturn]] void system_error(const std::string& what) {
  throw std::runtime_error("reading in a child process: " + what + " failed (" + std::strerror(errno) + ")");
}

// Owns a file descriptor.
class Fd {
 public:
  explicit Fd(int fd) : fd_(fd) {}
  ~Fd() {
    if (fd_ >= 0) ::close(fd_);
  }
  Fd(const Fd&) = delete;
  Fd& operator=(const Fd&) = delete;
  int get() const { return fd_; }

 private:
  int fd_;
};

// All of the bytes, or false.
bool write_all(int fd, const void* bytes, size_t size) {
  const char* at = static_cast<const char*>(bytes);
  while (size > 0) {
    const ssize_t n = ::write(fd, at, size);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) return false;
    at += n;
    size -= size_t(n);
  }
  return true;
}

// A crash must kill the child, so the handlers the parent installed (a fuzzer's, a sanitizer's
// SEGV handler) go; a sanitizer's report, though, is this program's bug or the library's, not the
// file's: the child then leaves with its own code, which the parent does not blame on the file.
void prepare_child_signals() {
  for (int signal : {SIGABRT, SIGSEGV, SIGBUS, SIGFPE, SIGILL, SIGTRAP}) std::signal(signal, SIG_DFL);
#ifdef FLUORO_SANITIZED
  __sanitizer_set_death_callback([] { ::_exit(kSanitizerReport); });
#endif
}

// The child's whole life: it never returns, and leaves by _exit (the parent's atexit handlers and
// static destructors are not its to run). What it prints goes to `stderr_fd`, not the terminal.
[[noreturn]] void run_child(int answer_fd, int stderr_fd, const std::function<void(const IsolatedWrite&)>& produce) {
  prepare_child_signals();
  if (::dup2(stderr_fd, STDERR_FILENO) < 0) ::close(STDERR_FILENO);
  const auto write = [&](const void* bytes, size_t size) {
    if (!write_all(answer_fd, bytes, size)) ::_exit(kAnswerNotWritten);
  };
  const auto answer_error = [&](char tag, const char* message) {
    // Back to the start: a value half-written before the exception is dropped.
    if (::ftruncate(answer_fd, 0) != 0 || ::lseek(answer_fd, 0, SEEK_SET) != 0) ::_exit(kAnswerNotWritten);
    write(&tag, 1);
    write(message, std::strlen(message));
  };
  try {
    write(&kValue, 1);
    produce(write);
  } catch (const InputError& e) {
    answer_error(kInputError, e.what());
  } catch (const std::exception& e) {
    answer_error(kOtherError, e.what());
  } catch (...) {
    answer_error(kOtherError, "unknown exception");
  }
  ::_exit(0);
}

// The bytes of an in-memory file, from its start.
std::string contents(int fd) {
  struct stat info {};
  if (::fstat(fd, &info) != 0 || info.st_size <= 0) return {};
  std::string text(size_t(info.st_size), '\0');
  const ssize_t n = ::pread(fd, text.data(), text.size(), 0);
  text.resize(n > 0 ? size_t(n) : 0);
  return text;
}

// A child that ended abnormally for a reason that is not the file's: what it printed goes to this
// program's stderr (a sanitizer's report, a fuzzer's), then an internal error.
[[noreturn]] void child_failed(int stderr_fd, const std::string& how) {
  const std::string printed = contents(stderr_fd);
  if (!printed.empty()) std::fwrite(printed.data(), 1, printed.size(), stderr);
  throw std::runtime_error("reading in a child process: the child " + how);
}

// With SIGCHLD ignored, children are reaped unasked and waitpid cannot see how one ended: while
// alive, SIGCHLD has its default action (ignore, but keep the child's status) if it was ignored.
class ChildStatusKept {
 public:
  ChildStatusKept() {
    struct sigaction now {};
    if (::sigaction(SIGCHLD, nullptr, &now) == 0 && now.sa_handler == SIG_IGN) {
      struct sigaction dfl {};
      dfl.sa_handler = SIG_DFL;
      sigemptyset(&dfl.sa_mask);
      restore_ = ::sigaction(SIGCHLD, &dfl, &before_) == 0;
    }
  }
  ~ChildStatusKept() {
    if (restore_) ::sigaction(SIGCHLD, &before_, nullptr);
  }
  ChildStatusKept(const ChildStatusKept&) = delete;
  ChildStatusKept& operator=(const ChildStatusKept&) = delete;

 private:
  struct sigaction before_ {};
  bool restore_ = false;
};

}  // namespace

void run_isolated_read(const std::string& path, const std::string& library,
                       const std::function<void(const IsolatedWrite&)>& produce,
                       const std::function<void(std::string_view)>& consume) {
  const Fd answer(::memfd_create("fluoro_isolated_read", MFD_CLOEXEC));
  const Fd printed(::memfd_create("fluoro_isolated_read_stderr", MFD_CLOEXEC));
  if (answer.get() < 0 || printed.get() < 0) system_error("memfd_create");
  const ChildStatusKept keep_status;
  pid_t child = 0;
  {
    // No other thread is inside a reader's library calls while the process forks, and the child
    // gets no copy of output this process has not written yet.
    const LibraryCallsPaused paused;
    std::fflush(nullptr);
    child = ::fork();
  }
  if (child < 0) system_error("fork");
  if (child == 0) run_child(answer.get(), printed.get(), produce);

  int status = 0;
  while (::waitpid(child, &status, 0) < 0)
    if (errno != EINTR) system_error("waitpid");
  if (WIFSIGNALED(status)) {
    // Killed from outside (the kernel's out-of-memory killer, a user): not the file's fault.
    if (WTERMSIG(status) == SIGKILL) child_failed(printed.get(), "was killed (out of memory?) reading " + path);
    const char* name = ::strsignal(WTERMSIG(status));
    throw_input_error(path, library + " crashed reading it (" + std::string(name ? name : "a signal") +
                                "): a malformed file");
  }
  if (!WIFEXITED(status) || WEXITSTATUS(status) != 0) {
    const int code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
    child_failed(printed.get(), code == kSanitizerReport   ? "met a sanitizer report reading " + path
                                : code == kAnswerNotWritten ? "could not write its answer reading " + path
                                                            : "ended with exit status " + std::to_string(code) +
                                                                  " reading " + path);
  }

  struct stat info {};
  if (::fstat(answer.get(), &info) != 0) system_error("fstat");
  const size_t size = size_t(info.st_size);
  if (size == 0) child_failed(printed.get(), "gave no answer reading " + path);
  void* mapped = ::mmap(nullptr, size, PROT_READ, MAP_PRIVATE, answer.get(), 0);
  if (mapped == MAP_FAILED) system_error("mmap");
  struct Unmap {
    void* at;
    size_t size;
    ~Unmap() { ::munmap(at, size); }
  } unmap{mapped, size};
  const std::string_view bytes(static_cast<const char*>(mapped), size);
  const std::string_view rest = bytes.substr(1);
  switch (bytes[0]) {
    case kValue: consume(rest); return;
    case kInputError: throw InputError(std::string(rest));
    case kOtherError: throw std::runtime_error(std::string(rest));
    default: child_failed(printed.get(), "gave an answer of unknown kind reading " + path);
  }
}

}  // namespace fluoro
