#!/usr/bin/env bash
# The px4 profile's own error: flies MISSION N times on PX4 SITL (sitl/px4-fly.sh, physical
# battery), the k-th armed k seconds after PX4 and the battery process are up (FLY_DELAY_S 0 ..
# N-1: PX4 SITL flies differently when armed at another moment, docs/px4-sitl.md), each checked
# with its mission within 5% and every leg measured (sitl/check_report.py; a flight outside that
# is flown once more), then combines them (`emplan report DIR... --json`) and checks the means
# over the N flights (sitl/check_combined.py): each leg within 6% of its price, the mission
# within 2%, the take-off and the landing within 10% (docs/px4-sitl.md).
# Usage: sitl/px4-means.sh N [EMPLAN_BINARY] [MISSION] [WORK_DIR]
set -euo pipefail
cd "$(dirname "$0")/.."
n=${1:?usage: sitl/px4-means.sh N [EMPLAN_BINARY] [MISSION] [WORK_DIR]}
emplan=${2:-target/release/emplan}
mission=${3:-missions/paper-sample-8wp.toml}
work=${4:-$(mktemp -d -t emplan-px4-means.XXXXXX)}
dirs=()
for ((k = 0; k < n; k++)); do
  for try in 1 2; do
    dir="$work/flight-$k-$try"
    mkdir -p "$dir"
    echo "== PX4 SITL: flight $((k + 1)) of $n, armed $k s after PX4 is up (try $try)"
    if FLY_DELAY_S=$k EMPLAN=$emplan bash sitl/px4-fly.sh "$mission" "$dir" >"$dir/fly.json" &&
      python3 sitl/check_report.py "$dir/fly.json" --mission-within 5; then
      dirs+=("$dir")
      break
    fi
    [ "$try" = 2 ] && { echo "FAIL: flight $((k + 1)) outside its bounds twice" >&2; exit 1; }
  done
done
"$emplan" report "${dirs[@]}" --json >"$work/combined.json"
python3 sitl/check_combined.py "$work/combined.json" --flights "$n" --legs-within 6 \
  --mission-within 2 --takeoff-within 10 --landing-within 10
echo "flights: ${dirs[*]}"
