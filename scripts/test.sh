#!/usr/bin/env bash
# The README's test command: set up, run the whole suite, then the suite again under
# AddressSanitizer + UndefinedBehaviorSanitizer. `--quick` skips the sanitizer pass.
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
fi
