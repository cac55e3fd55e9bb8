#!/usr/bin/env bash
# Energy in wind on physics we did not write: ArduCopter SITL (ArduPilot's own multicopter,
# battery and wind: SIM_WIND_SPD, SIM_WIND_DIR, SIM_WIND_T=1 a flat wind at every height,
# SIM_WIND_TURB=0) flies MISSION (sitl/ardupilot-fly.sh, `emplan fly --arm`, the ardupilot profile):
# 1. the ratio set: the mission's listed order in calm air and in winds of SPEEDS (m/s) from FROM
#    (degrees, meteorological), each priced by emplan in the wind it flies in (`--wind`), so each
#    leg's measured ratio wind / calm (which cancels most of the difference between ArduPilot's
#    airframe and emplan's) is set beside emplan's predicted ratio;
# 2. the orders: in the last of SPEEDS, REPEATS flights each of the still-air energy order
#    (`--order energy`, planned without the wind) and of the wind-aware energy order
#    (`--order energy --wind S@FROM`): the wind-aware one must measure less, or the difference
#    must be within the flights' own spread (both are printed; sitl/check_wind.py).
# 3. live: in the last of SPEEDS, the energy order flown with `--wind live`, ArduCopter's EKF3
#    estimating the wind by drag fusion (EK3_DRAG_MCOEF 0.2, the frame's own momentum drag
#    coefficient in s1000.json; EK3_DRAG_BCOEF_X/Y 24.3 kg/m2 = rho v^2 / (2 g tan 30 deg), the
#    frame's 15 m/s at a 30 degree lean): it learns the wind only in the air, so emplan plans in
#    still air and must price the rest again in flight, closer to the measurement
#    (sitl/check_live_wind.py).
# The vehicle is the one emplan plans with (VEHICLE_ARGS, default the built-in S1000): its
# model is not tuned to ArduPilot's airframe.
# Usage: sitl/ardupilot-wind.sh [EMPLAN_BINARY] [MISSION] [WORK_DIR]; SPEEDS (default "3 6"),
# FROM (default 270), REPEATS (default 2), SITL_INSTANCE as sitl/ardupilot-fly.sh (default 4).
set -euo pipefail
cd "$(dirname "$0")/.."
emplan=${1:-target/debug/emplan}
mission=${2:-missions/paper-sample-8wp.toml}
work=${3:-$(mktemp -d -t emplan-ardupilot-wind.XXXXXX)}
speeds=${SPEEDS:-3 6}
from=${FROM:-270}
repeats=${REPEATS:-2}
export SITL_INSTANCE=${SITL_INSTANCE:-4}
vehicle_args=${VEHICLE_ARGS:-}
mkdir -p "$work"

# fly NAME SPEED FLY_ARGS...: one flight in a wind of SPEED m/s from FROM.
fly() {
  local name=$1 speed=$2
  shift 2
  echo "== ArduCopter SITL flies $(basename "$mission"): $name (wind $speed m/s from $from)"
  # shellcheck disable=SC2086 # VEHICLE_ARGS is a list of arguments
  SITL_PARAMS="SIM_WIND_SPD=$speed SIM_WIND_DIR=$from SIM_WIND_T=1 SIM_WIND_TURB=0 ${EXTRA_PARAMS:-}" \
    FLY_ARGS="$* $vehicle_args" bash sitl/ardupilot-fly.sh "$emplan" "$mission" "$work/$name" \
    >"$work/$name.log" 2>&1 || {
    cat "$work/$name.log" >&2
    echo "FAIL: the flight $name on ArduCopter SITL" >&2
    exit 1
  }
}

ratio_set=("$work/calm/fly.json")
fly calm 0 --order listed
for s in $speeds; do
  fly "listed-$s" "$s" --order listed --wind "$s@$from"
  ratio_set+=("$work/listed-$s/fly.json")
  last=$s
done
still=()
aware=()
for k in $(seq 1 "$repeats"); do
  fly "still-air-order-$k" "$last" --order energy
  fly "wind-aware-order-$k" "$last" --order energy --wind "$last@$from"
  still+=("$work/still-air-order-$k/fly.json")
  aware+=("$work/wind-aware-order-$k/fly.json")
done
# What emplan predicts for the two orders' legs in that wind (plan --wind: the still-air order
# priced in the wind beside the wind-aware one).
# shellcheck disable=SC2086 # VEHICLE_ARGS is a list of arguments
"$emplan" plan "$mission" --order energy --wind "$last@$from" $vehicle_args \
  $([[ " $vehicle_args " == *" --profile "* ]] || echo "--profile ardupilot") --json \
  >"$work/plan-in-wind.json"
python3 sitl/check_wind.py --ratios "${ratio_set[@]}" \
  --still "${still[@]}" --aware "${aware[@]}" --plan "$work/plan-in-wind.json"
EXTRA_PARAMS="EK3_DRAG_MCOEF=0.2 EK3_DRAG_BCOEF_X=24.3 EK3_DRAG_BCOEF_Y=24.3" \
  fly "live-$last" "$last" --order energy --wind live
python3 sitl/check_live_wind.py "$work/live-$last/fly.json" "$last" "$from"
