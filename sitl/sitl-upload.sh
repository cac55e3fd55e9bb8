#!/usr/bin/env bash
# Starts a real autopilot in SITL and, right after (no waiting for it to boot), uploads a mission
# to it with emplan; fails unless emplan reports the upload verified. The SITL is stopped after.
# Usage: sitl/sitl-upload.sh ardupilot|px4 [EMPLAN_BINARY] [MISSION]
#   ardupilot: ../shared/sitl/ardupilot/run.sh INSTANCE 10 (INSTANCE from $SITL_INSTANCE, default
#              0), emplan --connect tcpout:127.0.0.1:$((5760 + 10*INSTANCE)); ArduPilot refuses
#              uploads with MAV_MISSION_NO_SPACE while it boots: emplan waits that out.
#   px4:       sitl/px4-run.sh (one PX4 per machine), emplan --connect udpin:127.0.0.1:14550.
set -euo pipefail
cd "$(dirname "$0")/.."
which=${1:?usage: sitl/sitl-upload.sh ardupilot|px4 [EMPLAN_BINARY] [MISSION]}
emplan=${2:-target/debug/emplan}
mission=${3:-missions/paper-sample-8wp.toml}
shared=${SHARED_SITL:-../shared/sitl}
[ -d "$shared" ] || shared=/work/shared/sitl
log=$(mktemp -t emplan-sitl.XXXXXX)
case "$which" in
  ardupilot)
    inst=${SITL_INSTANCE:-0}
    "$shared/ardupilot/run.sh" "$inst" 10 >"$log" 2>&1 &
    url="tcpout:127.0.0.1:$((5760 + 10 * inst))"
    ;;
  px4)
    PX4_SITL_DIR="$shared/px4" PX4_SIM_SPEED_FACTOR=10 PX4_PARAM_SDLOG_MODE=-1 sitl/px4-run.sh >"$log" 2>&1 &
    url="udpin:127.0.0.1:14550"
    ;;
  *) echo "unknown autopilot $which (ardupilot or px4)" >&2; exit 2 ;;
esac
sitl=$!
stop() { kill "$sitl" 2>/dev/null || true; wait "$sitl" 2>/dev/null || true; }
trap stop EXIT
start=$(date +%s.%N)
if ! out=$(timeout 90 "$emplan" upload "$mission" --connect "$url" --json); then
  echo "FAIL: emplan upload to $which SITL ($url) did not verify:" >&2
  echo "$out" >&2
  tail -20 "$log" >&2
  exit 1
fi
python3 - "$out" "$which" "$start" <<'PY'
import json, sys, time
doc = json.loads(sys.argv[1])
report = doc["report"]
assert report["verified"], doc
print(f"{sys.argv[2]} SITL: {report['items']} items of {doc['mission']} verified "
      f"({'accepted' if report['acked'] else 'final ack lost, settled by read-back'}), "
      f"{time.time() - float(sys.argv[3]):.1f} s after the SITL was started")
PY
