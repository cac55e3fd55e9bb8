#!/usr/bin/env bash
# Runs LKH-3 (PyPI elkai) side by side with emplan's solvers and prints cost and time of both.
# Creates its own venv (target/peers-venv). Usage:
#   benches/peers/run.sh [tsplib|mission|all]
# tsplib: every TSPLIB ATSP instance in ../shared/tsplib-atsp, emplan `--solver auto` (exact
#         where it can prove it); mission: a generated 1000-waypoint mission priced with the
#         S1000 px4 table (costs in 0.1 J), emplan `--solver heuristic`.
set -euo pipefail
cd "$(dirname "$0")/../.."
what=${1:-all}
venv=target/peers-venv
[ -x "$venv/bin/python" ] || python3 -m venv "$venv"
"$venv/bin/pip" install --quiet --disable-pip-version-check elkai==2.0.1
cargo build --release --quiet
emplan=target/release/emplan
py="$venv/bin/python benches/peers/peers.py $emplan"
if [ "$what" = tsplib ] || [ "$what" = all ]; then
  $py ../shared/tsplib-atsp/*.atsp --emplan-args "--solver auto"
fi
if [ "$what" = mission ] || [ "$what" = all ]; then
  dir=target/peers
  mkdir -p "$dir"
  $emplan generate "$dir/random-1000.toml" --waypoints 1000 --xy 50 --z 25 --seed 1 --force >/dev/null
  $emplan plan "$dir/random-1000.toml" --export-atsp "$dir/random-1000.atsp" --force \
    --solver heuristic --time-limit 1 --json >/dev/null 2>&1 || true
  $py "$dir/random-1000.atsp" --emplan-args "--solver heuristic --time-limit ${TIME_LIMIT:-30}"
fi
