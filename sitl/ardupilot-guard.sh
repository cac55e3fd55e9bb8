#!/usr/bin/env bash
# The energy guard against a real autopilot: ArduCopter SITL (../shared/sitl/ardupilot, ArduPilot's
# own multicopter and battery physics, about twice as costly as emplan's model over a mission)
# given a small pack, SIM_BATT_CAP_AH and BATT_CAPACITY set over MAVLink to the capacity of
# sitl/ardupilot/vehicle-small-pack (6S 3.4 Ah) and read back before emplan connects. emplan plans
# with that vehicle, whose plan fits the pack with its reserve; ArduPilot's physics does not
# (docs/ardupilot-sitl.md). `emplan fly --arm` with GUARD_ARGS (default "--guard rtl") flies it,
# and sitl/check_guard.py reads ArduPilot's own BATTERY_STATUS at landing from the .tlog emplan
# wrote: with --guard rtl the vehicle was commanded home (RTL) and landed with at least the
# reserve (usable energy minus ArduPilot's energy_consumed >= reserve_pct of usable); with
# anything else (GUARD_ARGS="--guard off", or "" before the guard existed) it is the control, which
# must land below the reserve. EXPECT=home|below overrides which.
# ArduPilot's battery failsafes stay disabled (params/s1000.parm: BATT_FS_*_ACT 0, no low/critical
# voltage or mAh), so only emplan's guard acts.
# Usage: sitl/ardupilot-guard.sh [EMPLAN_BINARY] [MISSION] [LOG_DIR]; SITL_INSTANCE picks the
# instance (TCP 5760 + 10 x instance, default 2; the parameters go through its second port, +2).
# The vehicle directory with its px4 energy table is built in target/ardupilot-guard-vehicle
# (emplan table build: about 2 minutes with a debug binary, once).
set -euo pipefail
cd "$(dirname "$0")/.."
emplan=${1:-target/debug/emplan}
mission=${2:-missions/paper-sample-8wp.toml}
log_dir=${3:-$(mktemp -d -t emplan-ardupilot-guard.XXXXXX)}
guard_args=${GUARD_ARGS---guard rtl}
case " $guard_args " in
  *" --guard rtl "* | *" --guard=rtl "*) expect=${EXPECT:-home} ;;
  *) expect=${EXPECT:-below} ;;
esac
shared=${SHARED_SITL:-../shared/sitl}
[ -d "$shared" ] || shared=/work/shared/sitl
inst=${SITL_INSTANCE:-2}

venv=target/pymavlink-venv
if [ ! -x "$venv/bin/python" ]; then
  python3 -m venv "$venv"
fi
"$venv/bin/pip" install --quiet --disable-pip-version-check pymavlink==2.4.50

# The vehicle of the small pack, with its px4 table: the table's energies do not depend on the
# pack's capacity, but its parameter hash does, so it is built here rather than committed twice
# (again whenever the vehicle file or the emplan binary is newer than it).
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

sitl_log=$(mktemp -t emplan-sitl.XXXXXX)
"$shared/ardupilot/run.sh" "$inst" 10 >"$sitl_log" 2>&1 &
sitl=$!
trap 'kill $sitl 2>/dev/null || true; wait $sitl 2>/dev/null || true' EXIT
# SIM_BATT_CAP_AH takes effect at once on the ground: ArduPilot's simulated battery resets to a
# full pack of that capacity when the parameter changes (libraries/SITL/SIM_Battery.cpp,
# maybe_reset); BATT_CAPACITY is what its monitor's remaining % counts consumed mAh against.
if ! "$venv/bin/python" sitl/ardupilot_params.py "tcp:127.0.0.1:$((5762 + 10 * inst))" \
    "SIM_BATT_CAP_AH=$pack_ah" "BATT_CAPACITY=$pack_mah" \
    BATT_FS_LOW_ACT=0 BATT_FS_CRT_ACT=0 BATT_LOW_MAH=0 BATT_CRT_MAH=0 BATT_LOW_VOLT=0 BATT_CRT_VOLT=0; then
  echo "FAIL: ArduCopter SITL's battery parameters could not be set" >&2
  tail -20 "$sitl_log" >&2
  exit 1
fi
mkdir -p "$log_dir"
report=$log_dir/fly.json
# Exit 3: the flight landed with waypoints left (the guard sent it home), a report all the same.
rc=0
# shellcheck disable=SC2086 # GUARD_ARGS is a list of arguments, split on purpose
timeout 600 "$emplan" fly "$mission" --arm --connect "tcpout:127.0.0.1:$((5760 + 10 * inst))" \
    --vehicle "$vehicle" --log-dir "$log_dir" --json $guard_args >"$report" || rc=$?
if [ "$rc" -ne 0 ] && [ "$rc" -ne 3 ]; then
  echo "FAIL: emplan fly $guard_args on ArduCopter SITL did not end in a report (exit $rc):" >&2
  cat "$report" >&2
  tail -20 "$sitl_log" >&2
  exit 1
fi
flight=$(python3 -c 'import json,sys; print(json.load(open(sys.argv[1]))["log_dir"])' "$report")
python3 -c 'import json,sys; t=json.load(open(sys.argv[1]))["total"]
print("emplan: predicted %.1f kJ, measured %.1f kJ over what was flown" % (t["predicted_kj"], t["measured_kj"]))' "$report"
"$venv/bin/python" sitl/check_guard.py "$flight" --vehicle "$vehicle" --expect "$expect"
