#!/usr/bin/env bash
# Runs the independent MAVSDK peer test: creates its own Python venv (target/sitl-venv), installs
# MAVSDK 4.1 from PyPI, and uploads a mission with the emplan binary to MAVSDK's autopilot-side
# MissionRawServer. Usage: sitl/mavsdk_peer.sh [EMPLAN_BINARY] [MISSION]
set -euo pipefail
cd "$(dirname "$0")/.."
emplan=${1:-target/debug/emplan}
mission=${2:-missions/paper-sample-8wp.toml}
venv=target/sitl-venv
if [ ! -x "$venv/bin/python" ]; then
  python3 -m venv "$venv"
fi
"$venv/bin/pip" install --quiet --disable-pip-version-check mavsdk==4.1.0
"$venv/bin/python" sitl/mavsdk_peer.py "$emplan" "$mission" "${MAVSDK_PORT:-14561}"
