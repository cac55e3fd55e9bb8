#!/usr/bin/env bash
# The pre-flight check on a real autopilot: ArduCopter SITL (../shared/sitl/ardupilot, home at the
# sample missions' field) is handed a mission whose origin is elsewhere (by default the orchard
# survey, 2.3 km away). `emplan fly --arm` must refuse it before uploading, naming the distance,
# and leave the vehicle's mission untouched (read back with `emplan download`: ArduPilot holds
# only its home, item 0). Then `emplan fly --arm --origin vehicle` plans it from the vehicle's
# home, and its outcome must be what `emplan plan` of that re-homed mission says: refused for a
# leg beyond the vehicle's limits or for the battery (the same error, nothing uploaded), or flown.
# Usage: sitl/ardupilot-far-origin.sh [EMPLAN_BINARY] [MISSION.toml] [LOG_DIR]; SITL_INSTANCE
# picks the instance (TCP 5760 + 10 x instance, default 0).
set -euo pipefail
cd "$(dirname "$0")/.."
emplan=${1:-target/debug/emplan}
mission=${2:-missions/davis-orchard-survey.toml}
work=${3:-$(mktemp -d -t emplan-far-origin.XXXXXX)}
mkdir -p "$work"
shared=${SHARED_SITL:-../shared/sitl}
[ -d "$shared" ] || shared=/work/shared/sitl
inst=${SITL_INSTANCE:-0}
url="tcpout:127.0.0.1:$((5760 + 10 * inst))"
sitl_log=$work/sitl.log
"$shared/ardupilot/run.sh" "$inst" 10 >"$sitl_log" 2>&1 &
sitl=$!
trap 'kill $sitl 2>/dev/null || true; wait $sitl 2>/dev/null || true' EXIT
fail() {
  echo "FAIL: $*" >&2
  tail -5 "$sitl_log" >&2
  exit 1
}

# 1. From the mission's origin: refused before upload, naming both positions and the distance.
if "$emplan" fly "$mission" --arm --connect "$url" --log-dir "$work/flights" --json \
    >"$work/refused.json" 2>"$work/refused.err"; then
  fail "emplan fly flew a mission whose origin is far from the vehicle's home"
fi
python3 - "$work/refused.json" <<'EOF'
import json, re, sys
doc = json.load(open(sys.argv[1]))
assert doc["ok"] is False and doc["stage"] == "preflight" and doc["accepted"] is False, doc
m = re.search(r"is (\d+) m from the mission's origin", doc["error"])
assert m and int(m.group(1)) > 20, doc["error"]
print(f"refused before upload: {doc['error']}")
EOF
"$emplan" download "$work/held.json" --connect "$url" --force 2>"$work/download.err" \
  || fail "emplan download: $(cat "$work/download.err")"
python3 - "$work/held.json" <<'EOF'
import json, sys
items = json.load(open(sys.argv[1]))
items = items["items"] if isinstance(items, dict) else items
assert len(items) <= 1, f"the vehicle holds {len(items)} items: something was uploaded"
print(f"nothing uploaded: the vehicle holds {len(items)} item (its home)")
EOF

# 2. From the vehicle's home: what `emplan plan` of the re-homed mission says.
set +e
"$emplan" fly "$mission" --arm --origin vehicle --connect "$url" --log-dir "$work/flights" \
  >"$work/vehicle.out" 2>"$work/vehicle.err"
flown=$?
set -e
home=$(grep -o "origin moved to the vehicle's home ([-0-9.]*, [-0-9.]*)" "$work/vehicle.err") \
  || fail "no re-homing line: $(cat "$work/vehicle.err")"
echo "$home"
python3 - "$mission" "$home" "$work/rehomed.toml" <<'EOF'
import re, sys
text = open(sys.argv[1]).read()
lat, lon = re.search(r"\(([-0-9.]+), ([-0-9.]+)\)", sys.argv[2]).groups()
# The waypoints are geodetic with heights above home: a new origin is the re-homed mission.
origin = re.search(r"\[origin\][^\[]*", text).group(0)
moved = re.sub(r"lat_deg = [-0-9.]+", f"lat_deg = {lat}", origin, count=1)
moved = re.sub(r"lon_deg = [-0-9.]+", f"lon_deg = {lon}", moved, count=1)
open(sys.argv[3], "w").write(text.replace(origin, moved, 1))
EOF
set +e
"$emplan" plan "$work/rehomed.toml" --json >"$work/plan.json" 2>"$work/plan.err"
planned=$?
set -e
if [ $planned -ne 0 ]; then
  said=$(grep '^error: ' "$work/plan.err" | head -1)
  [ $flown -ne 0 ] || fail "the plan refuses the re-homed mission ($said) but emplan fly flew it"
  grep -qF "$said" "$work/vehicle.err" \
    || fail "the plan says '$said'; emplan fly said: $(cat "$work/vehicle.err")"
  echo "refused as the plan says: ${said#error: }"
elif python3 -c 'import json,sys; sys.exit(0 if json.load(open(sys.argv[1]))["battery"]["feasible"] else 1)' "$work/plan.json"; then
  [ $flown -eq 0 ] || fail "the plan flies the re-homed mission but emplan fly did not: $(cat "$work/vehicle.err")"
  echo "flown from the vehicle's home, as planned"
else
  [ $flown -ne 0 ] && grep -q "not uploaded" "$work/vehicle.err" \
    || fail "the plan refuses the re-homed mission for the battery but emplan fly did not"
  echo "refused for the battery, as the plan says"
fi
if [ $flown -ne 0 ]; then
  "$emplan" download "$work/held.json" --connect "$url" --force 2>"$work/download.err" \
    || fail "emplan download: $(cat "$work/download.err")"
  python3 -c 'import json,sys; d=json.load(open(sys.argv[1])); d=d["items"] if isinstance(d,dict) else d; assert len(d)<=1, len(d)' \
    "$work/held.json" || fail "a refused flight left a mission on the vehicle"
fi
echo "OK: the far origin refused before upload, --origin vehicle as the plan says"
