#!/usr/bin/env bash
# A field mission with actions on a real ArduPilot: ArduCopter SITL (CAM1_TYPE 1, a camera on a
# servo output, answers each photo with CAMERA_FEEDBACK) flies missions/orchard-inspection.plan
# (a gimbal pitch and a photo at each of its eight points, a speed of 4 m/s then 8 m/s, a region
# of interest set and cleared, a yaw) in the energy order with `emplan fly --arm`, priced with
# VEHICLE (the vehicle calibrated on ArduCopter flights) and the ardupilot profile. Then
# sitl/check_actions.py, with pymavlink reading the .tlog emplan wrote: as many CAMERA_FEEDBACK
# as photo actions, one at each waypoint, each within 2 m of it; every leg measured (the flight
# checked by sitl/check_report.py); the legs flown after the speed change within LEGS_PCT
# (default 10) of what ArduCopter measured.
# Usage: sitl/ardupilot-actions.sh EMPLAN_BINARY VEHICLE_DIR [LOG_DIR]
set -euo pipefail
cd "$(dirname "$0")/.."
emplan=$1
vehicle=$2
log_dir=${3:-$(mktemp -d -t emplan-ardupilot-actions.XXXXXX)}
mission=missions/orchard-inspection.plan
mkdir -p "$log_dir"
"$emplan" plan "$mission" --vehicle "$vehicle" --profile ardupilot --order energy --json \
  >"$log_dir/plan.json"
FLY_ARGS="--vehicle $vehicle --profile ardupilot --order energy" \
  bash sitl/ardupilot-fly.sh "$emplan" "$mission" "$log_dir"
venv=target/pymavlink-venv
if [ ! -x "$venv/bin/python" ]; then
  python3 -m venv "$venv"
fi
"$venv/bin/pip" install --quiet --disable-pip-version-check pymavlink==2.4.50
"$venv/bin/python" sitl/check_actions.py "$mission" "$log_dir/plan.json" "$log_dir/fly.json" \
  --legs-within "${LEGS_PCT:-10}"
