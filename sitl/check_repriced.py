#!/usr/bin/env python3
"""Checks a flight re-priced with a calibrated vehicle (`emplan report FLIGHT --vehicle DIR --json`).

usage: check_repriced.py REPORT.json [--uncalibrated REPORT.json] [--vehicle-dir DIR]
                         [--legs-within PCT] [--mission-within PCT]

REPORT.json must say it was re-priced (`"priced_with"`, from --vehicle-dir when given), its
flight whole (check_report.flight_problems: the legs chain from the origin back to it, landed)
and every leg measured; --legs-within / --mission-within bound each leg's and the mission's
error against the re-priced prediction, as in check_report.py. Prints the flight part by part
priced with the calibrated vehicle and, with --uncalibrated, with that other report's vehicle
beside it (how far off it was).
"""
import json
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from check_report import flight_problems, fmt_error  # noqa: E402


def parts(doc):
    """(name, predicted_kj, measured_kj, error_pct) of each part: take-off, legs, the settles and
    holds at the points together, landing, total."""
    out = []
    if doc.get("takeoff"):
        t = doc["takeoff"]
        out.append(("take-off", t["predicted_kj"], t["measured_kj"], t.get("error_pct")))
    for leg in doc["legs"]:
        out.append((f"{leg['from']} -> {leg['to']}", leg["predicted_kj"], leg["measured_kj"],
                    leg.get("error_pct")))
    at = doc.get("at_points") or []
    if at:
        p = sum(a["predicted_kj"] or 0 for a in at)
        m = sum(a["measured_kj"] or 0 for a in at)
        out.append((f"settle + hover ({len(at)})", p, m, (m - p) / p * 100 if p else None))
    if doc.get("landing"):
        l = doc["landing"]
        out.append(("landing", l["predicted_kj"], l["measured_kj"], l.get("error_pct")))
    t = doc["total"]
    out.append(("total", t["predicted_kj"], t["measured_kj"], t.get("error_pct")))
    return out


def named(doc):
    p = doc.get("priced_with")
    return f"{p['vehicle']} ({p['dir']}, {p['profile']})" if p else "its plan's prices"


def main():
    args = sys.argv[1:]
    path = args[0]

    def option(flag, cast=str):
        return cast(args[args.index(flag) + 1]) if flag in args else None

    legs_pct, mission_pct = option("--legs-within", float), option("--mission-within", float)
    other_path, vehicle_dir = option("--uncalibrated"), option("--vehicle-dir")
    doc = json.load(open(path))
    other = json.load(open(other_path)) if other_path else None
    problems = list(flight_problems(doc))
    priced = doc.get("priced_with")
    if not priced:
        problems.append("the report does not say it was re-priced (no priced_with)")
    elif vehicle_dir and os.path.abspath(priced["dir"]) != os.path.abspath(vehicle_dir):
        problems.append(f"re-priced with {priced['dir']}, not {vehicle_dir}")
    print(f"flight {doc['flight']}: calibrated = {named(doc)}"
          + (f"; uncalibrated = {named(other)}" if other else ""))
    print(f"{'part':<24} {'measured_kj':>11} {'calibrated':>11} {'error':>8}"
          + (f" {'uncalibrated':>12} {'error':>8}" if other else ""))
    others = {name: (p, e) for name, p, _, e in parts(other)} if other else {}
    for name, p, m, e in parts(doc):
        line = (f"{name:<24} {m if m is not None else float('nan'):>11.3f} "
                f"{p if p is not None else float('nan'):>11.3f} {fmt_error(e):>8}")
        if other:
            op, oe = others.get(name, (None, None))
            line += f" {op if op is not None else float('nan'):>12.3f} {fmt_error(oe):>8}"
        print(line)
    for leg in doc["legs"]:
        error = leg.get("error_pct")
        if leg["measured_kj"] is None:
            problems.append(f"leg {leg['from']} -> {leg['to']} not measured: {leg['flags']}")
        elif legs_pct is not None and (error is None or abs(error) > legs_pct):
            problems.append(f"leg {leg['from']} -> {leg['to']}: {error:+.1f}% beyond {legs_pct}%")
    if mission_pct is not None:
        e = doc["total"].get("error_pct")
        if e is None or abs(e) > mission_pct:
            problems.append(f"mission energy {fmt_error(e)} beyond {mission_pct}%")
    if problems:
        sys.exit("FAIL:\n  " + "\n  ".join(problems))
    print(f"ok: every leg within {legs_pct}%, the mission within {mission_pct}% "
          f"of {named(doc)}")


if __name__ == "__main__":
    main()
