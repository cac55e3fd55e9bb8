#!/usr/bin/env bash
# Flies a mission on ArduCopter SITL (../shared/sitl/ardupilot: ArduPilot's own multicopter and
# battery physics, an S1000-like octocopter) with `emplan fly --arm`, started right after the SITL:
# verified upload (ArduPilot's boot refusal waited out), GUIDED, arm, AUTO, MISSION_START, recorded
# until landed and disarmed, reported. Checks every leg found and measured and the log complete
# (sitl/check_report.py; pymavlink reads the .tlog: sitl/tlog_check.sh), and prints the per-leg
# comparison: ArduPilot's physics is not emplan's, so measured differs from predicted (its climbs
# cost far less, its hover power is higher) -- that is information, not a failure.
# ArduCopter's own DataFlash log of the flight (logged while armed) is kept as LOG_DIR/ardupilot.bin.
# Usage: sitl/ardupilot-fly.sh [EMPLAN_BINARY] [MISSION] [LOG_DIR]; SITL_INSTANCE picks the
# instance (TCP 5760 + 10 x instance, default 0); FLY_ARGS adds arguments to emplan fly;
# SITL_PARAMS sets ArduPilot parameters (NAME=VALUE ..., e.g. "SIM_WIND_SPD=6 SIM_WIND_DIR=270
# SIM_WIND_T=1") over MAVLink and reads them back before emplan connects.
set -euo pipefail
cd "$(dirname "$0")/.."
emplan=${1:-target/debug/emplan}
mission=${2:-missions/paper-sample-8wp.toml}
log_dir=${3:-$(mktemp -d -t emplan-ardupilot-fly.XXXXXX)}
shared=${SHARED_SITL:-../shared/sitl}
[ -d "$shared" ] || shared=/work/shared/sitl
inst=${SITL_INSTANCE:-0}
sitl_log=$(mktemp -t emplan-sitl.XXXXXX)
# run.sh makes its working directory (where ArduCopter writes logs/*.BIN) with mktemp under
# TMPDIR: a TMPDIR of our own tells us where it is.
sitl_tmp=$(mktemp -d -t emplan-sitl-work.XXXXXX)
TMPDIR=$sitl_tmp "$shared/ardupilot/run.sh" "$inst" 10 >"$sitl_log" 2>&1 &
sitl=$!
stop_sitl() {
  kill $sitl 2>/dev/null || true
  wait $sitl 2>/dev/null || true
}
trap 'stop_sitl; rm -rf "$sitl_tmp"' EXIT
if [ -n "${SITL_PARAMS:-}" ]; then
  venv=target/pymavlink-venv
  if [ ! -x "$venv/bin/python" ]; then
    python3 -m venv "$venv"
  fi
  "$venv/bin/pip" install --quiet --disable-pip-version-check pymavlink==2.4.50
  # shellcheck disable=SC2086 # SITL_PARAMS is a list of NAME=VALUE, split on purpose
  if ! "$venv/bin/python" sitl/ardupilot_params.py "tcp:127.0.0.1:$((5762 + 10 * inst))" \
      $SITL_PARAMS; then
    echo "FAIL: ArduCopter SITL's parameters $SITL_PARAMS could not be set" >&2
    tail -20 "$sitl_log" >&2
    exit 1
  fi
fi
mkdir -p "$log_dir"
report=$log_dir/fly.json
# FLY_ARGS: more arguments for emplan fly (e.g. "--order distance"), split on spaces.
# shellcheck disable=SC2086
if ! timeout 300 "$emplan" fly "$mission" --arm --connect "tcpout:127.0.0.1:$((5760 + 10 * inst))" \
    --log-dir "$log_dir" --json ${FLY_ARGS:-} >"$report"; then
  echo "FAIL: emplan fly on ArduCopter SITL did not end in a report:" >&2
  cat "$report" >&2
  tail -20 "$sitl_log" >&2
  exit 1
fi
# ArduCopter writes its log from a thread of its own: let it write the disarm and its buffer
# (2 s at 10x is 20 s of its time), then stop it so the file is whole.
sleep 2
stop_sitl
bin=$(ls -t "$sitl_tmp"/arducopter-sitl.*/logs/*.BIN 2>/dev/null | head -1 || true)
if [ -z "$bin" ]; then
  echo "FAIL: ArduCopter SITL wrote no DataFlash log under $sitl_tmp" >&2
  exit 1
fi
cp "$bin" "$log_dir/ardupilot.bin"
echo "ArduCopter's DataFlash log: $log_dir/ardupilot.bin ($(stat -c %s "$log_dir/ardupilot.bin") bytes)"
python3 sitl/check_report.py "$report"
flight=$(python3 -c 'import json,sys; print(json.load(open(sys.argv[1]))["log_dir"])' "$report")
bash sitl/tlog_check.sh "$flight"
