#!/usr/bin/env python3
"""Independent check of an emplan flight log with pymavlink.

Reads flight.tlog with pymavlink's mavutil.mavlink_connection (the reader MAVProxy and MAVExplorer
use), counts its BATTERY_STATUS messages and compares the count with the battery_status rows of
the samples.csv beside it. Exits 0 when they match, 1 when they differ, 2 on bad usage or an
unreadable file.

Usage: tlog_check.py FLIGHT_DIR | FLIGHT_TLOG [SAMPLES_CSV]
"""

import csv
import os
import sys


def count_battery_status(tlog):
    from pymavlink import mavutil

    log = mavutil.mavlink_connection(tlog, dialect="ardupilotmega")
    battery = 0
    total = 0
    last_stamp = None
    while True:
        msg = log.recv_match(blocking=False)
        if msg is None:
            break
        if msg.get_type() == "BAD_DATA":
            continue
        total += 1
        last_stamp = getattr(msg, "_timestamp", last_stamp)
        if msg.get_type() == "BATTERY_STATUS":
            battery += 1
    return battery, total, last_stamp


def count_rows(samples):
    with open(samples, newline="") as f:
        reader = csv.DictReader(f)
        if reader.fieldnames is None or "source" not in reader.fieldnames:
            raise ValueError(f"{samples}: not an emplan samples.csv (no 'source' column)")
        return sum(1 for row in reader if row["source"] == "battery_status")


def main(argv):
    if len(argv) not in (2, 3):
        print(__doc__.strip(), file=sys.stderr)
        return 2
    target = argv[1]
    if os.path.isdir(target):
        tlog = os.path.join(target, "flight.tlog")
        samples = os.path.join(target, "samples.csv")
    else:
        tlog = target
        samples = os.path.join(os.path.dirname(target) or ".", "samples.csv")
    if len(argv) == 3:
        samples = argv[2]
    try:
        battery, total, last_stamp = count_battery_status(tlog)
        rows = count_rows(samples)
    except (OSError, ValueError) as e:
        print(f"tlog_check: {e}", file=sys.stderr)
        return 2
    print(
        f"{tlog}: {total} messages read by pymavlink, {battery} BATTERY_STATUS "
        f"(last timestamp {last_stamp}); {samples}: {rows} battery_status rows"
    )
    if total == 0 or battery != rows:
        print("tlog_check: MISMATCH", file=sys.stderr)
        return 1
    print("tlog_check: ok")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
