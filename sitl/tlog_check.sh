#!/usr/bin/env bash
# Checks an emplan flight log with pymavlink, independently of emplan's own reader: creates its
# own Python venv (target/pymavlink-venv) with pymavlink from PyPI, then counts BATTERY_STATUS in
# flight.tlog and compares with samples.csv (sitl/tlog_check.py). Exit 0 when they match.
# Usage: sitl/tlog_check.sh FLIGHT_DIR | FLIGHT_TLOG [SAMPLES_CSV]
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
venv="$root/target/pymavlink-venv"
if [ ! -x "$venv/bin/python" ]; then
  python3 -m venv "$venv"
fi
"$venv/bin/pip" install --quiet --disable-pip-version-check pymavlink==2.4.50
exec "$venv/bin/python" "$root/sitl/tlog_check.py" "$@"
