#include "kernels/cpu/simd_targets.hpp"

#include <algorithm>
#include <cctype>
#include <cstdint>

#include <hwy/targets.h>

#include "engine/error.hpp"
#include "kernels/cpu/ray_march.hpp"

namespace fluoro::cpu {
namespace {

std::string lower(std::string_view s) {
  std::string out(s);
  for (char& c : out) c = char(std::tolower(static_cast<unsigned char>(c)));
  return out;
}

// Highway's target bits, best first (a lower bit is a better set): those it would run now...
std::vector<int64_t> targets_best_first() {
  std::vector<int64_t> t = hwy::SupportedAndGeneratedTargets();
  std::sort(t.begin(), t.end());
  return t;
}

// ...and those it offered before any cap (limit_simd is the only cap, and reads this first).
const std::vector<int64_t>& offered_targets() {
  static const std::vector<int64_t> offered = targets_best_first();
  return offered;
}

}  // namespace

std::vector<std::string> simd_targets() {
  std::vector<std::string> names;
  for (const int64_t t : offered_targets()) names.emplace_back(hwy::TargetName(t));
  return names;
}

// Asked of the dispatcher itself, not of the list of supported sets: Highway 1.0's
// SupportedTargets() re-chooses from every set the CPU has before applying the cap, so the two can
// disagree after a call to it (limit_simd mends that).
std::string simd_target() { return march_target(); }

void limit_simd(std::string_view name) {
  std::string choices;
  for (const int64_t t : offered_targets()) {
    if (lower(hwy::TargetName(t)) == lower(name)) {
      // Every better set is a lower bit than this one.
      hwy::DisableTargets(t - 1);
      // DisableTargets leaves the dispatch to choose again at its next call, which it does from
      // SupportedTargets(); but a call of that made elsewhere first re-chooses from every set the
      // CPU has (Highway 1.0), so choose now, from the capped sets.
      hwy::GetChosenTarget().Update(hwy::SupportedTargets());
      if (lower(simd_target()) != lower(name))
        throw InputError("SIMD set " + std::string(name) + " could not be selected (the kernels run " + simd_target() + ")");
      return;
    }
    choices += (choices.empty() ? "" : ", ") + std::string(hwy::TargetName(t));
  }
  throw InputError("unknown SIMD set '" + std::string(name) + "' (this build and CPU offer: " + choices + ")");
}

}  // namespace fluoro::cpu
