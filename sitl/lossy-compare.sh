#!/usr/bin/env bash
# Mission transfer over a bad radio: emplan, MAVSDK 4.1.0's client and a pymavlink loop, each
# against MAVSDK's MissionRawServer through a seeded relay dropping each datagram with
# probability p each way (sitl/lossy_compare.py says how a trial is counted).
# Usage: sitl/lossy-compare.sh [run|speed] [options of sitl/lossy_compare.py]
#   sitl/lossy-compare.sh run                 # 50 items, 20 trials, p = 0.1 and 0.3 (~30-60 min)
#   sitl/lossy-compare.sh run --trials 5      # a quicker look
#   sitl/lossy-compare.sh speed               # clean loopback, 500 items, median of 5 runs
# Creates target/sitl-venv with mavsdk==4.1.0 and pymavlink from PyPI and builds emplan (release).
set -euo pipefail
cd "$(dirname "$0")/.."
venv=target/sitl-venv
if [ ! -x "$venv/bin/python" ]; then
  python3 -m venv "$venv"
fi
"$venv/bin/pip" install --quiet --disable-pip-version-check mavsdk==4.1.0 pymavlink
cargo build --release --quiet
mode=${1:-run}
shift || true
exec "$venv/bin/python" sitl/lossy_compare.py "$mode" --emplan target/release/emplan "$@"
