#!/usr/bin/env python3
"""Checks a flight of a mission with survey blocks on a simulated autopilot.

usage: check_survey.py PLAN.json FLY.json [--blocks-within PCT]

- Every block of the plan's energy order is in the flight's report, in the same direction,
  measured, and within PCT of its prediction.
- Each block took photos (its distance trigger on along its lines), and the photos pymavlink
  finds in the flight.tlog emplan wrote (CAMERA_FEEDBACK / CAMERA_IMAGE_CAPTURED) are at least
  the report's count over the blocks (the points take photos of their own).
"""
import json
import os
import sys

from pymavlink import mavutil


def photos_in(tlog):
    log = mavutil.mavlink_connection(tlog)
    n = 0
    while True:
        m = log.recv_match(type=["CAMERA_FEEDBACK", "CAMERA_IMAGE_CAPTURED"])
        if m is None:
            return n
        n += 1


def main():
    args = sys.argv[1:]
    plan_json, fly_json = args[:2]
    within = float(args[args.index("--blocks-within") + 1]) if "--blocks-within" in args else 10.0
    plan = json.load(open(plan_json))
    report = json.load(open(fly_json))
    planned = [(b["name"], b["reversed"]) for b in plan["orders"][0]["blocks"]]
    blocks = report.get("blocks") or []
    flown = [(b["name"], b["reversed"]) for b in blocks]
    failures = []
    if flown != planned:
        failures.append(f"blocks flown {flown}, planned {planned}")
    taken = 0
    for b in blocks:
        pred, meas, err = b.get("predicted_kj"), b.get("measured_kj"), b.get("error_pct")
        direction = "reversed" if b["reversed"] else "forward"
        shown = (f"predicted {pred:.2f} kJ, measured {meas:.2f} kJ ({err:+.1f}%)"
                 if None not in (pred, meas, err) else "not measured")
        print(f"block {b['name']} ({direction}) {b['from']} -> {b['to']}: {shown}, photos "
              f"{b['photos_taken']} of about {b['photos_expected']}")
        if meas is None or pred is None or err is None:
            failures.append(f"block {b['name']} not measured")
        elif abs(err) > within:
            failures.append(f"block {b['name']} measured {err:+.1f}% from its prediction")
        if b["photos_taken"] == 0:
            failures.append(f"block {b['name']} took no photos")
        taken += b["photos_taken"]
    tlog = os.path.join(report["log_dir"], "flight.tlog")
    in_tlog = photos_in(tlog)
    print(f"photos: {taken} along the blocks in the report, {in_tlog} in the .tlog")
    if in_tlog < taken:
        failures.append(f"the .tlog has {in_tlog} photos, fewer than the report's {taken}")
    if failures:
        print("FAIL: " + "; ".join(failures))
        sys.exit(1)
    print(f"OK: {len(blocks)} blocks flown as planned, each within {within}% of its prediction")


if __name__ == "__main__":
    main()
