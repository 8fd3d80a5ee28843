#include "engine/library_output.hpp"

#include <itkObjectFactory.h>
#include <itkOutputWindow.h>
#include <nifti1_io.h>

#include <cstdarg>
#include <iostream>
#include <mutex>
#include <regex>

// ITK bundles libtiff with every symbol prefixed "itk_" and Debian ships no header for it. Its
// default handlers print "TIFFReadDirectory: Warning, ..." to stderr with C stdio; with none set,
// libtiff prints nothing and ITK still sees each failure in the return codes.
extern "C" {
using ItkTiffHandler = void (*)(const char* module, const char* format, va_list arguments);
ItkTiffHandler itk_TIFFSetWarningHandler(ItkTiffHandler handler);
ItkTiffHandler itk_TIFFSetErrorHandler(ItkTiffHandler handler);
}

namespace fluoro {
namespace {

// ITK's warnings (e.g. "is Analyze file and it's deprecated") and debug text go nowhere: the
// reader's own checks say what matters about the file in the one line the user gets.
class SilentOutputWindow : public itk::OutputWindow {
 public:
  using Self = SilentOutputWindow;
  using Pointer = itk::SmartPointer<Self>;
  itkNewMacro(Self);
  void DisplayText(const char*) override {}
};

std::mutex& capture_mutex() {
  static std::mutex m;
  return m;
}

}  // namespace

void quiet_library_output() {
  static std::once_flag once;
  std::call_once(once, [] {
    itk::OutputWindow::SetInstance(SilentOutputWindow::New());
    nifti_set_debug_level(0);  // "** ERROR: nifti_convert_nhdr2nim: bad dim[1]" and the like
    itk_TIFFSetWarningHandler(nullptr);
    itk_TIFFSetErrorHandler(nullptr);
  });
}

CapturedLibraryOutput::CapturedLibraryOutput() {
  quiet_library_output();
  capture_mutex().lock();
  cerr_ = std::cerr.rdbuf(buffer_.rdbuf());
  clog_ = std::clog.rdbuf(buffer_.rdbuf());
}

CapturedLibraryOutput::~CapturedLibraryOutput() {
  std::cerr.rdbuf(cerr_);
  std::clog.rdbuf(clog_);
  capture_mutex().unlock();
}

// In a forked child the lock is released too, by the thread that is the forking one's copy (a
// plain mutex has no owner check: what pthread_atfork handlers do).
LibraryCallsPaused::LibraryCallsPaused() { capture_mutex().lock(); }
LibraryCallsPaused::~LibraryCallsPaused() { capture_mutex().unlock(); }

std::string CapturedLibraryOutput::first_line() const {
  std::istringstream text(buffer_.str());
  std::string line;
  while (std::getline(text, line)) {
    const size_t b = line.find_first_not_of(" \t\r");
    if (b == std::string::npos) continue;
    line = line.substr(b, line.find_last_not_of(" \t\r") - b + 1);
    // VNL prefixes its messages with its source file ("./Modules/.../vnl_svd.hxx: "): not the user's.
    static const std::regex source_prefix(R"(^\S+\.(c|cc|cxx|cpp|h|hxx|txx)(:\s*\d+)?:\s*)");
    return std::regex_replace(line, source_prefix, "");
  }
  return {};
}

}  // namespace fluoro
