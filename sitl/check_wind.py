#!/usr/bin/env python3
"""Reads sitl/ardupilot-wind.sh's flights: the per-leg wind / calm ratios, and the two orders.

usage: check_wind.py --ratios CALM.json WIND1.json [WIND2.json ...]
                     --still STILL1.json [...] --aware AWARE1.json [...] [--plan PLAN.json]

Each file is `emplan fly --json` (sitl/ardupilot-fly.sh's fly.json), every flight complete with
every leg measured.
- The ratio set flies one order in calm air and in each wind, each priced by emplan in its own
  wind: for every leg, the measured ratio (wind / calm) beside emplan's predicted ratio, and how
  often they agree on the leg getting dearer or cheaper.
- The orders: flights of the still-air energy order and of the wind-aware energy order, in the
  same wind. Prints each flight's measured mission and legs energy, the mean of each order, and
  the spread of each order's repeats (largest minus smallest). Fails unless the wind-aware order's
  mean measured mission energy is below the still-air order's, or the difference is within the
  larger of the two spreads (then says so).
- PLAN.json (`emplan plan --wind --json`): the legs' saving emplan predicted for the wind-aware
  order against the still-air order priced in the same wind, printed beside the measured one.
"""
import json
import sys


def load(path):
    doc = json.load(open(path))
    problems = []
    if not doc.get("complete"):
        problems.append(f"{path}: the flight is not complete")
    legs = doc.get("legs") or []
    if not legs or any(l.get("measured_kj") is None for l in legs):
        problems.append(f"{path}: a leg is not measured")
    return doc, problems


def sequence(doc):
    legs = doc.get("legs") or []
    return " ".join([legs[0]["from"]] + [l["to"] for l in legs]) if legs else "-"


def groups(argv):
    out, key = {}, None
    for a in argv:
        if a.startswith("--"):
            key = a[2:]
            out[key] = []
        elif key is None:
            sys.exit(__doc__)
        else:
            out[key].append(a)
    if not out.get("ratios") or len(out["ratios"]) < 2 or not out.get("still") or not out.get("aware"):
        sys.exit(__doc__)
    return out


def main():
    args = groups(sys.argv[1:])
    problems = []
    docs = {}
    for key in ("ratios", "still", "aware"):
        docs[key] = []
        for path in args[key]:
            doc, p = load(path)
            problems += p
            docs[key].append((path, doc))
    if problems:
        sys.exit("FAIL:\n  " + "\n  ".join(problems))

    calm_path, calm = docs["ratios"][0]
    calm_legs = calm["legs"]
    agree = total = 0
    errors = []
    for path, doc in docs["ratios"][1:]:
        legs = doc["legs"]
        if [(l["from"], l["to"]) for l in legs] != [(l["from"], l["to"]) for l in calm_legs]:
            sys.exit(f"FAIL: {path} flew other legs than {calm_path}")
        print(f"ratio wind / calm, {path}:")
        print(f"{'leg':<16} {'measured':>9} {'predicted':>9} {'difference':>10}")
        for c, w in zip(calm_legs, legs):
            m = w["measured_kj"] / c["measured_kj"]
            p = w["predicted_kj"] / c["predicted_kj"]
            total += 1
            agree += (m > 1) == (p > 1)
            errors.append((p - m) / m * 100)
            print(f"{c['from'] + ' -> ' + c['to']:<16} {m:>9.3f} {p:>9.3f} {100 * (p - m) / m:>+9.1f}%")
        mc, mw = calm["total"]["measured_kj"], doc["total"]["measured_kj"]
        pc, pw = calm["total"]["predicted_kj"], doc["total"]["predicted_kj"]
        print(f"{'mission':<16} {mw / mc:>9.3f} {pw / pc:>9.3f} {100 * (pw / pc - mw / mc) / (mw / mc):>+9.1f}%")
    print(f"legs whose ratio is on the same side of 1, measured and predicted: {agree} of {total}")
    print(f"predicted ratio against measured: {min(errors):+.1f}% to {max(errors):+.1f}%")

    def summary(key):
        flights = docs[key]
        missions = [d["total"]["measured_kj"] for _, d in flights]
        legs = [sum(l["measured_kj"] for l in d["legs"]) for _, d in flights]
        predicted = [d["total"]["predicted_kj"] for _, d in flights]
        orders = {sequence(d) for _, d in flights}
        return missions, legs, predicted, orders

    still = summary("still")
    aware = summary("aware")
    for name, (missions, legs, predicted, orders) in (("still-air order", still), ("wind-aware order", aware)):
        print(f"{name}: {' | '.join(sorted(orders))}")
        for k, (m, l, p) in enumerate(zip(missions, legs, predicted)):
            print(f"  flight {k + 1}: mission measured {m:.2f} kJ (predicted {p:.2f}), legs {l:.2f} kJ")
    if still[3] == aware[3]:
        sys.exit("FAIL: the two orders are the same order: nothing to compare")
    mean = lambda xs: sum(xs) / len(xs)
    spread = max(max(still[0]) - min(still[0]), max(aware[0]) - min(aware[0]))
    ms, ma = mean(still[0]), mean(aware[0])
    ls, la = mean(still[1]), mean(aware[1])
    print(f"mission, mean: still-air order {ms:.2f} kJ, wind-aware order {ma:.2f} kJ: "
          f"{100 * (ma - ms) / ms:+.2f}% (spread of repeats {spread:.2f} kJ, {100 * spread / ms:.2f}%)")
    print(f"legs, mean: still-air order {ls:.2f} kJ, wind-aware order {la:.2f} kJ: {100 * (la - ls) / ls:+.2f}%")
    if args.get("plan"):
        w = json.load(open(args["plan"][0])).get("wind") or {}
        if w.get("saving_pct") is not None:
            print(f"legs, predicted in the wind (plan --wind): still-air order "
                  f"{w['still_air_order']['energy_kj']:.2f} kJ, wind-aware order "
                  f"{w['still_air_order']['energy_kj'] - w['saving_kj']:.2f} kJ: "
                  f"{-w['saving_pct']:+.2f}%")
    if ma < ms:
        print("ok: the wind-aware order measured less than the still-air order in the same wind")
    elif ma - ms <= spread:
        print(f"ok (within the spread): the wind-aware order measured {ma - ms:.2f} kJ more, "
              f"within the {spread:.2f} kJ spread of the repeats")
    else:
        sys.exit(f"FAIL: the wind-aware order measured {ma:.2f} kJ, more than the still-air order's "
                 f"{ms:.2f} kJ by more than the spread of the repeats ({spread:.2f} kJ)")


if __name__ == "__main__":
    main()
