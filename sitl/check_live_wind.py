#!/usr/bin/env python3
"""Reads a `emplan fly --wind live` flight on ArduCopter SITL in a wind (sitl/ardupilot-wind.sh).

usage: check_live_wind.py FLY.json SPEED FROM_DEG

FLY.json is `emplan fly --json` (sitl/ardupilot-fly.sh's fly.json); SPEED and FROM_DEG the wind
the simulator blew (SIM_WIND_SPD, SIM_WIND_DIR). ArduCopter learns the wind only in the air (its
EKF3 with drag fusion), so emplan plans in the still air it reports on the ground and must price
the rest of the flight again once the estimate has settled. Fails unless
- the flight is complete with every leg measured;
- the rest was priced again at least once, the first time in a wind within 1.5 m/s and 30 degrees
  of the simulator's (the estimate is ArduCopter's, from its drag model of the airframe);
- over the legs flown after that, the new prices are closer to what ArduPilot's physics measured
  than the plan's first prices: the sum of |measured - predicted| is smaller.
Prints every such leg with both prices.
"""
import json
import math
import pathlib
import sys


def main():
    if len(sys.argv) != 4:
        print(__doc__, file=sys.stderr)
        return 2
    report = json.load(open(sys.argv[1]))
    speed, from_deg = float(sys.argv[2]), float(sys.argv[3])
    legs = report.get("legs") or []
    if not report.get("complete") or not legs or any(l.get("measured_kj") is None for l in legs):
        print(f"FAIL: {sys.argv[1]}: the flight is not complete with every leg measured")
        return 1
    repriced = report.get("repriced") or []
    if not repriced:
        print("FAIL: the rest of the flight was never priced again in the vehicle's wind")
        return 1
    first = repriced[0]
    heard = first["wind"]
    off_deg = abs((heard["from_deg"] - from_deg + 180.0) % 360.0 - 180.0)
    print(
        f"priced again {len(repriced)} time(s); first at {first['t_s']:.1f} s from {first['from']}"
        f" in {heard['speed_m_s']:.2f} m/s from {heard['from_deg']:.1f} deg (the simulator's:"
        f" {speed:g} m/s from {from_deg:g}); the rest {first['rest_before_kj']:.2f} ->"
        f" {first['rest_after_kj']:.2f} kJ"
    )
    ok = True
    if abs(heard["speed_m_s"] - speed) > 1.5 or off_deg > 30.0:
        print("FAIL: the wind priced in is not the simulator's within 1.5 m/s and 30 degrees")
        ok = False
    plan = json.load(open(pathlib.Path(report["log_dir"]) / "plan.json"))
    planned = plan["predicted"]["legs"]
    before = after = 0.0
    print(f"{'leg':<18}{'measured_kj':>12}{'first_kj':>10}{'err':>8}{'repriced_kj':>13}{'err':>8}")
    for k, leg in enumerate(legs):
        if leg["start_s"] <= first["t_s"]:
            continue
        measured, new = leg["measured_kj"], leg["predicted_kj"]
        old = planned[k]["energy_j"] / 1e3
        before += abs(measured - old)
        after += abs(measured - new)
        name = f"{leg['from']} -> {leg['to']}"
        print(
            f"{name:<18}{measured:>12.3f}{old:>10.3f}{(measured / old - 1) * 100:>+7.1f}%"
            f"{new:>13.3f}{(measured / new - 1) * 100:>+7.1f}%"
        )
    print(f"sum of |measured - predicted| over those legs: first prices {before:.3f} kJ, "
          f"repriced {after:.3f} kJ")
    if not after < before:
        print("FAIL: the prices in the vehicle's wind are not closer to the measurement")
        ok = False
    if math.isnan(after):
        ok = False
    print("ok: the rest priced again in ArduCopter's own wind estimate" if ok else "")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
