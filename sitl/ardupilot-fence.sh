#!/usr/bin/env bash
# A fenced field on ArduCopter SITL: the fence enabled (FENCE_ENABLE 1, FENCE_TYPE 4: polygons,
# FENCE_ACTION 1: a breach sends the vehicle home) and EXTENDED_STATUS streamed on the link emplan
# uses (MAV1_EXT_STAT 2, the first link's extended status stream: ArduPilot's FENCE_STATUS rides in it), set over MAVLink and read back
# before emplan connects; `emplan fly MISSION --order energy --arm` uploads the mission, its fence
# (an inclusion polygon, an exclusion square on a leg of the energy order) and its rally point and
# flies it (sitl/ardupilot-fly.sh: every leg found and measured, the log complete). Then
# sitl/check_fence.py: no breach (emplan's report has no `breaches`; no FENCE_STATUS breached, no
# breach STATUSTEXT, ArduCopter never in RTL while flying the mission, and the path flown, from
# ArduPilot's GLOBAL_POSITION_INT, never inside the exclusion zone nor outside the inclusion
# zone), every leg measured, and the energy order of the same mission without its fence, flown
# straight, would have crossed the exclusion square.
# Usage: sitl/ardupilot-fence.sh [EMPLAN_BINARY] [MISSION.plan] [LOG_DIR]; SITL_INSTANCE as
# sitl/ardupilot-fly.sh (default here 3).
set -euo pipefail
cd "$(dirname "$0")/.."
emplan=${1:-target/debug/emplan}
mission=${2:-missions/orchard-fenced.plan}
log_dir=${3:-$(mktemp -d -t emplan-ardupilot-fence.XXXXXX)}
mkdir -p "$log_dir"
# The straight order the check holds the flight against: the energy order of the same mission
# without its fence and rally points, as emplan planned it before it knew of fences.
python3 - "$mission" "$log_dir/unfenced.plan" <<'PY'
import json, sys
plan = json.load(open(sys.argv[1]))
plan["geoFence"] = {"version": 2, "polygons": [], "circles": []}
plan["rallyPoints"] = {"version": 2, "points": []}
json.dump(plan, open(sys.argv[2], "w"))
PY
"$emplan" plan "$log_dir/unfenced.plan" --order energy --json >"$log_dir/plan.json"
SITL_INSTANCE=${SITL_INSTANCE:-3} \
  SITL_PARAMS="FENCE_ENABLE=1 FENCE_TYPE=4 FENCE_ACTION=1 MAV1_EXT_STAT=2" \
  FLY_ARGS="--order energy" \
  bash sitl/ardupilot-fly.sh "$emplan" "$mission" "$log_dir"
# ardupilot-fly.sh made the pymavlink venv.
target/pymavlink-venv/bin/python sitl/check_fence.py "$log_dir/fly.json" "$mission" "$log_dir/plan.json"
