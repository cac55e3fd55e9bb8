#!/usr/bin/env python3
"""Checks a flight measured from the flight controller's own log (docs/onboard-logs.md).

usage: check_onboard.py SOURCES.json [--within PCT]
       check_onboard.py --report REPORT.json [--format ulog|dataflash]

SOURCES.json is what `emplan report FLIGHT_DIR --onboard LOG --json` printed: the flight's .tlog
and the autopilot's own log measured against the same plan, leg by leg. Fails unless every leg
has both measurements, |difference_pct| <= PCT (default 3) on every leg, the .tlog report says
`source.format` "tlog" and the onboard one "ulog" or "dataflash". Prints the per-leg table.

--report REPORT.json is what `emplan report LOG.bin|LOG.ulg --json` printed (the log alone, its
plan from the log's CMD records or --mission): fails unless every leg was found (the legs chain
origin -> ... -> origin) and measured (a number, no fake_current or unmeasurable flag), the
flight is complete and the source is the flight controller's log (of --format when given).
"""
import json
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from check_report import flight_problems  # noqa: E402

ONBOARD = ("ulog", "dataflash")


def num(x, spec):
    return format(x, spec) if x is not None else "-".rjust(len(format(0.0, spec)))


def source_format(report):
    return (report.get("source") or {}).get("format")


def check_report(doc, fmt):
    problems = []
    legs = doc.get("legs") or []
    source = doc.get("source") or {}
    print(f"source: {source.get('format')}, battery {source.get('battery_hz')} Hz"
          + (f", torn: {source['tear']}" if source.get("tear") else ""))
    print(f"{'leg':<22} {'predicted_kj':>12} {'measured_kj':>12} {'error':>8}  flags")
    for leg in legs:
        name = f"{leg['from']} -> {leg['to']}"
        err = leg.get("error_pct")
        print(f"{name:<22} {num(leg.get('predicted_kj'), '12.3f')} "
              f"{num(leg.get('measured_kj'), '12.3f')} "
              f"{(f'{err:+.1f}%' if err is not None else '-'):>8}  {','.join(leg['flags'])}")
        if leg.get("measured_kj") is None or {"fake_current", "unmeasurable"} & set(leg["flags"]):
            problems.append(f"leg {name} not measured: {leg['flags']}")
    problems.extend(flight_problems(doc))
    got = source_format(doc)
    if got not in ONBOARD or (fmt is not None and got != fmt):
        problems.append(f"source.format is {got!r}, not {fmt or ' or '.join(ONBOARD)}")
    if source.get("tear"):
        problems.append(f"the log tore: {source['tear']}")
    return problems


def check_sources(doc, within):
    problems = []
    tlog_fmt, onboard_fmt = source_format(doc.get("tlog") or {}), source_format(doc.get("onboard") or {})
    print(f"tlog: {tlog_fmt}, battery {(doc.get('tlog') or {}).get('source', {}).get('battery_hz')} Hz; "
          f"onboard: {onboard_fmt}, battery {(doc.get('onboard') or {}).get('source', {}).get('battery_hz')} Hz")
    if tlog_fmt != "tlog":
        problems.append(f"the tlog report's source.format is {tlog_fmt!r}, not 'tlog'")
    if onboard_fmt not in ONBOARD:
        problems.append(f"the onboard report's source.format is {onboard_fmt!r}, not ulog or dataflash")
    legs = doc.get("legs") or []
    if not legs:
        problems.append("no legs matched between the two logs")
    print(f"{'leg':<22} {'predicted_kj':>12} {'tlog_kj':>10} {'onboard_kj':>10} {'diff':>8} "
          f"{'tlog_s':>8} {'onboard_s':>9}")
    worst = 0.0
    for leg in legs:
        name = f"{leg['from']} -> {leg['to']}"
        diff = leg.get("difference_pct")
        print(f"{name:<22} {num(leg.get('predicted_kj'), '12.3f')} {num(leg.get('tlog_kj'), '10.3f')} "
              f"{num(leg.get('onboard_kj'), '10.3f')} "
              f"{(f'{diff:+.2f}%' if diff is not None else '-'):>8} "
              f"{num(leg.get('tlog_duration_s'), '8.1f')} {num(leg.get('onboard_duration_s'), '9.1f')}")
        if leg.get("tlog_kj") is None or leg.get("onboard_kj") is None:
            problems.append(f"leg {name}: not measured by both logs "
                            f"(tlog {leg.get('tlog_kj')}, onboard {leg.get('onboard_kj')})")
        elif diff is None or abs(diff) > within:
            problems.append(f"leg {name}: the onboard log differs from the tlog by {diff}% "
                            f"(beyond {within}%)")
        if diff is not None:
            worst = max(worst, abs(diff))
    print(f"worst |difference|: {worst:.2f}% (bound {within}%)")
    return problems


def main():
    args = sys.argv[1:]
    if not args:
        sys.exit(__doc__)

    def value(flag, default=None):
        return args[args.index(flag) + 1] if flag in args else default

    if "--report" in args:
        path = value("--report")
        with open(path) as f:
            problems = check_report(json.load(f), value("--format"))
    else:
        path = args[0]
        with open(path) as f:
            problems = check_sources(json.load(f), float(value("--within", "3")))
    if problems:
        sys.exit(f"FAIL ({path}):\n  " + "\n  ".join(problems))
    print(f"ok: {path}")


if __name__ == "__main__":
    main()
