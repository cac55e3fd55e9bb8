#!/usr/bin/env python3
"""Check a fenced flight: no breach, every leg measured, and the straight order would have crossed.

Reads emplan's fly report (FLY_JSON), the flight.tlog it names (pymavlink, independently of
emplan's reader), the mission (a QGroundControl .plan with `geoFence` and `rallyPoints`) and
`emplan plan MISSION --order energy --json` (PLAN_JSON).

- No breach: the report has no `breaches`; no FENCE_STATUS from the autopilot with breach_status 1
  or a breach count above the first one seen; no STATUSTEXT naming a fence breach; the autopilot
  never in RTL (ArduCopter custom mode 6) while armed before the mission's last item; and every
  GLOBAL_POSITION_INT while armed and above 1 m outside every exclusion polygon and circle and
  inside every inclusion one (a 0.5 m tolerance for the position's own noise).
- Every leg measured: each of the report's legs has a measured_kj and no `incomplete` flag, and
  the report is complete.
- The straight order would have crossed: the energy order's waypoints joined by straight lines
  (origin, the sequence, origin; no via points) cross an exclusion zone.

Prints what it found. Exits 0 when all hold, 1 when one does not, 2 on bad usage or an unreadable
file.

Usage: check_fence.py FLY_JSON MISSION.plan PLAN_JSON
"""

import json
import math
import os
import sys

ARMED_FLAG = 128
ARDUCOPTER_RTL = 6
MAV_TYPE_GCS = 6
EARTH_M = 6371000.0


def local(lat0, lon0, lat, lon):
    """East, north (m) of (lat, lon) from (lat0, lon0), flat earth (fields of a few hundred m)."""
    north = math.radians(lat - lat0) * EARTH_M
    east = math.radians(lon - lon0) * EARTH_M * math.cos(math.radians(lat0))
    return east, north


def inside_polygon(p, poly):
    inside = False
    j = len(poly) - 1
    for i in range(len(poly)):
        a, b = poly[i], poly[j]
        if (a[1] > p[1]) != (b[1] > p[1]):
            x = a[0] + (p[1] - a[1]) / (b[1] - a[1]) * (b[0] - a[0])
            if p[0] < x:
                inside = not inside
        j = i
    return inside


def point_segment_m(p, a, b):
    dx, dy = b[0] - a[0], b[1] - a[1]
    n = dx * dx + dy * dy
    t = 0.0 if n == 0 else max(0.0, min(1.0, ((p[0] - a[0]) * dx + (p[1] - a[1]) * dy) / n))
    return math.hypot(p[0] - a[0] - t * dx, p[1] - a[1] - t * dy)


def segments_cross(a, b, c, d):
    def cross(o, p, q):
        return (p[0] - o[0]) * (q[1] - o[1]) - (p[1] - o[1]) * (q[0] - o[0])

    d1, d2, d3, d4 = cross(c, d, a), cross(c, d, b), cross(a, b, c), cross(a, b, d)
    return ((d1 > 0) != (d2 > 0)) and ((d3 > 0) != (d4 > 0)) and 0 not in (d1, d2, d3, d4)


def distance_to_boundary_m(p, zone):
    if zone["kind"] == "circle":
        return abs(math.hypot(p[0] - zone["center"][0], p[1] - zone["center"][1]) - zone["radius_m"])
    poly = zone["polygon"]
    return min(point_segment_m(p, poly[i], poly[(i + 1) % len(poly)]) for i in range(len(poly)))


def contains(zone, p):
    if zone["kind"] == "circle":
        return math.hypot(p[0] - zone["center"][0], p[1] - zone["center"][1]) <= zone["radius_m"]
    return inside_polygon(p, zone["polygon"])


def segment_enters(zone, a, b):
    """Whether the straight line a-b has a point inside the exclusion zone."""
    if contains(zone, a) or contains(zone, b):
        return True
    if zone["kind"] == "circle":
        return point_segment_m(zone["center"], a, b) <= zone["radius_m"]
    poly = zone["polygon"]
    return any(segments_cross(a, b, poly[i], poly[(i + 1) % len(poly)]) for i in range(len(poly)))


def mission(path):
    """The .plan's home, waypoints by name, and fence zones in the home's local frame."""
    with open(path) as f:
        plan = json.load(f)
    home = plan["mission"]["plannedHomePosition"]
    lat0, lon0 = home[0], home[1]
    items = [i for i in plan["mission"]["items"] if i.get("type") == "SimpleItem" and i.get("command") == 16]
    names = (plan.get("emplan") or {}).get("waypoint_names") or []
    if len(names) != len(items):
        # emplan's names for a .plan's waypoints without its own (src/mission/qgc_plan.rs).
        names = [f"WP{k + 1}" for k in range(len(items))]
    waypoints = {n: local(lat0, lon0, i["params"][4], i["params"][5]) for n, i in zip(names, items)}
    zones = []
    fence = plan.get("geoFence") or {}
    for k, p in enumerate(fence.get("polygons") or []):
        zones.append({
            "kind": "polygon",
            "inclusion": bool(p.get("inclusion", True)),
            "polygon": [local(lat0, lon0, v[0], v[1]) for v in p["polygon"]],
            "name": f"{'inclusion' if p.get('inclusion', True) else 'exclusion'} polygon {k + 1}",
        })
    for k, c in enumerate(fence.get("circles") or []):
        circle = c.get("circle") or {}
        zones.append({
            "kind": "circle",
            "inclusion": bool(c.get("inclusion", True)),
            "center": local(lat0, lon0, circle["center"][0], circle["center"][1]),
            "radius_m": float(circle["radius"]),
            "name": f"{'inclusion' if c.get('inclusion', True) else 'exclusion'} circle {k + 1}",
        })
    return (lat0, lon0), waypoints, zones


def read_tlog(tlog, lat0, lon0):
    from pymavlink import mavutil

    log = mavutil.mavlink_connection(tlog, dialect="ardupilotmega")
    autopilot = None
    armed = False
    s = {"fence": [], "texts": [], "rtl_armed": False, "positions": [], "current": None, "rtl_before_end": False}
    last_item = None
    while True:
        msg = log.recv_match(blocking=False)
        if msg is None:
            break
        kind = msg.get_type()
        if kind == "BAD_DATA":
            continue
        if kind == "HEARTBEAT" and msg.get_srcComponent() == 1 and msg.type != MAV_TYPE_GCS:
            autopilot = msg.get_srcSystem()
            armed = bool(msg.base_mode & ARMED_FLAG)
            if armed and msg.custom_mode == ARDUCOPTER_RTL:
                s["rtl_armed"] = True
            continue
        if autopilot is None or msg.get_srcSystem() != autopilot:
            continue
        if kind == "FENCE_STATUS":
            s["fence"].append((armed, msg.breach_status, msg.breach_count, msg.breach_type))
        elif kind == "STATUSTEXT":
            s["texts"].append(msg.text)
        elif kind == "MISSION_CURRENT":
            last_item = msg.seq
        elif kind == "GLOBAL_POSITION_INT" and armed and msg.relative_alt > 1000:
            s["positions"].append(local(lat0, lon0, msg.lat / 1e7, msg.lon / 1e7))
    s["last_item"] = last_item
    return s


def main(argv):
    if len(argv) != 4:
        print(__doc__.strip(), file=sys.stderr)
        return 2
    try:
        with open(argv[1]) as f:
            report = json.load(f)
        (lat0, lon0), waypoints, zones = mission(argv[2])
        with open(argv[3]) as f:
            plan = json.load(f)
        tlog = os.path.join(report["log_dir"], "flight.tlog")
        s = read_tlog(tlog, lat0, lon0)
    except (OSError, KeyError, ValueError, IndexError) as e:
        print(f"check_fence: {e}", file=sys.stderr)
        return 2
    failures = []
    exclusions = [z for z in zones if not z["inclusion"]]
    inclusions = [z for z in zones if z["inclusion"]]
    if not exclusions:
        failures.append(f"{argv[2]} has no exclusion zone")
    # No breach.
    if report.get("breaches"):
        failures.append(f"emplan's report flags {len(report['breaches'])} breach(es): {report['breaches']}")
    first_count = s["fence"][0][2] if s["fence"] else 0
    breached = [f for f in s["fence"] if f[1] == 1 or f[2] > first_count]
    if breached:
        failures.append(f"FENCE_STATUS says breached: {breached[0]}")
    texts = [t for t in s["texts"] if "fence" in t.lower() and "breach" in t.lower()]
    if texts:
        failures.append(f"the autopilot said {texts[0]!r}")
    if s["rtl_armed"]:
        failures.append("ArduCopter went into RTL while armed (FENCE_ACTION 1 on a breach)")
    tolerance_m = 0.5
    for p in s["positions"]:
        for z in exclusions:
            if contains(z, p) and distance_to_boundary_m(p, z) > tolerance_m:
                failures.append(f"the vehicle flew inside {z['name']} at east {p[0]:.1f} m, north {p[1]:.1f} m")
                break
        for z in inclusions:
            if not contains(z, p) and distance_to_boundary_m(p, z) > tolerance_m:
                failures.append(f"the vehicle flew outside {z['name']} at east {p[0]:.1f} m, north {p[1]:.1f} m")
                break
        if len(failures) > 10:
            break
    # Every leg measured.
    legs = report.get("legs") or []
    unmeasured = [f"{l['from']}->{l['to']}" for l in legs if l.get("measured_kj") is None or "incomplete" in l.get("flags", [])]
    if not legs or unmeasured:
        failures.append(f"legs not measured: {unmeasured or 'none found'}")
    if not report.get("complete"):
        failures.append("the report is not complete")
    # The straight energy order would have crossed an exclusion zone.
    sequence = plan["orders"][0]["sequence"]
    path = [(0.0, 0.0)] + [waypoints[n] for n in sequence] + [(0.0, 0.0)]
    crossed = [
        (a, b, z["name"])
        for a, b in zip(path, path[1:])
        for z in exclusions
        if segment_enters(z, a, b)
    ]
    print(
        f"{tlog}: {len(s['fence'])} FENCE_STATUS ({sum(1 for f in s['fence'] if f[0])} while armed), "
        f"{len(s['positions'])} positions while flying checked against {len(zones)} zone(s); "
        f"report legs {len(legs)}, breaches {len(report.get('breaches') or [])}; "
        f"the straight energy order ({' '.join(sequence)}) crosses an exclusion zone on {len(crossed)} leg(s)"
    )
    if not crossed:
        failures.append("the straight energy order crosses no exclusion zone: the test means nothing")
    for f in failures:
        print(f"check_fence: FAIL: {f}", file=sys.stderr)
    if not failures:
        print("check_fence: ok (no breach, every leg measured, the straight order would have crossed)")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
