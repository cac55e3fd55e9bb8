#!/usr/bin/env python3
"""Draws docs/figures/wind-study.svg from `emplan study --wind ... --json` documents.

usage: wind_study.py OUT.svg STUDY.json [STUDY.json ...]

Each STUDY.json is one setting's document (docs/json.md, "emplan study ... --wind"); their
"winds" rows are pooled. Two panels against the wind speed, one line per direction the wind
blows from: the share of missions whose minimum-energy order the wind changes, and the mean
saving of planning in the wind (the still-air order's price in the wind over the wind-aware
order's). A wind in which more than half the missions have a leg the vehicle cannot fly
(`infeasible_missions`) is left out: its statistics are of the few left. Plain SVG, no plotting
library.
"""
import json
import sys

COLOURS = ["#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#8c564b", "#e377c2", "#17becf"]


def main():
    if len(sys.argv) < 3:
        sys.exit(__doc__)
    rows = []
    title = ""
    for path in sys.argv[2:]:
        doc = json.load(open(path))
        title = (f"N={doc['waypoints']}, XY={doc['xy_m']:g} m, Z={doc['z_m']:g} m, "
                 f"{doc['winds'][0]['missions']} missions, seed {doc['seed']}, {doc['profile']} profile")
        rows += [r for r in doc["winds"] if 2 * r["infeasible_missions"] <= r["missions"]]
    directions = sorted({r["from_deg"] for r in rows})
    speeds = sorted({r["speed_m_s"] for r in rows})
    panels = [("order changed by the wind (% of missions)", lambda r: r["order_changed_pct"]),
              ("mean saving of planning in the wind (%)", lambda r: r["saving"]["mean_pct"])]
    w, h, pad = 420, 300, 50
    out = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{2 * w + 40}" height="{h + 90}" '
           f'font-family="sans-serif" font-size="12">',
           f'<text x="{w + 20}" y="18" text-anchor="middle" font-size="13">{title}</text>']
    for p, (label, value) in enumerate(panels):
        x0, y0 = 20 + p * (w + 20) + pad, 40
        pw, ph = w - pad - 10, h - pad
        top = max([value(r) for r in rows] + [1e-9]) * 1.1
        xmax = max(speeds) if speeds else 1
        sx = lambda s: x0 + pw * s / xmax
        sy = lambda v: y0 + ph - ph * v / top
        out.append(f'<rect x="{x0}" y="{y0}" width="{pw}" height="{ph}" fill="none" stroke="#444"/>')
        out.append(f'<text x="{x0 + pw / 2}" y="{y0 + ph + 35}" text-anchor="middle">wind speed (m/s)</text>')
        out.append(f'<text x="{x0 - 38}" y="{y0 + ph / 2}" text-anchor="middle" '
                   f'transform="rotate(-90 {x0 - 38} {y0 + ph / 2})">{label}</text>')
        for s in speeds:
            out.append(f'<text x="{sx(s)}" y="{y0 + ph + 15}" text-anchor="middle">{s:g}</text>')
        for k in range(5):
            v = top * k / 4
            out.append(f'<text x="{x0 - 5}" y="{sy(v) + 4}" text-anchor="end">{v:.1f}</text>')
            out.append(f'<line x1="{x0}" y1="{sy(v)}" x2="{x0 + pw}" y2="{sy(v)}" stroke="#ddd"/>')
        for i, d in enumerate(directions):
            pts = sorted((r["speed_m_s"], value(r)) for r in rows if r["from_deg"] == d)
            colour = COLOURS[i % len(COLOURS)]
            path = " ".join(f"{sx(s):.1f},{sy(v):.1f}" for s, v in pts)
            out.append(f'<polyline points="{path}" fill="none" stroke="{colour}" stroke-width="2"/>')
            for s, v in pts:
                out.append(f'<circle cx="{sx(s):.1f}" cy="{sy(v):.1f}" r="3" fill="{colour}"/>')
            if p == 0:
                out.append(f'<text x="{x0 + 10}" y="{y0 + 16 + 15 * i}" fill="{colour}">from {d:g} deg</text>')
    out.append("</svg>")
    open(sys.argv[1], "w").write("\n".join(out) + "\n")


if __name__ == "__main__":
    main()
