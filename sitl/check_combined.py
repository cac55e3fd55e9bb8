#!/usr/bin/env python3
"""Checks `emplan report --json` of several flights of one mission: the per-leg means.

usage: check_combined.py COMBINED.json --flights N [--legs-within PCT] [--mission-within PCT]
                         [--takeoff-within PCT] [--landing-within PCT]

Every leg must have been measured on all N flights, and with --legs-within the mean of its
measured energies must be within PCT of its prediction; --mission-within, --takeoff-within and
--landing-within hold the whole mission's mean (over the complete flights), the take-off's and
the landing's to their bounds. One flight's legs on PX4 SITL spread
with the moment PX4 was armed (docs/px4-sitl.md); the mean over flights armed at different
moments is what the `px4` profile's error is, so this bound is the one that catches a profile
that has drifted. Prints the per-leg comparison either way.
"""
import json
import sys


def main():
    args = sys.argv[1:]
    if not args or "--flights" not in args:
        sys.exit(__doc__)
    path = args[0]
    flights = int(args[args.index("--flights") + 1])
    def bound(name):
        return float(args[args.index(name) + 1]) if name in args else None
    legs_pct = bound("--legs-within")
    with open(path) as f:
        doc = json.load(f)
    legs = doc.get("legs") or []
    problems = []
    if len(doc.get("flights", [])) != flights:
        problems.append(f"{len(doc.get('flights', []))} flights combined, expected {flights}")
    if not legs:
        problems.append("no legs in the combined report")
    print(f"{'leg':<22} {'n':>3} {'predicted_kj':>12} {'mean_kj':>9} {'sd_kj':>7} {'min_kj':>7} "
          f"{'max_kj':>7} {'error':>8}")
    for leg in legs:
        name = f"{leg['from']} -> {leg['to']}"
        stats = leg.get("measured_stats_kj") or {}
        n = stats.get("n", 0)
        error = leg.get("error_pct")
        print(f"{name:<22} {n:>3} {leg['predicted_kj'] or 0:>12.3f} {stats.get('mean', float('nan')):>9.3f} "
              f"{stats.get('std', float('nan')):>7.3f} {stats.get('min', float('nan')):>7.3f} "
              f"{stats.get('max', float('nan')):>7.3f} "
              f"{(f'{error:+.1f}%' if error is not None else '-'):>8}")
        if n != flights:
            problems.append(f"leg {name} measured on {n} of {flights} flights")
        if legs_pct is not None and (error is None or abs(error) > legs_pct):
            problems.append(f"leg {name}: mean {error}% beyond {legs_pct}%")
    for key, option in (("takeoff", "--takeoff-within"), ("landing", "--landing-within"),
                        ("mission", "--mission-within")):
        part = doc.get(key)
        pct = bound(option)
        stats = (part or {}).get("measured_stats_kj") or {}
        error = (part or {}).get("error_pct")
        print(f"{key:<22} {stats.get('n', 0):>3} {(part or {}).get('predicted_kj') or 0:>12.3f} "
              f"{stats.get('mean', float('nan')):>9.3f} {stats.get('std', float('nan')):>7.3f} "
              f"{stats.get('min', float('nan')):>7.3f} {stats.get('max', float('nan')):>7.3f} "
              f"{(f'{error:+.1f}%' if error is not None else '-'):>8}")
        if pct is not None and (error is None or abs(error) > pct):
            problems.append(f"{key}: mean {error}% beyond {pct}%")
    if problems:
        sys.exit("FAIL:\n  " + "\n  ".join(problems))
    print(f"ok: {len(legs)} legs measured on all {flights} flights"
          + (f", each leg's mean within {legs_pct}%" if legs_pct is not None else "")
          + "".join(f", the {k} within {bound(o)}%" for k, o in (("mission", "--mission-within"),
                    ("take-off", "--takeoff-within"), ("landing", "--landing-within"))
                    if bound(o) is not None))


if __name__ == "__main__":
    main()
