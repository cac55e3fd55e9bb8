#!/usr/bin/env bash
# Starts one SITL autopilot, runs sitl/probe_actions.py against it (what it takes and keeps of
# each action command) and stops it. Writes tests/fixtures/actions/<autopilot>.txt.
# Usage: sitl/probe-actions.sh ardupilot|px4 [OUT]
#   ardupilot: ../shared/sitl/ardupilot/run.sh $SITL_INSTANCE (default 7) 10,
#              tcp:127.0.0.1:$((5760 + 10*SITL_INSTANCE)).
#   px4:       sitl/px4-run.sh (one PX4 per machine), udpin:127.0.0.1:14550.
# Needs pymavlink: $PYTHON (default target/sitl-venv/bin/python, made as sitl/sitl-upload.sh makes it).
set -euo pipefail
cd "$(dirname "$0")/.."
which=${1:?usage: sitl/probe-actions.sh ardupilot|px4 [OUT]}
out=${2:-tests/fixtures/actions/$which.txt}
shared=${SHARED_SITL:-../shared/sitl}
[ -d "$shared" ] || shared=/work/shared/sitl
python=${PYTHON:-target/sitl-venv/bin/python}
if [ ! -x "$python" ]; then
  python3 -m venv target/sitl-venv
  target/sitl-venv/bin/pip install --quiet --disable-pip-version-check pymavlink
  python=target/sitl-venv/bin/python
fi
log=$(mktemp -t emplan-probe.XXXXXX)
case "$which" in
  ardupilot)
    inst=${SITL_INSTANCE:-7}
    "$shared/ardupilot/run.sh" "$inst" 10 >"$log" 2>&1 &
    url="tcp:127.0.0.1:$((5760 + 10 * inst))"
    sleep 2
    ;;
  px4)
    PX4_SITL_DIR="$shared/px4" PX4_SIM_SPEED_FACTOR=10 PX4_PARAM_SDLOG_MODE=-1 sitl/px4-run.sh >"$log" 2>&1 &
    url="udpin:127.0.0.1:14550"
    ;;
  *) echo "unknown autopilot $which (ardupilot or px4)" >&2; exit 2 ;;
esac
sitl=$!
stop() {
  kill "$sitl" 2>/dev/null || true
  wait "$sitl" 2>/dev/null || true
}
trap stop EXIT
mkdir -p "$(dirname "$out")"
timeout 600 "$python" sitl/probe_actions.py "$url" "$which" "$out"
