#include "engine/thread_limit.hpp"

#include <itkMultiThreaderBase.h>
#include <tbb/global_control.h>

#include <cstdlib>
#include <memory>
#include <opencv2/core/utility.hpp>
#include <string>

namespace fluoro {

void limit_threads(int n) {
  // global_control holds the limit only while the object lives: keep it for the whole process.
  static std::unique_ptr<tbb::global_control> control;
  control = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism, size_t(n));
  cv::setNumThreads(n);
  itk::MultiThreaderBase::SetGlobalMaximumNumberOfThreads(itk::ThreadIdType(n));
  itk::MultiThreaderBase::SetGlobalDefaultNumberOfThreads(itk::ThreadIdType(n));
  // Mesa's llvmpipe/lavapipe threads, read from the environment when the driver loads.
  ::setenv("LP_NUM_THREADS", std::to_string(n).c_str(), 1);
}

int thread_limit() {
  return int(tbb::global_control::active_value(tbb::global_control::max_allowed_parallelism));
}

}  // namespace fluoro
