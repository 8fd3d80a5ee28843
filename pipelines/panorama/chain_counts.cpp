#include "pipelines/panorama/chain_counts.hpp"

#include <algorithm>
#include <limits>

namespace fluoro {

std::optional<ChainCounts> settle_chain_counts(const std::vector<std::vector<CountCandidate>>& pairs, long residue,
                                               long modulus) {
  // A run is a few pairs with a dozen correlating candidates each: enumeration is cheap; a run
  // long enough to make it expensive is not decided this way.
  double combinations = 1;
  for (const auto& p : pairs) combinations *= double(p.size());
  if (pairs.empty() || combinations == 0 || combinations > 2e5 || modulus <= 0) return std::nullopt;
  const double none = -std::numeric_limits<double>::infinity();
  ChainCounts best;
  double best_score = none;
  std::vector<std::pair<std::vector<size_t>, double>> fitting;
  std::vector<size_t> at(pairs.size(), 0);
  for (;;) {
    long sum = 0;
    double score = 0;
    for (size_t k = 0; k < pairs.size(); ++k) sum += pairs[k][at[k]].K, score += pairs[k][at[k]].score;
    if ((((sum - residue) % modulus) + modulus) % modulus == 0) {
      fitting.emplace_back(at, score);
      if (score > best_score) best_score = score, best.chosen = at;
    }
    size_t k = 0;
    while (k < pairs.size() && ++at[k] == pairs[k].size()) at[k++] = 0;
    if (k == pairs.size()) break;
  }
  if (best_score == none) return std::nullopt;
  // Combinations that differ from the best in some pair's count (candidates of one pair have
  // distinct counts, so a different index is a different count).
  double second = none;
  for (const auto& [c, score] : fitting)
    if (c != best.chosen) second = std::max(second, score);
  best.lead = second == none ? std::numeric_limits<double>::infinity() : best_score - second;
  return best;
}

}  // namespace fluoro
