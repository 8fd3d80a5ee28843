#!/usr/bin/env bash
# The README's test command: set up, run the whole suite, then the suite again under
# AddressSanitizer + UndefinedBehaviorSanitizer (clang, which also builds the libFuzzer targets),
# then every fuzz target for FLUORO_FUZZ_SECONDS (default 5) each. `--quick` skips the sanitizer
# pass and the fuzzing.
# Each phase prints its elapsed time, so a slow CI run shows where its time went.
set -euo pipefail
cd "$(dirname "$0")/.."
start=$SECONDS
phase() { echo "test.sh: $1 done at +$((SECONDS - start)) s"; }
scripts/setup.sh release
phase "release build"
ctest --preset release -j2
phase "release tests"
if [ "${1:-}" != "--quick" ]; then
  scripts/setup.sh asan
  phase "sanitizer build"
  ctest --preset asan -j2
  phase "sanitizer tests"
  # Every libFuzzer target, built with the sanitizer pass, for a short run from its committed seed
  # corpus; a finding fails the command (docs/fuzzing.md).
  scripts/fuzz.sh --built build-asan "${FLUORO_FUZZ_SECONDS:-5}"
  phase "fuzzing"
fi
