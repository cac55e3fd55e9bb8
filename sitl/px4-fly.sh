#!/usr/bin/env bash
# Flies a mission on real PX4 (SITL, SIH quadrotor, 10x real time, no .ulg) with a physical
# battery: starts PX4 SITL with SIM_BAT_ENABLE=0 and `emplan battery-sim` on its onboard link
# (UDP 14540), runs `emplan fly MISSION --arm --connect udpin:127.0.0.1:14550 --log-dir LOG_DIR
# --json`, prints its JSON and stops what it started. Exits with fly's status.
#
# Usage: sitl/px4-fly.sh [--no-battery] MISSION LOG_DIR [-- EXTRA FLY ARGS]
#   --no-battery: no battery process; PX4 keeps its own simulated battery (SIM_BAT_ENABLE=1), whose
#                 current is a fake -1 A: the flight is recorded but no energy is measurable.
# Env: EMPLAN (default target/debug/emplan), PX4_SITL_DIR (see sitl/px4-run.sh), PX4_SPEED (10),
#      FLY_DELAY_S (0): seconds to wait, once PX4 and the battery are up, before `emplan fly`.
#      PX4 SITL flies the same way each time it is armed at the same moment after its boot, and
#      differently when armed at another (docs/px4-sitl.md): flights with different delays
#      sample its flight-to-flight spread.
# PX4's and the battery process's output go to LOG_DIR/px4.log and LOG_DIR/battery-sim.log.
# One PX4 per machine: fails at once when something already listens on PX4's UDP port 18570.
set -euo pipefail
cd "$(dirname "$0")/.."
battery=1
if [ "${1:-}" = --no-battery ]; then battery=0; shift; fi
mission=${1:?usage: sitl/px4-fly.sh [--no-battery] MISSION LOG_DIR [-- EXTRA FLY ARGS]}
log_dir=${2:?usage: sitl/px4-fly.sh [--no-battery] MISSION LOG_DIR [-- EXTRA FLY ARGS]}
shift 2
[ "${1:-}" = -- ] && shift
emplan=${EMPLAN:-target/debug/emplan}
[ -x "$emplan" ] || { echo "px4-fly.sh: $emplan not built (cargo build)" >&2; exit 2; }
if ss -lun 2>/dev/null | grep -q '127.0.0.1:18570 '; then
  echo "px4-fly.sh: PX4 SITL already runs on this machine (UDP 18570 is taken): one at a time" >&2
  exit 2
fi
mkdir -p "$log_dir"
work=$(mktemp -d "${TMPDIR:-/tmp}/px4-fly.XXXXXX")
px4=
bat=
stop() {
  [ -n "$bat" ] && kill "$bat" 2>/dev/null && wait "$bat" 2>/dev/null || true
  [ -n "$px4" ] && kill "$px4" 2>/dev/null && wait "$px4" 2>/dev/null || true
  rm -rf "$work"
}
trap stop EXIT
trap 'exit 130' INT TERM
PX4_SHADOW="$work/shadow" PX4_WORKDIR="$work/px4" PX4_SIM_SPEED_FACTOR=${PX4_SPEED:-10} \
  PX4_PARAM_SDLOG_MODE=-1 PX4_PARAM_SIM_BAT_ENABLE=$((1 - battery)) \
  bash sitl/px4-run.sh >"$log_dir/px4.log" 2>&1 &
px4=$!
# PX4 takes off only once its estimator is ready ("Ready for takeoff"); the battery process
# must be reporting before the arming.
for _ in $(seq 300); do
  grep -q "Ready for takeoff" "$log_dir/px4.log" 2>/dev/null && break
  kill -0 "$px4" 2>/dev/null || { echo "px4-fly.sh: PX4 SITL exited:" >&2; tail -20 "$log_dir/px4.log" >&2; exit 1; }
  sleep 0.2
done
grep -q "Ready for takeoff" "$log_dir/px4.log" || { echo "px4-fly.sh: PX4 SITL not ready after 60 s" >&2; exit 1; }
if [ "$battery" = 1 ]; then
  RUST_LOG=${RUST_LOG:-info} "$emplan" battery-sim --connect udpin:127.0.0.1:14540 >"$log_dir/battery-sim.log" 2>&1 &
  bat=$!
  sleep 2
  kill -0 "$bat" 2>/dev/null || { echo "px4-fly.sh: battery-sim exited:" >&2; cat "$log_dir/battery-sim.log" >&2; exit 1; }
fi
sleep "${FLY_DELAY_S:-0}"
set +e
timeout 900 "$emplan" fly "$mission" --arm --connect udpin:127.0.0.1:14550 --log-dir "$log_dir" --json "$@"
status=$?
set -e
exit "$status"
