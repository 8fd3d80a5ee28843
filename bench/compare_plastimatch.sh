#!/usr/bin/env bash
# Times a whole `fluoro drr` run (load, render, write) against `plastimatch drr -i exact` on the
# same CT and the same geometry, side by side, interleaved, and prints the medians and their ratio.
# plastimatch is a benchmark-only dependency (Debian package `plastimatch`), installed if missing.
# Usage: bench/compare_plastimatch.sh [CT_SIZE=256] [DETECTOR_PIXELS=512] [RUNS=7] [FORMAT=mha|nii]
# (mha: zlib-compressed MetaImage, the phantom's default; nii: uncompressed NIfTI)
# FLUORO_BEFORE=/path/to/an/older/fluoro also times that binary in the same interleaved runs, so
# that a change is measured before and after on one machine at one time.
set -euo pipefail
cd "$(dirname "$0")/.."
size=${1:-256}
pixels=${2:-512}
runs=${3:-7}
format=${4:-mha}
fluoro=build/bin/fluoro
before=${FLUORO_BEFORE:-}
[ -x "$fluoro" ] || scripts/setup.sh release
if ! command -v plastimatch >/dev/null; then
  sudo_cmd=""; [ "$(id -u)" -ne 0 ] && sudo_cmd="sudo"
  $sudo_cmd apt-get install -y -qq --no-install-recommends plastimatch >/dev/null
fi
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

# plastimatch ignores direction cosines: the phantom has the identity direction.
$fluoro phantom --kind pelvis --size "$size" --out "$work/ct.$format" >/dev/null

# plastimatch's default geometry (SAD 1000, SID 1500, gantry angle 0) with a 400 mm detector.
# Its camera: source on +x at 1000 mm looking at the isocentre; the same camera for fluoro, from
# the extrinsic and intrinsic matrices plastimatch writes beside its image.
plastimatch drr -i exact -t pfm -r "$pixels $pixels" -z "400 400" -O "$work/pm/img" "$work/ct.$format" >/dev/null
f=$(awk -v p="$pixels" 'BEGIN { print 1500 / (400 / p) }')
c=$(awk -v p="$pixels" 'BEGIN { print (p - 1) / 2 }')
cat >"$work/cam.json" <<JSON
{ "width": $pixels, "height": $pixels,
  "K": [[$f, 0, $c], [0, $f, $c], [0, 0, 1]],
  "R": [[0, 1, 0], [0, 0, -1], [-1, 0, 0]],
  "t": [0, 0, 1000] }
JSON

now() { date +%s.%N; }
median() { sort -g | awk '{ a[NR] = $1 } END { print (NR % 2) ? a[(NR + 1) / 2] : (a[NR / 2] + a[NR / 2 + 1]) / 2 }'; }
: >"$work/t_fluoro"
: >"$work/t_pm"
: >"$work/t_before"
for _ in $(seq "$runs"); do
  t0=$(now)
  plastimatch drr -i exact -t pfm -r "$pixels $pixels" -z "400 400" -O "$work/pm/img" "$work/ct.$format" >/dev/null
  t1=$(now)
  $fluoro drr --ct "$work/ct.$format" --camera "$work/cam.json" --out "$work/fluoro.tif" --step 1 --quiet
  t2=$(now)
  awk -v a="$t0" -v b="$t1" 'BEGIN { print b - a }' >>"$work/t_pm"
  awk -v a="$t1" -v b="$t2" 'BEGIN { print b - a }' >>"$work/t_fluoro"
  if [ -n "$before" ]; then
    t3=$(now)
    "$before" drr --ct "$work/ct.$format" --camera "$work/cam.json" --out "$work/before.tif" --step 1 --quiet
    t4=$(now)
    awk -v a="$t3" -v b="$t4" 'BEGIN { print b - a }' >>"$work/t_before"
  fi
done
m_pm=$(median <"$work/t_pm")
m_fl=$(median <"$work/t_fluoro")
echo "CT ${size}^3 pelvis phantom (.$format), ${pixels}^2 DRR, median of $runs interleaved runs (whole command: load, render, write)"
printf "  plastimatch drr -i exact: %.3f s\n" "$m_pm"
printf "  fluoro drr (cpu, 1 mm):   %.3f s\n" "$m_fl"
printf "  ratio fluoro/plastimatch: %.2f\n" "$(awk -v a="$m_fl" -v b="$m_pm" 'BEGIN { print a / b }')"
if [ -n "$before" ]; then
  m_before=$(median <"$work/t_before")
  printf "  %s: %.3f s (ratio %.2f; this build %.2fx faster)\n" "$before" "$m_before" \
    "$(awk -v a="$m_before" -v b="$m_pm" 'BEGIN { print a / b }')" "$(awk -v a="$m_before" -v b="$m_fl" 'BEGIN { print a / b }')"
fi
