#include "engine/isolated_read.hpp"

#include <fcntl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <csignal>
#include <cstring>
#include <exception>
#include <stdexcept>

#include "engine/error.hpp"

namespace fluoro {
namespace {

// The answer's first byte says what follows.
constexpr char kValue = 'V';       // the bytes `produce` wrote
constexpr char kInputError = 'E';  // an InputError's message
constexpr char kOtherError = 'X';  // another exception's text

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

// The child's whole life: it never returns. Signals that a crash raises kill it (the handlers the
// parent installed, a fuzzer's or a sanitizer's, would report the library's crash as this
// program's), and it leaves by _exit: the parent's atexit handlers and static destructors are not
// its to run.
[[noreturn]] void run_child(int answer_fd, const std::function<void(const IsolatedWrite&)>& produce) {
  for (int signal : {SIGABRT, SIGSEGV, SIGBUS, SIGFPE, SIGILL, SIGTRAP}) std::signal(signal, SIG_DFL);
  if (const int null = ::open("/dev/null", O_WRONLY | O_CLOEXEC); null >= 0) ::dup2(null, STDERR_FILENO);
  bool written = true;
  const auto write = [&](const void* bytes, size_t size) {
    if (!write_all(answer_fd, bytes, size)) {
      written = false;
      throw std::runtime_error("cannot write the answer (" + std::string(std::strerror(errno)) + ")");
    }
  };
  const auto answer_error = [&](char tag, const char* message) {
    // Back to the start: a value half-written before the exception is dropped.
    if (::ftruncate(answer_fd, 0) != 0 || ::lseek(answer_fd, 0, SEEK_SET) != 0) ::_exit(1);
    if (!write_all(answer_fd, &tag, 1) || !write_all(answer_fd, message, std::strlen(message))) ::_exit(1);
  };
  try {
    write(&kValue, 1);
    produce(write);
  } catch (const InputError& e) {
    answer_error(kInputError, e.what());
  } catch (const std::exception& e) {
    if (!written) ::_exit(1);
    answer_error(kOtherError, e.what());
  } catch (...) {
    answer_error(kOtherError, "unknown exception");
  }
  ::_exit(0);
}

std::string how_it_ended(int status) {
  if (WIFSIGNALED(status)) {
    const char* name = ::strsignal(WTERMSIG(status));
    return "crashed reading it (" + std::string(name ? name : "a signal") + ")";
  }
  if (WIFEXITED(status) && WEXITSTATUS(status) != 0)
    return "stopped reading it (exit status " + std::to_string(WEXITSTATUS(status)) + ")";
  return "gave no answer reading it";
}

}  // namespace

void run_isolated_read(const std::string& path, const std::string& library,
                       const std::function<void(const IsolatedWrite&)>& produce,
                       const std::function<void(std::string_view)>& consume) {
  const Fd answer(::memfd_create("fluoro_isolated_read", MFD_CLOEXEC));
  if (answer.get() < 0) system_error("memfd_create");
  const pid_t child = ::fork();
  if (child < 0) system_error("fork");
  if (child == 0) run_child(answer.get(), produce);

  int status = 0;
  while (::waitpid(child, &status, 0) < 0)
    if (errno != EINTR) system_error("waitpid");
  struct stat info {};
  if (::fstat(answer.get(), &info) != 0) system_error("fstat");
  const size_t size = size_t(info.st_size);
  if (!WIFEXITED(status) || WEXITSTATUS(status) != 0 || size == 0)
    throw_input_error(path, library + " " + how_it_ended(status) + ": a malformed file");

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
    default: throw_input_error(path, library + " gave no answer reading it: a malformed file");
  }
}

}  // namespace fluoro
