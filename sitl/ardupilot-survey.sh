#!/usr/bin/env bash
# Survey blocks on a real ArduPilot: ArduCopter SITL (CAM1_TYPE 1, a camera on a servo output,
# its distance trigger answered with CAMERA_FEEDBACK) flies missions/orchard-survey.plan (two
# QGroundControl surveys and five inspection points) in the energy order with `emplan fly --arm`,
# priced with VEHICLE (the vehicle calibrated on ArduCopter flights) and the ardupilot profile.
# Then sitl/check_survey.py: every block of the plan flown and measured, each within BLOCKS_PCT
# (default 10) of its prediction, its photos counted; pymavlink counts the CAMERA_FEEDBACK in
# the .tlog emplan wrote and they agree with the report's.
# Usage: sitl/ardupilot-survey.sh EMPLAN_BINARY VEHICLE_DIR [LOG_DIR]
set -euo pipefail
cd "$(dirname "$0")/.."
emplan=$1
vehicle=$2
log_dir=${3:-$(mktemp -d -t emplan-ardupilot-survey.XXXXXX)}
mission=missions/orchard-survey.plan
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
"$venv/bin/python" sitl/check_survey.py "$log_dir/plan.json" "$log_dir/fly.json" \
  --blocks-within "${BLOCKS_PCT:-10}"
