#!/usr/bin/env python3
"""Checks a flight of a mission with actions on a simulated autopilot, independently of emplan's
own reader: pymavlink reads the flight.tlog emplan wrote.

usage: check_actions.py MISSION.plan PLAN.json FLY.json [--legs-within PCT]

- Photos: as many CAMERA_FEEDBACK (ArduPilot) or CAMERA_IMAGE_CAPTURED (PX4) as the mission has
  photo actions (DO_DIGICAM_CONTROL with shoot 1, IMAGE_START_CAPTURE of one image), each
  nearest a waypoint that has one, one per such waypoint, within 2 m of it (3D, altitude above
  home).
- Speeds: every leg emplan's plan prices at a speed a DO_CHANGE_SPEED set (the plan's legs with
  "speed_m_s") measured within PCT of its prediction in the flight's report.
"""
import json
import math
import os
import sys

from pymavlink import mavutil

PHOTO_WITHIN_M = 2.0


def photo_actions(plan_file):
    """(lat, lon, alt above home) of every waypoint with a photo action, once per photo."""
    doc = json.load(open(plan_file))
    out = []
    last = None
    for item in doc["mission"]["items"]:
        c, p = item["command"], item["params"]
        if c in (16, 82):
            last = (p[4], p[5], p[6])
        elif (c == 203 and p[4] == 1) or (c == 2000 and p[2] == 1):
            out.append(last)
    return out


def distance_m(a, b):
    north = (a[0] - b[0]) * 111_320.0
    east = (a[1] - b[1]) * 111_320.0 * math.cos(math.radians(a[0]))
    return math.sqrt(north * north + east * east + (a[2] - b[2]) ** 2)


def photos_in(tlog):
    log = mavutil.mavlink_connection(tlog)
    found = []
    while True:
        m = log.recv_match(type=["CAMERA_FEEDBACK", "CAMERA_IMAGE_CAPTURED"])
        if m is None:
            return found
        if m.get_type() == "CAMERA_FEEDBACK":
            found.append((m.lat / 1e7, m.lng / 1e7, m.alt_rel))
        else:
            found.append((m.lat / 1e7, m.lon / 1e7, m.relative_alt / 1000.0))


def main():
    args = sys.argv[1:]
    plan_file, plan_json, fly_json = args[:3]
    legs_within = float(args[args.index("--legs-within") + 1]) if "--legs-within" in args else 10.0
    problems = []
    report = json.load(open(fly_json))
    tlog = os.path.join(report["log_dir"], "flight.tlog")
    wanted = photo_actions(plan_file)
    taken = photos_in(tlog)
    print(f"photos: {len(taken)} reported by the autopilot, {len(wanted)} photo actions")
    if len(taken) != len(wanted):
        problems.append(f"{len(taken)} photos reported for {len(wanted)} photo actions")
    used = set()
    for k, photo in enumerate(taken):
        d, nearest = min((distance_m(photo, w), i) for i, w in enumerate(wanted))
        print(f"  photo {k + 1} at {photo[0]:.7f}, {photo[1]:.7f}, {photo[2]:.2f} m: "
              f"{d:.2f} m from the waypoint of photo action {nearest + 1}")
        if d > PHOTO_WITHIN_M:
            problems.append(f"photo {k + 1} is {d:.2f} m from its waypoint (more than {PHOTO_WITHIN_M} m)")
        if nearest in used:
            problems.append(f"photo {k + 1}: a second photo at the waypoint of action {nearest + 1}")
        used.add(nearest)
    plan = json.load(open(plan_json))
    fast = [(l["from"], l["to"], l["speed_m_s"]) for l in plan["orders"][0]["legs"] if "speed_m_s" in l]
    if not fast:
        problems.append("the plan prices no leg at a speed a DO_CHANGE_SPEED set")
    legs = {(l["from"], l["to"]): l for l in report["legs"]}
    for a, b, speed in fast:
        leg = legs.get((a, b))
        error = leg.get("error_pct") if leg else None
        print(f"  leg {a} -> {b} at {speed} m/s: "
              f"{leg.get('predicted_kj') if leg else '-'} kJ predicted, "
              f"{leg.get('measured_kj') if leg else '-'} kJ measured, "
              f"{'-' if error is None else f'{error:+.1f}%'}")
        if error is None:
            problems.append(f"leg {a} -> {b} was not measured")
        elif abs(error) > legs_within:
            problems.append(f"leg {a} -> {b} at {speed} m/s is {error:+.1f}% off (more than {legs_within}%)")
    for p in problems:
        print(f"FAIL: {p}")
    if problems:
        sys.exit(1)
    print("ok: every photo at its waypoint, every leg after the speed change within "
          f"{legs_within}%")


if __name__ == "__main__":
    main()
