#!/usr/bin/env bash
# Whole-process `fluoro register` with and without `--prepared` (fluoro prepare), alternating, on
# the shared pelvis CT (3 mm; views rendered by `fluoro drr` at a known pose, a start 5.4 mm and 3
# degrees off) and on the 256^3 femur phantom at 1 mm (views and start from `fluoro demo --size
# 256`). Prints per run: wall s, user s, sys s, max RSS KB (GNU time), and the load average, then
# `fluoro prepare`'s own timings. Results in docs/benchmarks.md ("Prepare once, register many").
# Usage: bench/prepared_ct.sh [RUNS=3] [WORK_DIR=a temporary]
set -euo pipefail
cd "$(dirname "$0")/.."
runs=${1:-3}
fluoro=$(pwd)/build/bin/fluoro
pelvis=$(cd .. && pwd)/shared/datasets/pelvis-ct/ct.nii.gz
work=${2:-$(mktemp -d)}
mkdir -p "$work" && cd "$work"

$fluoro -q phantom --kind femur --size 256 --out femur256.nii.gz
$fluoro -q demo --size 256 --out-dir demo256 >/dev/null
# The pelvis CT's centre at the isocentre; the start turned 3 degrees about z and shifted (4, -3, 2) mm.
python3 - <<'PY'
import json, math
c = [-3.544, -161.319, 260.8]  # centre of the shared pelvis CT (fluoro info)
json.dump({"T_world_ct": [[1, 0, 0, -c[0]], [0, 1, 0, -c[1]], [0, 0, 1, -c[2]], [0, 0, 0, 1]]}, open("pelvis_truth.json", "w"))
a = math.radians(3); R = [[math.cos(a), -math.sin(a), 0], [math.sin(a), math.cos(a), 0], [0, 0, 1]]; d = [4.0, -3.0, 2.0]
M = [[R[i][0], R[i][1], R[i][2], -sum(R[i][k] * c[k] for k in range(3)) + d[i]] for i in range(3)] + [[0, 0, 0, 1]]
json.dump({"T_world_ct": M}, open("pelvis_start.json", "w"))
PY
pv="--init pelvis_start.json"; fv="--init demo256/start_pose.json"
for v in ap oblique60 lateral_tilted; do
  $fluoro -q drr --ct "$pelvis" --camera demo256/${v}_camera.json --pose pelvis_truth.json --out pelvis_${v}.png
  pv="$pv --view pelvis_${v}.png:demo256/${v}_camera.json"
  fv="$fv --view demo256/${v}_xray.png:demo256/${v}_camera.json"
done
t() { /usr/bin/time -f "%e %U %S %M" -o time.txt "$@" >/dev/null 2>&1; cat time.txt; }
echo "prepare pelvis: $(t $fluoro prepare --ct "$pelvis" --out pelvis.fluoroprep)"
echo "prepare femur:  $(t $fluoro prepare --ct femur256.nii.gz --out femur256.fluoroprep)"
ls -l pelvis.fluoroprep femur256.fluoroprep
for i in $(seq 1 "$runs"); do
  echo "pelvis plain    $(t $fluoro register --ct "$pelvis" $pv --out p_plain.json)  load $(cut -d' ' -f1-3 /proc/loadavg)"
  echo "pelvis prepared $(t $fluoro register --ct "$pelvis" $pv --prepared pelvis.fluoroprep --out p_prep.json)"
  echo "femur plain     $(t $fluoro register --ct femur256.nii.gz $fv --out f_plain.json)"
  echo "femur prepared  $(t $fluoro register --ct femur256.nii.gz $fv --prepared femur256.fluoroprep --out f_prep.json)"
done
python3 - <<'PY'
import json
for a, b in [("p_plain.json", "p_prep.json"), ("f_plain.json", "f_prep.json")]:
    x, y = json.load(open(a)), json.load(open(b))
    print(a[0], "same pose:", x["T_world_ct"] == y["T_world_ct"], "preparation_seconds", x["preparation_seconds"], "->",
          y["preparation_seconds"], "prepared_load_seconds", y["prepared_load_seconds"], "sha256_seconds",
          x["provenance"]["sha256_seconds"], "->", y["provenance"]["sha256_seconds"])
PY
