#!/usr/bin/env python3
"""Compares two flights of one mission: its energy order and its distance order.

usage: check_orders.py ENERGY_FLY.json DISTANCE_FLY.json

Each is `emplan fly --json` (sitl/ardupilot-fly.sh's fly.json). Both must be complete with every
leg measured; prints what each order was predicted and measured to cost, over the whole mission
(take-off to landing) and over its legs alone, and the energy order's saving, predicted and
measured. Fails unless the energy order measured less than the distance order over the mission.
"""
import json
import sys


def totals(path):
    doc = json.load(open(path))
    problems = []
    if not doc.get("complete"):
        problems.append(f"{path}: the flight is not complete")
    legs = doc.get("legs") or []
    if not legs or any(l.get("measured_kj") is None for l in legs):
        problems.append(f"{path}: a leg is not measured")
    total = doc.get("total") or {}
    order = " ".join([legs[0]["from"]] + [l["to"] for l in legs]) if legs else "-"
    return {
        "order": order,
        "mission": (total.get("predicted_kj"), total.get("measured_kj")),
        "legs": (sum(l.get("predicted_kj") or 0 for l in legs),
                 sum(l.get("measured_kj") or 0 for l in legs)),
    }, problems


def saving(energy, distance):
    if energy is None or distance is None or distance <= 0:
        return None
    return (energy - distance) / distance * 100


def main():
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    energy, p1 = totals(sys.argv[1])
    distance, p2 = totals(sys.argv[2])
    problems = p1 + p2
    print(f"energy order:   {energy['order']}")
    print(f"distance order: {distance['order']}")
    print(f"{'':<10} {'order':<9} {'predicted_kj':>12} {'measured_kj':>12}")
    for what in ("mission", "legs"):
        for name, doc in (("energy", energy), ("distance", distance)):
            p, m = doc[what]
            print(f"{what:<10} {name:<9} {p or 0:>12.3f} {m or 0:>12.3f}")
        ps = saving(energy[what][0], distance[what][0])
        ms = saving(energy[what][1], distance[what][1])
        fmt = lambda x: f"{x:+.1f}%" if x is not None else "-"
        print(f"{what:<10} the energy order's saving: predicted {fmt(ps)}, measured {fmt(ms)}")
    if energy["order"] == distance["order"]:
        problems.append("the two flights flew the same order")
    em, dm = energy["mission"][1], distance["mission"][1]
    if em is None or dm is None or not em < dm:
        problems.append(f"the energy order measured {em} kJ, not less than the distance order's {dm} kJ")
    if problems:
        sys.exit("FAIL:\n  " + "\n  ".join(problems))
    print("ok: the energy order measured less than the distance order")


if __name__ == "__main__":
    main()
