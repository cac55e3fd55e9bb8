#!/usr/bin/env bash
# A field flight over a telemetry radio, in real time: the built-in mock autopilot (the S1000,
# flying at 1x, as a vehicle does) behind a serial pair that carries 57 600 baud with 100 ms of
# latency each way, shared by both directions and dropping what overflows its 2 KB buffer
# (sitl/serial_radio.py); emplan connects to the pair's device as to a SiK radio
# (serial:/dev/pts/N:57600), uploads, arms, flies and measures. Passes when the upload verified,
# every leg was measured within 3% and no leg is flagged with a telemetry gap; prints what the
# radio carried (bytes a second each way, by message, the share of the line in use, frames
# dropped).
#
# usage: sitl/radio-fly.sh EMPLAN [MISSION] [OUT_DIR]
# RADIO_ARGS adds options to serial_radio.py (e.g. "--baud 57600 --latency-ms 100 --full-duplex").
set -euo pipefail
cd "$(dirname "$0")/.."
emplan=${1:-target/release/emplan}
mission=${2:-missions/paper-sample-8wp.toml}
out=${3:-$(mktemp -d -t emplan-radio.XXXXXX)}
mkdir -p "$out"
port=${RADIO_PORT:-14750}

"$emplan" mock-autopilot --listen "udpin:127.0.0.1:$port" --vehicle models/s1000 --speedup 1 \
  --quiet >"$out/mock.log" 2>&1 &
mock=$!
# shellcheck disable=SC2086 # RADIO_ARGS is a list of options, split on purpose
python3 sitl/serial_radio.py "127.0.0.1:$port" --baud 57600 --latency-ms 100 ${RADIO_ARGS:-} \
  --device-file "$out/device" --stats "$out/radio.json" >"$out/radio.out" 2>"$out/radio.err" &
radio=$!
stop() {
  kill "$radio" 2>/dev/null || true
  wait "$radio" 2>/dev/null || true
  kill "$mock" 2>/dev/null || true
  wait "$mock" 2>/dev/null || true
}
trap stop EXIT
for _ in $(seq 50); do
  [ -s "$out/device" ] && break
  sleep 0.1
done
device=$(cat "$out/device")
echo "the radio's ground end: $device (57600 baud, 100 ms latency)"
if ! timeout 900 "$emplan" fly "$mission" --connect "serial:$device:57600" --arm \
    --log-dir "$out/logs" --json >"$out/fly.json" 2>"$out/fly.err"; then
  echo "FAIL: emplan fly over the radio did not end in a report:" >&2
  cat "$out/fly.json" "$out/fly.err" >&2
  exit 1
fi
stop
trap - EXIT
python3 sitl/check_report.py "$out/fly.json" --legs-within 3
python3 - "$out/fly.json" "$out/radio.json" <<'EOF'
import json, sys
report = json.load(open(sys.argv[1]))
radio = json.load(open(sys.argv[2]))
gaps = [f"{l['from']} -> {l['to']}" for l in report["legs"] if "telemetry_gap" in l["flags"]]
if gaps:
    sys.exit(f"FAIL: telemetry gaps flagged over the radio on {', '.join(gaps)}")
names = {"0": "HEARTBEAT", "1": "SYS_STATUS", "24": "GPS_RAW_INT", "30": "ATTITUDE",
         "32": "LOCAL_POSITION_NED", "33": "GLOBAL_POSITION_INT", "42": "MISSION_CURRENT",
         "46": "MISSION_ITEM_REACHED", "147": "BATTERY_STATUS", "242": "HOME_POSITION",
         "245": "EXTENDED_SYS_STATE", "231": "WIND_COV", "77": "COMMAND_ACK",
         "253": "STATUSTEXT", "22": "PARAM_VALUE", "73": "MISSION_ITEM_INT",
         "51": "MISSION_REQUEST_INT", "44": "MISSION_COUNT", "47": "MISSION_ACK"}
seconds = radio["seconds"]
print(f"radio: {seconds} s, line in use {100 * radio['line_in_use']:.0f}% "
      f"({radio['duplex']} duplex, {radio['baud']} baud, {radio['latency_ms']:.0f} ms), "
      f"down {radio['down_bytes_per_s']} B/s, up {radio['up_bytes_per_s']} B/s, "
      f"frames dropped down {radio['down_dropped_frames']} up {radio['up_dropped_frames']}, "
      f"most queued {radio['max_queued_bytes']} B")
for key, n in sorted(radio["down_bytes_by_message"].items(), key=lambda kv: -kv[1]):
    print(f"  down {names.get(key, 'message ' + key):<22} {n / seconds:7.0f} B/s")
print("ok: over the radio the upload verified and every leg was measured with no telemetry gap")
EOF
