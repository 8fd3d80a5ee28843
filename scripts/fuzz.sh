#!/usr/bin/env bash
# Runs each libFuzzer target (fuzz/, docs/fuzzing.md) for SECONDS, two at a time. A crash, a
# sanitizer report, 20 s on one input or 2 GiB of memory stops that target; its input is kept in
# <build>/findings/<target>/, the end of its log is printed and the script exits 1.
#
# Usage: scripts/fuzz.sh [SECONDS] [TARGET...]
#   Builds the targets first (the "fuzz" preset: clang, ASan + UBSan, build-fuzz/, only the readers)
#   and runs them from the committed seed corpus (fuzz/corpus/<target>/) plus what earlier runs
#   found (build-fuzz/corpus/<target>/). Default 30 s; every target fuzz_all builds, or the named
#   ones, e.g. volume_nii camera, or sweep_config (built only when named).
# Usage: scripts/fuzz.sh --built BUILD_DIR [SECONDS] [TARGET...]
#   Builds nothing: runs the targets already in BUILD_DIR/bin (the asan preset builds every one
#   of them with the whole project: scripts/test.sh runs them this way, CI's short fuzz run), from
#   the committed seed corpus only (what a run learns goes to a fresh BUILD_DIR/fuzz-run/, so each
#   run starts alike), with a fixed seed (FLUORO_FUZZ_SEED, default 1): CI's short run tries the same
#   inputs each time, so it fails on a change, not on a lucky draw. Every target of fuzz/corpus/
#   must have been built.
set -euo pipefail
cd "$(dirname "$0")/.."
built=""
seed_option=""  # libFuzzer draws a seed per run
if [ "${1:-}" = "--built" ]; then
  built=${2:?"--built needs a build directory"}
  shift 2
fi
seconds=${1:-30}
shift || true

if [ -z "$built" ]; then
  build=build-fuzz
  cmake --preset fuzz >/dev/null
  cmake --build --preset fuzz  # fuzz_all: every target but sweep_config (fuzz/CMakeLists.txt says why)
  learned=$build/corpus
else
  build=$built
  learned=$build/fuzz-run/corpus
  rm -rf "$build/fuzz-run"
  seed_option="-seed=${FLUORO_FUZZ_SEED:-1}"
fi

if (($#)); then
  targets=("$@")
  if [ -z "$built" ]; then
    for t in "${targets[@]}"; do cmake --build "$build" --target "fuzz_$t"; done
  fi
else
  targets=()
  for dir in fuzz/corpus/*/; do
    t=$(basename "$dir")
    if [ -x "$build/bin/fuzz_$t" ]; then
      targets+=("$t")
    elif [ -n "$built" ]; then
      echo "fuzz: $build/bin/fuzz_$t was not built (configure with FLUORO_FUZZ=ON: the asan preset)" >&2
      exit 1
    fi
  done
fi

run_one() {  # build learned target seconds [seed option]
  local build=$1 learned=$2 t=$3 s=$4 seed=${5:-}
  local work=$learned/$t findings=$build/findings/$t log=$build/logs/$t.log
  mkdir -p "$work" "$findings" "$build/logs"
  # ITK's factories and singletons live until exit: leak checks would report them, not the reader.
  if ASAN_OPTIONS=detect_leaks=0:abort_on_error=1 UBSAN_OPTIONS=print_stacktrace=1 \
    "$build/bin/fuzz_$t" "$work" "fuzz/corpus/$t" -max_total_time="$s" -rss_limit_mb=2048 -timeout=20 \
    -max_len=65536 -print_final_stats=1 -artifact_prefix="$findings/" $seed >"$log" 2>&1; then
    echo "$t: $(grep -o 'stat::number_of_executed_units: *[0-9]*' "$log" | grep -o '[0-9]*$') runs, no finding"
  else
    echo "$t: FINDING (input in $findings/, log $log; its end:)"
    tail -n 30 "$log" | sed 's/^/    /'
    return 1
  fi
}
export -f run_one
printf '%s\n' "${targets[@]}" | xargs -P 2 -I{} bash -c "run_one '$build' '$learned' {} $seconds $seed_option" || {
  echo "fuzz: findings (see above)"
  exit 1
}
