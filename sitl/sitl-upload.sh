#!/usr/bin/env bash
# Starts a real autopilot in SITL and, right after (no waiting for it to boot), uploads a mission
# to it with emplan; fails unless emplan reports the upload verified. The SITL is stopped after.
# Usage: sitl/sitl-upload.sh ardupilot|px4|ardupilot-corrupt [EMPLAN_BINARY] [MISSION]
#   ardupilot: ../shared/sitl/ardupilot/run.sh INSTANCE 10 (INSTANCE from $SITL_INSTANCE, default
#              0), emplan --connect tcpout:127.0.0.1:$((5760 + 10*INSTANCE)); ArduPilot refuses
#              uploads with MAV_MISSION_NO_SPACE while it boots: emplan waits that out.
#   px4:       sitl/px4-run.sh (one PX4 per machine), emplan --connect udpin:127.0.0.1:14550.
#   ardupilot-corrupt: as ardupilot, through sitl/corrupting_proxy.py, which moves item 3's
#              latitude 10 degE7 on its way: ArduPilot accepts and stores a different mission,
#              and this fails unless emplan's read-back catches it (stage verify, accepted, item 3).
#              Needs pymavlink: target/sitl-venv is made as sitl/mavsdk_peer.sh makes it.
# A mission with a geofence and rally points (missions/orchard-fenced.plan) has them uploaded
# beside the mission and read back identical; this then fails unless both are verified and
# `emplan download OUT.plan` reads the same numbers of fence and rally items back.
set -euo pipefail
cd "$(dirname "$0")/.."
which=${1:?usage: sitl/sitl-upload.sh ardupilot|px4|ardupilot-corrupt [EMPLAN_BINARY] [MISSION]}
emplan=${2:-target/debug/emplan}
mission=${3:-missions/paper-sample-8wp.toml}
shared=${SHARED_SITL:-../shared/sitl}
[ -d "$shared" ] || shared=/work/shared/sitl
log=$(mktemp -t emplan-sitl.XXXXXX)
case "$which" in
  ardupilot|ardupilot-corrupt)
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
proxy=
stop() {
  [ -n "$proxy" ] && kill "$proxy" 2>/dev/null || true
  kill "$sitl" 2>/dev/null || true
  wait "$sitl" 2>/dev/null || true
}
trap stop EXIT
start=$(date +%s.%N)
if [ "$which" = ardupilot-corrupt ]; then
  venv=target/sitl-venv
  [ -x "$venv/bin/python" ] || python3 -m venv "$venv"
  "$venv/bin/pip" install --quiet --disable-pip-version-check pymavlink
  port=$((5760 + 10 * inst))
  proxy_port=$((15760 + 10 * inst))
  # The autopilot's TCP port opens a moment after start.
  for _ in $(seq 50); do (exec 3<>"/dev/tcp/127.0.0.1/$port") 2>/dev/null && break; sleep 0.2; done
  "$venv/bin/python" sitl/corrupting_proxy.py "$proxy_port" "$port" 3 >>"$log" 2>&1 &
  proxy=$!
  sleep 1
  if out=$(timeout 90 "$emplan" upload "$mission" --connect "tcpout:127.0.0.1:$proxy_port" --json); then
    echo "FAIL: emplan reported verified although ArduPilot holds a different item 3:" >&2
    echo "$out" >&2
    exit 1
  fi
  python3 - "$out" <<'PY'
import json, sys
doc = json.loads(sys.argv[1])
assert (doc["ok"], doc["stage"], doc["accepted"], doc["item"]) == (False, "verify", True, 3), doc
print(f"ardupilot SITL holding a changed item 3: caught ({doc['error'].split(': verify: ')[-1]})")
PY
  exit 0
fi
if ! out=$(timeout 90 "$emplan" upload "$mission" --connect "$url" --json); then
  echo "FAIL: emplan upload to $which SITL ($url) did not verify:" >&2
  echo "$out" >&2
  tail -20 "$log" >&2
  exit 1
fi
lists=$(python3 - "$out" "$which" "$start" <<'PY'
import json, sys, time
doc = json.loads(sys.argv[1])
report = doc["report"]
assert report["verified"], doc
print(f"{sys.argv[2]} SITL: {report['items']} items of {doc['mission']} verified "
      f"({'accepted' if report['acked'] else 'final ack lost, settled by read-back'}), "
      f"{time.time() - float(sys.argv[3]):.1f} s after the SITL was started", file=sys.stderr)
counts = []
for key in ("fence", "rally"):
    got = doc.get(key)
    assert got is not None, f"{sys.argv[2]} SITL declares no {key} list: {doc}"
    assert got["verified"], doc
    print(f"{sys.argv[2]} SITL: {key} {got['count']} ({got['items']} items) verified", file=sys.stderr)
    counts.append(got["items"] if got["count"] else 0)
print(*counts)
PY
)
read -r fence_items rally_items <<<"$lists"
if [ "$fence_items" -gt 0 ] || [ "$rally_items" -gt 0 ]; then
  held=$(mktemp -d -t emplan-sitl-held.XXXXXX)
  if ! down=$(timeout 90 "$emplan" download --connect "$url" "$held/held.plan"); then
    echo "FAIL: emplan download from $which SITL ($url) failed" >&2
    exit 1
  fi
  want="fence $fence_items items, rally points $rally_items items"
  case "$down" in
    *"$want"*) echo "$which SITL: download read back the $want" ;;
    *) echo "FAIL: download from $which SITL: expected '$want' in: $down" >&2; exit 1 ;;
  esac
fi
