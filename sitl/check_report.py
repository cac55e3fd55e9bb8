#!/usr/bin/env python3
"""Checks the report JSON `emplan fly --json` printed for a flight on a simulated autopilot.

usage: check_report.py REPORT.json [--unmeasurable] [--mission-within PCT] [--legs-within PCT]
                       [--px4-parameters]

Default: every leg was found (the legs chain origin -> ... -> origin) and measured (a number,
no fake_current or unmeasurable flag), the flight is complete (it landed), and its log directory
holds flight.tlog, samples.csv, plan.json and report.json. --unmeasurable instead requires every
leg to be found but flagged unmeasurable (no number). --mission-within / --legs-within bound the
errors against the prediction. --px4-parameters requires that emplan read every trajectory
parameter from PX4 (PARAM_REQUEST_READ) and prints the ones that differ from the vehicle file.
Prints the per-leg comparison either way.
"""
import json
import os
import sys


def flight_problems(doc):
    """What is wrong with a report's flight as a whole: its legs must run from the origin back
    to it, each starting where the one before ended, and the flight must have landed."""
    problems = []
    names = [(l["from"], l["to"]) for l in doc["legs"]]
    if not names or names[0][0] != "origin" or names[-1][1] != "origin":
        problems.append(f"the legs do not run from the origin back to it: {names}")
    if any(a[1] != b[0] for a, b in zip(names, names[1:])):
        problems.append(f"the legs do not chain: {names}")
    if not doc.get("complete"):
        problems.append("the flight is not complete (no landing seen)")
    return problems


def fmt_error(error):
    return f"{error:+.1f}%" if error is not None else "-"


def main():
    args = sys.argv[1:]
    path = args[0]
    unmeasurable = "--unmeasurable" in args
    def bound(flag):
        return float(args[args.index(flag) + 1]) if flag in args else None
    mission_pct, legs_pct = bound("--mission-within"), bound("--legs-within")
    with open(path) as f:
        doc = json.load(f)
    if not doc.get("ok", False) or "legs" not in doc:
        sys.exit(f"FAIL: the flight ended without a report: {doc.get('stage')}: {doc.get('error')}")
    legs = doc["legs"]
    problems = []
    print(f"{'leg':<22} {'predicted_kj':>12} {'measured_kj':>12} {'error':>8}  flags")
    for leg in legs:
        error = leg.get("error_pct")
        print(f"{leg['from'] + ' -> ' + leg['to']:<22} {leg['predicted_kj'] or 0:>12.3f} "
              f"{leg['measured_kj'] if leg['measured_kj'] is not None else float('nan'):>12.3f} "
              f"{fmt_error(error):>8}  {','.join(leg['flags'])}")
        if unmeasurable:
            if leg["measured_kj"] is not None or "unmeasurable" not in leg["flags"]:
                problems.append(f"leg {leg['from']} -> {leg['to']} has a number: {leg}")
        else:
            if leg["measured_kj"] is None or {"fake_current", "unmeasurable"} & set(leg["flags"]):
                problems.append(f"leg {leg['from']} -> {leg['to']} not measured: {leg['flags']}")
            if legs_pct is not None and (error is None or abs(error) > legs_pct):
                problems.append(f"leg {leg['from']} -> {leg['to']}: {error}% beyond {legs_pct}%")
    total = doc["total"]
    print(f"{'total':<22} {total['predicted_kj'] or 0:>12.3f} "
          f"{total['measured_kj'] if total['measured_kj'] is not None else float('nan'):>12.3f} "
          f"{fmt_error(total.get('error_pct')):>8}")
    problems.extend(flight_problems(doc))
    if mission_pct is not None:
        e = total.get("error_pct")
        if e is None or abs(e) > mission_pct:
            problems.append(f"mission energy {e}% beyond {mission_pct}%")
    if "--px4-parameters" in args:
        params = doc.get("px4_parameters")
        if params is None:
            problems.append("no px4_parameters in the report: emplan did not read PX4's parameters")
        else:
            print(f"PX4 parameters read: {params['read']}, unanswered: {params['unanswered']}, "
                  f"differing from the vehicle file: {params['differing']}")
            if params["unanswered"] or params["read"] == 0:
                problems.append(f"PX4 parameters not all read: {params}")
    log_dir = doc.get("log_dir", "")
    for name in ("flight.tlog", "samples.csv", "plan.json", "report.json"):
        if not os.path.isfile(os.path.join(log_dir, name)):
            problems.append(f"{name} missing from {log_dir}")
    if problems:
        sys.exit("FAIL:\n  " + "\n  ".join(problems))
    print(f"ok: {len(legs)} legs found and {'flagged unmeasurable' if unmeasurable else 'measured'}, "
          f"the log complete in {log_dir}")


if __name__ == "__main__":
    main()
