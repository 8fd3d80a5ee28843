#!/usr/bin/env bash
# The README's test command: set up, run the whole suite, then the suite again under
# AddressSanitizer + UndefinedBehaviorSanitizer. `--quick` skips the sanitizer pass.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/setup.sh release
ctest --preset release -j2
if [ "${1:-}" != "--quick" ]; then
  scripts/setup.sh asan
  ctest --preset asan -j2
fi
