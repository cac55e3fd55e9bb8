#!/usr/bin/env bash
# Flies a mission on real PX4 (SITL, SIH quadrotor, 10x real time, no .ulg) with a physical
# battery: starts PX4 SITL with SIM_BAT_ENABLE=0 and `emplan battery-sim` on its onboard link
# (UDP 14540), runs `emplan fly MISSION --arm --connect udpin:127.0.0.1:14550 --log-dir LOG_DIR
# --json`, prints its JSON and stops what it started. Exits with fly's status.
#
# Usage: sitl/px4-fly.sh [--no-battery] [--ulog] MISSION LOG_DIR [-- EXTRA FLY ARGS]
#   --ulog: PX4 keeps its own flight log (SDLOG_MODE 0: from arming to disarming), copied to
#           LOG_DIR/px4.ulg once PX4 has closed it. Its topics are those a flight is measured from,
#           at the rates a flight controller logs them by default (etc/logging/logger_topics.txt in
#           PX4's working directory replaces the profile: SITL's default profile logs the
#           estimator at 100 Hz, over 40 MB for the 8-waypoint sample; this log is under 1 MB).
#           ULOG_TOPICS=FILE: another topics file (lines `topic interval_ms`).
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
ulog=0
while :; do
  case "${1:-}" in
    --no-battery) battery=0; shift ;;
    --ulog) ulog=1; shift ;;
    *) break ;;
  esac
done
mission=${1:?usage: sitl/px4-fly.sh [--no-battery] [--ulog] MISSION LOG_DIR [-- EXTRA FLY ARGS]}
log_dir=${2:?usage: sitl/px4-fly.sh [--no-battery] [--ulog] MISSION LOG_DIR [-- EXTRA FLY ARGS]}
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
if [ "$ulog" = 1 ]; then
  sdlog=(PX4_PARAM_SDLOG_MODE=0)
  # PX4 links its working directory's etc/ to its rootfs only when there is none: give it one
  # whose entries are the rootfs's (through the shadow directory px4-run.sh makes) plus the
  # logger's topics file.
  mkdir -p "$work/px4/etc/logging"
  for entry in extras init.d init.d-posix; do
    ln -s "$work/shadow/etc/$entry" "$work/px4/etc/$entry"
  done
  if [ -n "${ULOG_TOPICS:-}" ]; then
    cp "$ULOG_TOPICS" "$work/px4/etc/logging/logger_topics.txt"
  else
    cat >"$work/px4/etc/logging/logger_topics.txt" <<'TOPICS'
battery_status 200
vehicle_global_position 100
vehicle_local_position 100
home_position 0
mission_result 0
navigator_mission_item 0
vehicle_status 0
vehicle_land_detected 0
vehicle_command 0
TOPICS
  fi
else
  sdlog=(PX4_PARAM_SDLOG_MODE=-1)
fi
trap 'exit 130' INT TERM
env PX4_SHADOW="$work/shadow" PX4_WORKDIR="$work/px4" PX4_SIM_SPEED_FACTOR=${PX4_SPEED:-10} \
  "${sdlog[@]}" PX4_PARAM_SIM_BAT_ENABLE=$((1 - battery)) \
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
if [ "$ulog" = 1 ]; then
  # PX4's logger closes the file when the vehicle disarms (files go to log/<date>/<time>.ulg).
  for _ in $(seq 50); do
    grep -q "closed logfile" "$log_dir/px4.log" 2>/dev/null && break
    sleep 0.2
  done
  grep -q "closed logfile" "$log_dir/px4.log" ||
    echo "px4-fly.sh: PX4 has not closed its log: px4.ulg may be cut short" >&2
  ulg=$(find "$work/px4/log" -name '*.ulg' 2>/dev/null | sort | tail -1)
  if [ -n "$ulg" ]; then
    cp "$ulg" "$log_dir/px4.ulg"
  else
    echo "px4-fly.sh: PX4 wrote no .ulg under its log directory" >&2
    [ "$status" = 0 ] && status=1
  fi
fi
exit "$status"
