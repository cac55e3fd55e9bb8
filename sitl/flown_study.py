#!/usr/bin/env python3
"""The flown random-mission study's summary (sitl/flown-study.sh).

usage: flown_study.py WORK_DIR [--gate-pct P]

WORK_DIR holds one directory per mission, mK/, with mission.toml and energy/fly.json and
distance/fly.json (`emplan fly --json` of the two orders on ArduCopter SITL). For each mission it
prints the energy order's saving over the distance order, predicted (the prices fly flew with)
and measured (the battery), over the whole mission (take-off to landing) and over the legs alone;
then how often the energy order measured less, the mean savings, and the Pearson correlation and
least-squares slope of measured on predicted saving. A saving is 100 (D - E) / D: positive when
the energy order costs less. Writes WORK_DIR/flown-study.csv, flown-study.json and
flown-study.svg (measured against predicted mission saving, one point per mission).

--gate-pct P: fail unless every flight is complete with its legs measured and every mission
predicted to save at least P % over the mission measured less in the energy order.
"""
import json
import math
import os
import re
import sys

import check_orders


def flight(path):
    """check_orders.totals of one fly.json, or None and why it cannot be used."""
    if not os.path.exists(path):
        return None, "not flown"
    try:
        doc, problems = check_orders.totals(path)
    except (OSError, ValueError, KeyError) as e:
        return None, f"unreadable fly.json ({e})"
    if problems or None in doc["mission"]:
        return None, "; ".join(problems) or "no mission total"
    return doc, None


def profile_of(log_path):
    try:
        m = re.search(r"pricing with the (\w+) profile", open(log_path).read())
    except OSError:
        return None
    return m.group(1) if m else None


def saving(energy_kj, distance_kj):
    return 100.0 * (distance_kj - energy_kj) / distance_kj


def pearson(xs, ys):
    n = len(xs)
    if n < 3:
        return None, None
    mx, my = sum(xs) / n, sum(ys) / n
    sxx = sum((x - mx) ** 2 for x in xs)
    syy = sum((y - my) ** 2 for y in ys)
    sxy = sum((x - mx) * (y - my) for x, y in zip(xs, ys))
    if sxx == 0 or syy == 0:
        return None, None
    return sxy / math.sqrt(sxx * syy), sxy / sxx


def svg_scatter(rows, r, slope, path):
    """Measured against predicted mission saving, %, with the line measured = predicted."""
    w, h, left, right, top, bottom = 640, 540, 70, 20, 60, 60
    pts = [(row["predicted_saving_pct"], row["measured_saving_pct"]) for row in rows]
    lo = min([0.0] + [min(p) for p in pts]) - 1.0
    hi = max([1.0] + [max(p) for p in pts]) + 1.0
    lo, hi = math.floor(lo), math.ceil(hi)

    def sx(v):
        return left + (v - lo) / (hi - lo) * (w - left - right)

    def sy(v):
        return h - bottom - (v - lo) / (hi - lo) * (h - top - bottom)

    out = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{w}" height="{h}" '
           f'font-family="sans-serif" font-size="12">',
           f'<rect width="{w}" height="{h}" fill="white"/>']
    step = 2 if hi - lo <= 24 else 5
    for v in range(int(lo), int(hi) + 1):
        if v % step:
            continue
        out.append(f'<line x1="{sx(v):.1f}" y1="{sy(lo):.1f}" x2="{sx(v):.1f}" y2="{sy(hi):.1f}" '
                   'stroke="#eee"/>')
        out.append(f'<line x1="{sx(lo):.1f}" y1="{sy(v):.1f}" x2="{sx(hi):.1f}" y2="{sy(v):.1f}" '
                   'stroke="#eee"/>')
        out.append(f'<text x="{sx(v):.1f}" y="{h - bottom + 16}" text-anchor="middle">{v}</text>')
        out.append(f'<text x="{left - 6}" y="{sy(v) + 4:.1f}" text-anchor="end">{v}</text>')
    out.append(f'<rect x="{left}" y="{top}" width="{w - left - right}" height="{h - top - bottom}" '
               'fill="none" stroke="black"/>')
    out.append(f'<line x1="{sx(lo):.1f}" y1="{sy(lo):.1f}" x2="{sx(hi):.1f}" y2="{sy(hi):.1f}" '
               'stroke="#888" stroke-dasharray="5,4"/>')
    out.append(f'<line x1="{sx(lo):.1f}" y1="{sy(0):.1f}" x2="{sx(hi):.1f}" y2="{sy(0):.1f}" '
               'stroke="#c33"/>')
    for row in rows:
        x, y = row["predicted_saving_pct"], row["measured_saving_pct"]
        colour = "#1f5fbf" if y > 0 else "#c33"
        out.append(f'<circle cx="{sx(x):.1f}" cy="{sy(y):.1f}" r="4" fill="{colour}">'
                   f'<title>mission {row["mission"]}: predicted {x:.1f}%, measured {y:.1f}%</title>'
                   '</circle>')
    wins = sum(1 for row in rows if row["measured_saving_pct"] > 0)
    corr = f", r = {r:.2f}, slope {slope:.2f}" if r is not None else ""
    out.append(f'<text x="{w / 2}" y="22" text-anchor="middle" font-size="14">ArduCopter SITL: '
               'the energy order\'s saving over the distance order</text>')
    out.append(f'<text x="{w / 2}" y="42" text-anchor="middle" font-size="13">{len(rows)} missions, '
               f'{wins} measured less{corr}</text>')
    out.append(f'<text x="{(left + w - right) / 2}" y="{h - 18}" text-anchor="middle">predicted '
               'saving, % of the distance order\'s mission energy (dashed: measured = predicted)'
               '</text>')
    out.append(f'<text transform="translate(18,{(top + h - bottom) / 2}) rotate(-90)" '
               'text-anchor="middle">measured saving, % (red line: no saving)</text>')
    out.append('</svg>')
    with open(path, "w") as f:
        f.write("\n".join(out) + "\n")


def main():
    args = sys.argv[1:]
    gate = None
    if "--gate-pct" in args:
        i = args.index("--gate-pct")
        gate = float(args[i + 1])
        del args[i:i + 2]
    if len(args) != 1:
        sys.exit(__doc__)
    work = args[0]
    missions = sorted(
        (int(m.group(1)), d) for d in os.listdir(work)
        if (m := re.fullmatch(r"m(\d+)", d)) and os.path.isdir(os.path.join(work, d)))
    rows, problems, profiles = [], [], set()
    for k, d in missions:
        base = os.path.join(work, d)
        e, e_why = flight(os.path.join(base, "energy", "fly.json"))
        dist, d_why = flight(os.path.join(base, "distance", "fly.json"))
        for order in ("energy", "distance"):
            p = profile_of(os.path.join(base, f"{order}.log"))
            if p:
                profiles.add(p)
        if e is None or dist is None:
            why = "; ".join(f"{o} order: {w}" for o, w in (("energy", e_why), ("distance", d_why)) if w)
            problems.append(f"mission {k}: {why}")
            print(f"mission {k}: not compared ({why})")
            continue
        rows.append({
            "mission": k,
            "energy_order": e["order"],
            "distance_order": dist["order"],
            "same_order": e["order"] == dist["order"],
            "energy_predicted_kj": e["mission"][0],
            "distance_predicted_kj": dist["mission"][0],
            "energy_measured_kj": e["mission"][1],
            "distance_measured_kj": dist["mission"][1],
            "predicted_saving_pct": saving(e["mission"][0], dist["mission"][0]),
            "measured_saving_pct": saving(e["mission"][1], dist["mission"][1]),
            "legs_predicted_saving_pct": saving(e["legs"][0], dist["legs"][0]),
            "legs_measured_saving_pct": saving(e["legs"][1], dist["legs"][1]),
        })
    print(f"priced with the {', '.join(sorted(profiles)) or 'unknown'} profile; saving = "
          "100 (distance - energy) / distance, positive when the energy order costs less")
    print(f"{'mission':>7} {'E pred kJ':>9} {'D pred kJ':>9} {'E meas kJ':>9} {'D meas kJ':>9} "
          f"{'saving pred':>11} {'meas':>7} {'legs pred':>9} {'meas':>7}  note")
    for row in rows:
        note = "same order" if row["same_order"] else ("" if row["measured_saving_pct"] > 0
                                                      else "ENERGY ORDER NOT LESS")
        print(f"{row['mission']:>7} {row['energy_predicted_kj']:>9.2f} "
              f"{row['distance_predicted_kj']:>9.2f} {row['energy_measured_kj']:>9.2f} "
              f"{row['distance_measured_kj']:>9.2f} {row['predicted_saving_pct']:>+10.1f}% "
              f"{row['measured_saving_pct']:>+6.1f}% {row['legs_predicted_saving_pct']:>+8.1f}% "
              f"{row['legs_measured_saving_pct']:>+6.1f}%  {note}")
    summary = {"missions": len(rows), "profiles": sorted(profiles), "problems": problems}
    if rows:
        differ = [row for row in rows if not row["same_order"]]
        wins = sum(1 for row in differ if row["measured_saving_pct"] > 0)
        pred = [row["predicted_saving_pct"] for row in rows]
        meas = [row["measured_saving_pct"] for row in rows]
        r, slope = pearson(pred, meas)
        summary.update({
            "orders_differ": len(differ),
            "energy_order_measured_less": wins,
            "mean_predicted_saving_pct": sum(pred) / len(pred),
            "mean_measured_saving_pct": sum(meas) / len(meas),
            "pearson_r": r,
            "slope": slope,
        })
        print(f"{len(rows)} missions, the orders differ on {len(differ)}: the energy order "
              f"measured less on {wins} of {len(differ)}")
        print(f"mean saving predicted {summary['mean_predicted_saving_pct']:+.1f}%, measured "
              f"{summary['mean_measured_saving_pct']:+.1f}%"
              + (f"; measured against predicted: r = {r:.3f}, slope {slope:.2f}" if r is not None
                 else ""))
        with open(os.path.join(work, "flown-study.csv"), "w") as f:
            keys = list(rows[0].keys())
            f.write(",".join(keys) + "\n")
            for row in rows:
                f.write(",".join(f"{row[k]:.4f}" if isinstance(row[k], float) else str(row[k])
                                 for k in keys) + "\n")
        svg_scatter(rows, r, slope, os.path.join(work, "flown-study.svg"))
    with open(os.path.join(work, "flown-study.json"), "w") as f:
        json.dump({"summary": summary, "missions": rows}, f, indent=1)
    if gate is not None:
        failed = list(problems)
        for row in rows:
            if row["predicted_saving_pct"] >= gate and not row["measured_saving_pct"] > 0:
                failed.append(f"mission {row['mission']}: predicted to save "
                              f"{row['predicted_saving_pct']:.1f}%, measured "
                              f"{row['measured_saving_pct']:+.1f}%")
        if not rows:
            failed.append("no mission was compared")
        if failed:
            sys.exit("FAIL:\n  " + "\n  ".join(failed))
        gated = sum(1 for row in rows if row["predicted_saving_pct"] >= gate)
        print(f"ok: every mission predicted to save {gate:g}% or more ({gated} of {len(rows)}) "
              "measured less in the energy order")


if __name__ == "__main__":
    main()
