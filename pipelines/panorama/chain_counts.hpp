#pragma once
// The graduation counts of a run of consecutive pairs decided together. A frame that shows no
// 50 mm mark (a clamp over it, or a field that falls between two of them) leaves its pairs fixed
// only by the 10 mm marks: each count is decided by the anatomy alone, and may be ambiguous. Yet
// when the frames on both sides of the run show their 50 mm marks, the counts' sum along the run
// is fixed modulo 10 graduations: an error of 10 mm in one pair would need the opposite error in
// another. Scoring the combinations that respect that sum uses both pairs' evidence at once.
#include <optional>
#include <vector>

namespace fluoro {

// One graduation-aligned candidate of a pair: its count K (local index in the later frame + K =
// local index in the earlier one) and its score (higher is better).
struct CountCandidate {
  long K = 0;
  double score = 0;
};

struct ChainCounts {
  std::vector<size_t> chosen;  // per pair, the index of its candidate in the best combination
  double lead = 0;             // best combination's score minus the best one that differs
};

// Among the combinations of one candidate per pair whose counts sum to `residue` modulo
// `modulus`, the one with the highest total score, and its lead over the best combination that
// differs in any pair (infinite when no other is possible). nullopt when no combination fits or
// the run would be too large to enumerate.
std::optional<ChainCounts> settle_chain_counts(const std::vector<std::vector<CountCandidate>>& pairs, long residue,
                                               long modulus);

}  // namespace fluoro
