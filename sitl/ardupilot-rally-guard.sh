#!/usr/bin/env bash
# The energy guard's return to a rally point on ArduCopter SITL: sitl/ardupilot-guard.sh's small
# pack (6S 3.4 Ah: emplan's plan of MISSION fits it with its reserve, ArduPilot's physics does
# not) and MISSION with one rally point added, RALLY_EAST_M / RALLY_NORTH_M of home (default 18 m
# east, 18 m north: nearer than home from the mission's eastern and northern waypoints) at the
# origin's height. ArduCopter's rally parameters are set over MAVLink and read back before emplan
# connects (RALLY_INCL_HOME, default here 0: the return goes to the rally point from wherever the
# guard decides, not only where it is nearer than home; RALLY_LIMIT_KM left at 0.3), so emplan's
# guard reads them from the autopilot, prices the return to where ArduCopter goes, and commands
# it. sitl/check_rally.py then checks, from the .tlog (pymavlink) and emplan's report: the return
# commanded and accepted, ArduCopter in RTL while armed, landed within --at-m (5 m) of the rally
# point and away from home, with at least the reserve by ArduPilot's own BATTERY_STATUS, and the
# report's `return_to` and the guard's `return` note naming "rally point 1".
# Usage: sitl/ardupilot-rally-guard.sh [EMPLAN_BINARY] [MISSION] [LOG_DIR]; SITL_INSTANCE picks
# the instance (default 4; parameters through its second port, +2).
set -euo pipefail
cd "$(dirname "$0")/.."
emplan=${1:-target/debug/emplan}
mission=${2:-missions/paper-sample-8wp.toml}
log_dir=${3:-$(mktemp -d -t emplan-ardupilot-rally-guard.XXXXXX)}
rally_east_m=${RALLY_EAST_M:-18}
rally_north_m=${RALLY_NORTH_M:-18}
incl_home=${RALLY_INCL_HOME:-0}
shared=${SHARED_SITL:-../shared/sitl}
[ -d "$shared" ] || shared=/work/shared/sitl
inst=${SITL_INSTANCE:-4}

venv=target/pymavlink-venv
if [ ! -x "$venv/bin/python" ]; then
  python3 -m venv "$venv"
fi
"$venv/bin/pip" install --quiet --disable-pip-version-check pymavlink==2.4.50

# The small pack's vehicle with its px4 table, as sitl/ardupilot-guard.sh builds it.
vehicle=target/ardupilot-guard-vehicle
mkdir -p "$vehicle"
if ! cmp -s sitl/ardupilot/vehicle-small-pack/vehicle.toml "$vehicle/vehicle.toml"; then
  cp sitl/ardupilot/vehicle-small-pack/vehicle.toml "$vehicle/vehicle.toml"
  rm -f "$vehicle/px4.table"
fi
if [ ! -f "$vehicle/px4.table" ] || [ "$emplan" -nt "$vehicle/px4.table" ]; then
  "$emplan" table build --vehicle "$vehicle" --profile px4 --quiet
fi
pack_ah=$(python3 -c 'import tomllib,sys; print(tomllib.load(open(sys.argv[1], "rb"))["battery"]["capacity_ah"])' \
  "$vehicle/vehicle.toml")
pack_mah=$(python3 -c 'import sys; print(round(float(sys.argv[1]) * 1000))' "$pack_ah")

# MISSION as a .plan with its rally point (QGroundControl's `rallyPoints`, altitude above home).
mkdir -p "$log_dir"
rallied=$log_dir/$(basename "${mission%.*}")-rally.plan
rm -f "$rallied"
"$emplan" convert "$mission" "$rallied"
rally=$(python3 - "$rallied" "$rally_east_m" "$rally_north_m" <<'PY'
import json, math, sys
path, east, north = sys.argv[1], float(sys.argv[2]), float(sys.argv[3])
with open(path) as f:
    plan = json.load(f)
lat0, lon0, _ = plan["mission"]["plannedHomePosition"]
height = float((plan.get("emplan") or {}).get("height_above_home_m", 30.0))
lat = lat0 + math.degrees(north / 6371000.0)
lon = lon0 + math.degrees(east / (6371000.0 * math.cos(math.radians(lat0))))
plan["rallyPoints"] = {"points": [[lat, lon, height]], "version": 2}
with open(path, "w") as f:
    json.dump(plan, f, indent=2)
print(f"{lat:.7f},{lon:.7f}")
PY
)
echo "rally point 1 at $rally, ${rally_east_m} m east and ${rally_north_m} m north of home: $rallied"

sitl_log=$(mktemp -t emplan-sitl.XXXXXX)
"$shared/ardupilot/run.sh" "$inst" 10 >"$sitl_log" 2>&1 &
sitl=$!
trap 'kill $sitl 2>/dev/null || true; wait $sitl 2>/dev/null || true' EXIT
if ! "$venv/bin/python" sitl/ardupilot_params.py "tcp:127.0.0.1:$((5762 + 10 * inst))" \
    "SIM_BATT_CAP_AH=$pack_ah" "BATT_CAPACITY=$pack_mah" \
    BATT_FS_LOW_ACT=0 BATT_FS_CRT_ACT=0 BATT_LOW_MAH=0 BATT_CRT_MAH=0 BATT_LOW_VOLT=0 BATT_CRT_VOLT=0 \
    "RALLY_INCL_HOME=$incl_home"; then
  echo "FAIL: ArduCopter SITL's battery and rally parameters could not be set" >&2
  tail -20 "$sitl_log" >&2
  exit 1
fi
report=$log_dir/fly.json
rc=0
timeout 600 "$emplan" fly "$rallied" --arm --connect "tcpout:127.0.0.1:$((5760 + 10 * inst))" \
    --vehicle "$vehicle" --log-dir "$log_dir" --json --guard rtl >"$report" || rc=$?
if [ "$rc" -ne 0 ] && [ "$rc" -ne 3 ]; then
  echo "FAIL: emplan fly --guard rtl on ArduCopter SITL did not end in a report (exit $rc):" >&2
  cat "$report" >&2
  tail -20 "$sitl_log" >&2
  exit 1
fi
flight=$(python3 -c 'import json,sys; print(json.load(open(sys.argv[1]))["log_dir"])' "$report")
"$venv/bin/python" sitl/check_rally.py "$flight" --vehicle "$vehicle" --report "$report" --rally "$rally"
