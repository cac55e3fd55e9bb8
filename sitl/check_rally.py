#!/usr/bin/env python3
"""Check that the energy guard's return went to a rally point and landed there with the reserve.

Reads the flight.tlog emplan wrote (pymavlink, through sitl/check_guard.py's reader, independent
of emplan's), the vehicle.toml the flight was planned with and emplan's fly report. Passes when:
a MAV_CMD_NAV_RETURN_TO_LAUNCH was sent and accepted; the autopilot was in RTL (ArduCopter custom
mode 6) while armed; it landed within --at-m (default 5 m) of the rally point LAT,LON and more
than that from home; left >= reserve by the autopilot's own BATTERY_STATUS energy_consumed, in
check_guard.py's terms; and emplan's report says where the return went: its `return_to` and its
guard's `return` note's `return_to` are "rally point 1".

Prints the numbers either way. Exits 0 when all hold, 1 when one does not, 2 on bad usage or an
unreadable file.

Usage: check_rally.py FLIGHT_DIR|FLIGHT_TLOG --vehicle DIR --report FLY_JSON --rally LAT,LON [--at-m M]
"""

import json
import os
import sys
import tomllib

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from check_guard import distance_m, planning, read  # noqa: E402


def parse(argv):
    args = list(argv[1:])
    opts = {"--vehicle": None, "--report": None, "--rally": None, "--at-m": "5"}
    rest = []
    while args:
        a = args.pop(0)
        if a in opts:
            if not args:
                raise ValueError(f"{a} needs a value")
            opts[a] = args.pop(0)
        else:
            rest.append(a)
    if len(rest) != 1 or None in (opts["--vehicle"], opts["--report"], opts["--rally"]):
        raise ValueError("one flight, --vehicle DIR, --report FLY_JSON and --rally LAT,LON are needed")
    lat, _, lon = opts["--rally"].partition(",")
    target = rest[0]
    tlog = os.path.join(target, "flight.tlog") if os.path.isdir(target) else target
    return tlog, opts["--vehicle"], opts["--report"], (float(lat), float(lon)), float(opts["--at-m"])


def main(argv):
    try:
        tlog, vehicle_dir, report_path, rally, at_m = parse(argv)
    except ValueError as e:
        print(f"check_rally: {e}\n\n{__doc__.strip()}", file=sys.stderr)
        return 2
    try:
        usable_j, reserve_pct = planning(vehicle_dir)
        s = read(tlog)
        with open(report_path) as f:
            report = json.load(f)
    except (OSError, KeyError, ValueError, tomllib.TOMLDecodeError) as e:
        print(f"check_rally: {e}", file=sys.stderr)
        return 2
    if s["landing"] is None:
        print(f"check_rally: {tlog}: the vehicle never disarmed after it was armed (no landing)", file=sys.stderr)
        return 1
    battery, position = s["landing"]
    failures = []
    if battery.energy_consumed < 0:
        failures.append("the autopilot's BATTERY_STATUS carries no energy_consumed")
    left_j = usable_j - battery.energy_consumed * 100.0
    reserve_j = usable_j * reserve_pct / 100.0
    nan = float("nan")
    at_lat, at_lon = (position.lat / 1e7, position.lon / 1e7) if position is not None else (nan, nan)
    from_rally_m = distance_m(rally[0], rally[1], at_lat, at_lon)
    from_home_m = distance_m(s["home"][0], s["home"][1], at_lat, at_lon) if s["home"] else nan
    notes = [n for n in (report.get("guard") or {}).get("notes", []) if n.get("kind") == "return"]
    print(
        f"{tlog}: landed {from_rally_m:.1f} m from the rally point and {from_home_m:.1f} m from home; "
        f"left {left_j / 1000:.1f} kJ against the {reserve_pct:g}% reserve {reserve_j / 1000:.1f} kJ; "
        f"return commanded {s['rtl_sent']}x, accepted {s['rtl_accepted']}x, RTL while armed: "
        f"{'yes' if s['rtl_mode_armed'] else 'no'}; report return_to {report.get('return_to')!r}, "
        f"guard's return note {[(n.get('return_to'), n.get('home_kj')) for n in notes]}"
    )
    if s["rtl_sent"] == 0 or s["rtl_accepted"] == 0:
        failures.append("no MAV_CMD_NAV_RETURN_TO_LAUNCH sent and accepted")
    if not s["rtl_mode_armed"]:
        failures.append("the autopilot was never in RTL while armed")
    if not from_rally_m <= at_m:
        failures.append(f"landed {from_rally_m:.1f} m from the rally point, more than {at_m:g} m")
    if not from_home_m > at_m:
        failures.append(f"landed {from_home_m:.1f} m from home: not at the rally point")
    if left_j < reserve_j:
        failures.append(f"landed with {left_j / 1000:.1f} kJ, below the reserve {reserve_j / 1000:.1f} kJ")
    if report.get("return_to") != "rally point 1":
        failures.append(f"the report's return_to is {report.get('return_to')!r}, not 'rally point 1'")
    if not notes or notes[0].get("return_to") != "rally point 1":
        failures.append("the guard's return note does not name rally point 1")
    for f in failures:
        print(f"check_rally: FAIL: {f}", file=sys.stderr)
    if not failures:
        print("check_rally: ok (the guard's return landed at the rally point with the reserve)")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
