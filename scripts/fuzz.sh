#!/usr/bin/env bash
# Builds the libFuzzer targets (the "fuzz" preset: clang, ASan + UBSan, build-fuzz/) and runs each
# for SECONDS, two at a time, from the committed seed corpus (fuzz/corpus/<target>/) plus what
# earlier runs found (build-fuzz/corpus/<target>/). A crash, a sanitizer report, 20 s on one input
# or 2 GiB of memory stops that target; its input is kept in build-fuzz/findings/<target>/ and the
# script exits 1. docs/fuzzing.md explains the targets and how to turn a finding into a test.
# Usage: scripts/fuzz.sh [SECONDS] [TARGET...]   (default 30 s; every target fuzz_all builds;
#        name targets to run only those, e.g. volume_nii camera, or sweep_config)
set -euo pipefail
cd "$(dirname "$0")/.."
seconds=${1:-30}
shift || true

cmake --preset fuzz >/dev/null
cmake --build --preset fuzz  # fuzz_all: every target but sweep_config (fuzz/CMakeLists.txt says why)

if (($#)); then
  targets=("$@")
  for t in "${targets[@]}"; do cmake --build build-fuzz --target "fuzz_$t"; done
else
  targets=()
  for dir in fuzz/corpus/*/; do
    t=$(basename "$dir")
    [ -x "build-fuzz/bin/fuzz_$t" ] && targets+=("$t")
  done
fi

run_one() {  # target seconds
  local t=$1 s=$2
  local work=build-fuzz/corpus/$t findings=build-fuzz/findings/$t log=build-fuzz/logs/$t.log
  mkdir -p "$work" "$findings" build-fuzz/logs
  # ITK's factories and singletons live until exit: leak checks would report them, not the reader.
  if ASAN_OPTIONS=detect_leaks=0:abort_on_error=1 UBSAN_OPTIONS=print_stacktrace=1 \
    "build-fuzz/bin/fuzz_$t" "$work" "fuzz/corpus/$t" -max_total_time="$s" -rss_limit_mb=2048 -timeout=20 \
    -max_len=65536 -print_final_stats=1 -artifact_prefix="$findings/" >"$log" 2>&1; then
    echo "$t: $(grep -o 'stat::number_of_executed_units: *[0-9]*' "$log" | grep -o '[0-9]*$') runs, no finding"
  else
    echo "$t: FINDING (see $log; input in $findings/)"
    return 1
  fi
}
export -f run_one
printf '%s\n' "${targets[@]}" | xargs -P 2 -I{} bash -c "run_one {} $seconds" || {
  echo "fuzz: findings (see above)"
  exit 1
}
