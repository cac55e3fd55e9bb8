#!/usr/bin/env python3
"""Check, from the autopilot's own BATTERY_STATUS, what a flight had left at landing.

Reads the flight.tlog emplan wrote (pymavlink, independently of emplan's reader) and the
vehicle.toml the flight was planned with. Landing is the autopilot's last disarm after it was
armed; the battery at landing is the last BATTERY_STATUS up to that disarm. Its energy_consumed
(hJ) is the autopilot's own integral of voltage times current since boot (ArduPilot's
AP_BattMonitor consumed_wh), not emplan's.

    left    = usable - energy_consumed     usable = [planning] usable_energy_wh
    reserve = reserve_pct % of usable      reserve_pct = [planning] reserve_pct

the same terms as emplan's pre-flight battery check (the plan fits when its predicted total is at
most usable - reserve), so "at least the reserve" means left >= reserve.

--expect home: the guard commanded the vehicle home and it landed with the reserve: a
  MAV_CMD_NAV_RETURN_TO_LAUNCH sent by the ground station and accepted, the autopilot in its
  return mode (ArduCopter RTL, custom mode 6) while armed, landed within --home-m of home, and
  left >= reserve.
--expect below: the control, nothing commanded home: no MAV_CMD_NAV_RETURN_TO_LAUNCH sent, the
  vehicle landed (the mission's own end), and left < reserve.

Prints the numbers either way. Exits 0 when the expectation holds, 1 when it does not, 2 on bad
usage or an unreadable file.

Usage: check_guard.py FLIGHT_DIR|FLIGHT_TLOG --vehicle DIR --expect home|below [--home-m M]
"""

import math
import os
import sys
import tomllib

MAV_CMD_NAV_RETURN_TO_LAUNCH = 20
MAV_RESULT_ACCEPTED = 0
ARMED_FLAG = 128
ARDUCOPTER_RTL = 6
MAV_TYPE_GCS = 6


def parse(argv):
    args = list(argv[1:])
    opts = {"--vehicle": None, "--expect": None, "--home-m": "10"}
    rest = []
    while args:
        a = args.pop(0)
        if a in opts:
            if not args:
                raise ValueError(f"{a} needs a value")
            opts[a] = args.pop(0)
        else:
            rest.append(a)
    if len(rest) != 1 or opts["--vehicle"] is None or opts["--expect"] not in ("home", "below"):
        raise ValueError("one flight, --vehicle DIR and --expect home|below are needed")
    target = rest[0]
    tlog = os.path.join(target, "flight.tlog") if os.path.isdir(target) else target
    return tlog, opts["--vehicle"], opts["--expect"], float(opts["--home-m"])


def planning(vehicle_dir):
    path = os.path.join(vehicle_dir, "vehicle.toml")
    with open(path, "rb") as f:
        p = tomllib.load(f)["planning"]
    return float(p["usable_energy_wh"]) * 3600.0, float(p["reserve_pct"])


def distance_m(lat1, lon1, lat2, lon2):
    north = math.radians(lat2 - lat1) * 6371000.0
    east = math.radians(lon2 - lon1) * 6371000.0 * math.cos(math.radians(lat1))
    return math.hypot(north, east)


def read(tlog):
    """What the flight log says: the battery at landing and the return home, if any."""
    from pymavlink import mavutil

    log = mavutil.mavlink_connection(tlog, dialect="ardupilotmega")
    autopilot = None
    armed = False
    was_armed = False
    s = {
        "battery": None,  # last BATTERY_STATUS so far
        "landing": None,  # (BATTERY_STATUS, GLOBAL_POSITION_INT) at the last disarm
        "position": None,
        "home": None,
        "rtl_sent": 0,
        "rtl_accepted": 0,
        "rtl_mode_armed": False,
        "min_voltage_v": None,
        "reached": [],
    }
    while True:
        msg = log.recv_match(blocking=False)
        if msg is None:
            break
        kind = msg.get_type()
        if kind == "BAD_DATA":
            continue
        src = msg.get_srcSystem()
        if kind == "COMMAND_LONG" and msg.command == MAV_CMD_NAV_RETURN_TO_LAUNCH and src != autopilot:
            s["rtl_sent"] += 1
            continue
        if kind == "HEARTBEAT" and msg.get_srcComponent() == 1 and msg.type != MAV_TYPE_GCS:
            autopilot = src
            now_armed = bool(msg.base_mode & ARMED_FLAG)
            if now_armed and msg.custom_mode == ARDUCOPTER_RTL:
                s["rtl_mode_armed"] = True
            if armed and not now_armed and s["battery"] is not None:
                s["landing"] = (s["battery"], s["position"])
            armed = now_armed
            was_armed = was_armed or now_armed
            continue
        if autopilot is not None and src != autopilot:
            continue
        if kind == "BATTERY_STATUS":
            s["battery"] = msg
            cells = [c for c in msg.voltages if c != 65535]
            if armed and cells:
                v = sum(cells) / 1000.0
                s["min_voltage_v"] = v if s["min_voltage_v"] is None else min(s["min_voltage_v"], v)
        elif kind == "GLOBAL_POSITION_INT":
            s["position"] = msg
        elif kind == "HOME_POSITION":
            s["home"] = (msg.latitude / 1e7, msg.longitude / 1e7)
        elif kind == "COMMAND_ACK" and msg.command == MAV_CMD_NAV_RETURN_TO_LAUNCH:
            if msg.result == MAV_RESULT_ACCEPTED:
                s["rtl_accepted"] += 1
        elif kind == "MISSION_ITEM_REACHED":
            s["reached"].append(msg.seq)
    s["was_armed"] = was_armed
    return s


def main(argv):
    try:
        tlog, vehicle_dir, expect, home_m = parse(argv)
    except ValueError as e:
        print(f"check_guard: {e}\n\n{__doc__.strip()}", file=sys.stderr)
        return 2
    try:
        usable_j, reserve_pct = planning(vehicle_dir)
        s = read(tlog)
    except (OSError, KeyError, ValueError, tomllib.TOMLDecodeError) as e:
        print(f"check_guard: {e}", file=sys.stderr)
        return 2
    failures = []
    if s["landing"] is None:
        print(f"check_guard: {tlog}: the vehicle never disarmed after it was armed (no landing)", file=sys.stderr)
        return 1
    battery, position = s["landing"]
    if battery.energy_consumed < 0:
        print(f"check_guard: {tlog}: the autopilot's BATTERY_STATUS carries no energy_consumed", file=sys.stderr)
        return 1
    consumed_j = battery.energy_consumed * 100.0
    left_j = usable_j - consumed_j
    reserve_j = usable_j * reserve_pct / 100.0
    cells = [c for c in battery.voltages if c != 65535]
    landed_alt_m = position.relative_alt / 1000.0 + 0.0 if position is not None else float("nan")
    from_home_m = float("nan")
    if position is not None and s["home"] is not None:
        from_home_m = distance_m(s["home"][0], s["home"][1], position.lat / 1e7, position.lon / 1e7)
    print(
        f"{tlog}: at landing BATTERY_STATUS energy_consumed {consumed_j / 1000:.1f} kJ, "
        f"current_consumed {battery.current_consumed} mAh, battery_remaining {battery.battery_remaining}%, "
        f"{sum(cells) / 1000:.2f} V (lowest while armed {s['min_voltage_v'] or float('nan'):.2f} V); "
        f"landed {landed_alt_m:.1f} m above home, {from_home_m:.1f} m from it"
    )
    print(
        f"usable {usable_j / 1000:.1f} kJ ({vehicle_dir}/vehicle.toml): left {left_j / 1000:.1f} kJ "
        f"({100 * left_j / usable_j:.1f}% of usable) against the {reserve_pct:g}% reserve "
        f"{reserve_j / 1000:.1f} kJ; return home commanded {s['rtl_sent']}x, accepted {s['rtl_accepted']}x, "
        f"RTL mode while armed: {'yes' if s['rtl_mode_armed'] else 'no'}; mission items reached {s['reached']}"
    )
    if not landed_alt_m < 2.0:
        failures.append(f"the vehicle disarmed {landed_alt_m:.1f} m above home, not landed")
    if expect == "home":
        if s["rtl_sent"] == 0:
            failures.append("no MAV_CMD_NAV_RETURN_TO_LAUNCH was sent")
        if s["rtl_accepted"] == 0:
            failures.append("no MAV_CMD_NAV_RETURN_TO_LAUNCH was accepted")
        if not s["rtl_mode_armed"]:
            failures.append("the autopilot was never in RTL while armed")
        if not from_home_m <= home_m:
            failures.append(f"landed {from_home_m:.1f} m from home, more than {home_m:g} m")
        if left_j < reserve_j:
            failures.append(f"landed with {left_j / 1000:.1f} kJ, below the reserve {reserve_j / 1000:.1f} kJ")
    else:
        if s["rtl_sent"] > 0:
            failures.append("MAV_CMD_NAV_RETURN_TO_LAUNCH was sent in the control flight")
        if left_j >= reserve_j:
            failures.append(
                f"the control landed with {left_j / 1000:.1f} kJ, not below the reserve {reserve_j / 1000:.1f} kJ: "
                "the pack is too big for the test to mean anything"
            )
    for f in failures:
        print(f"check_guard: FAIL: {f}", file=sys.stderr)
    if not failures:
        print(f"check_guard: ok ({'home with the reserve' if expect == 'home' else 'the control lands below the reserve'})")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
