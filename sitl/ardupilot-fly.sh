#!/usr/bin/env bash
# Flies a mission on ArduCopter SITL (../shared/sitl/ardupilot: ArduPilot's own multicopter and
# battery physics, an S1000-like octocopter) with `emplan fly --arm`, started right after the SITL:
# verified upload (ArduPilot's boot refusal waited out), GUIDED, arm, AUTO, MISSION_START, recorded
# until landed and disarmed, reported. Checks every leg found and measured and the log complete
# (sitl/check_report.py; pymavlink reads the .tlog: sitl/tlog_check.sh), and prints the per-leg
# comparison: ArduPilot's physics is not emplan's, so measured differs from predicted (its climbs
# cost far less, its hover power is higher) -- that is information, not a failure.
# Usage: sitl/ardupilot-fly.sh [EMPLAN_BINARY] [MISSION] [LOG_DIR]; SITL_INSTANCE picks the
# instance (TCP 5760 + 10 x instance, default 0).
set -euo pipefail
cd "$(dirname "$0")/.."
emplan=${1:-target/debug/emplan}
mission=${2:-missions/paper-sample-8wp.toml}
log_dir=${3:-$(mktemp -d -t emplan-ardupilot-fly.XXXXXX)}
shared=${SHARED_SITL:-../shared/sitl}
[ -d "$shared" ] || shared=/work/shared/sitl
inst=${SITL_INSTANCE:-0}
sitl_log=$(mktemp -t emplan-sitl.XXXXXX)
"$shared/ardupilot/run.sh" "$inst" 10 >"$sitl_log" 2>&1 &
sitl=$!
trap 'kill $sitl 2>/dev/null || true; wait $sitl 2>/dev/null || true' EXIT
report=$log_dir/fly.json
if ! timeout 300 "$emplan" fly "$mission" --arm --connect "tcpout:127.0.0.1:$((5760 + 10 * inst))" \
    --log-dir "$log_dir" --json >"$report"; then
  echo "FAIL: emplan fly on ArduCopter SITL did not end in a report:" >&2
  cat "$report" >&2
  tail -20 "$sitl_log" >&2
  exit 1
fi
python3 sitl/check_report.py "$report"
flight=$(python3 -c 'import json,sys; print(json.load(open(sys.argv[1]))["log_dir"])' "$report")
bash sitl/tlog_check.sh "$flight"
