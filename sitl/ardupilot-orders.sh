#!/usr/bin/env bash
# The product's claim on physics we did not write: ArduCopter SITL (ArduPilot's own multicopter
# and battery physics) flies MISSION in the energy order and in the distance order
# (sitl/ardupilot-fly.sh with `emplan fly --order energy|distance --arm`, one after the other),
# and the energy order must measure less over the mission. Prints, for the mission and for its
# legs alone, what each order was predicted and measured to cost and the saving, predicted and
# measured (sitl/check_orders.py).
# Usage: sitl/ardupilot-orders.sh [EMPLAN_BINARY] [MISSION] [WORK_DIR]; SITL_INSTANCE as
# sitl/ardupilot-fly.sh.
set -euo pipefail
cd "$(dirname "$0")/.."
emplan=${1:-target/debug/emplan}
mission=${2:-missions/paper-sample-8wp.toml}
work=${3:-$(mktemp -d -t emplan-ardupilot-orders.XXXXXX)}
for order in energy distance; do
  mkdir -p "$work/$order"
  echo "== ArduCopter SITL flies $(basename "$mission") in the $order order"
  FLY_ARGS="--order $order" bash sitl/ardupilot-fly.sh "$emplan" "$mission" "$work/$order" \
    >"$work/$order.log" 2>&1 || {
    cat "$work/$order.log" >&2
    echo "FAIL: the $order order's flight on ArduCopter SITL" >&2
    exit 1
  }
done
python3 sitl/check_orders.py "$work/energy/fly.json" "$work/distance/fly.json"
