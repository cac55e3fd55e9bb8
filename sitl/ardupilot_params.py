#!/usr/bin/env python3
"""Set ArduPilot parameters over MAVLink and read each one back.

Connects to a running autopilot (e.g. ArduCopter SITL's second port, tcp:127.0.0.1:5762), sends
PARAM_SET for every NAME=VALUE given, then PARAM_REQUEST_READ until the autopilot answers with
PARAM_VALUE holding that value (resending both on silence). Prints each value read back. Exits 0
when every parameter reads back as set, 1 when one does not within the time allowed, 2 on bad
usage.

Usage: ardupilot_params.py CONNECTION NAME=VALUE... [--timeout-s S]
"""

import sys
import time


def parse(argv):
    timeout_s = 60.0
    args = list(argv[1:])
    if "--timeout-s" in args:
        i = args.index("--timeout-s")
        timeout_s = float(args[i + 1])
        del args[i : i + 2]
    if len(args) < 2:
        raise ValueError("a connection and at least one NAME=VALUE are needed")
    wanted = []
    for pair in args[1:]:
        name, sep, value = pair.partition("=")
        if not sep or not name or len(name) > 16:
            raise ValueError(f"{pair}: not NAME=VALUE with a name of at most 16 characters")
        wanted.append((name, float(value)))
    return args[0], wanted, timeout_s


def connect(url, deadline):
    from pymavlink import mavutil

    while True:
        try:
            link = mavutil.mavlink_connection(url, source_system=254, source_component=190)
            break
        except OSError:
            # SITL opens its extra ports a moment after it starts.
            if time.time() > deadline:
                raise
            time.sleep(0.5)
    while time.time() < deadline:
        hb = link.recv_match(type="HEARTBEAT", blocking=True, timeout=1)
        if hb is not None and hb.get_srcComponent() == 1 and hb.type != mavutil.mavlink.MAV_TYPE_GCS:
            link.target_system = hb.get_srcSystem()
            link.target_component = 1
            return link
    raise TimeoutError(f"{url}: no autopilot heartbeat")


def set_and_read_back(link, name, value, deadline):
    from pymavlink import mavutil

    real32 = mavutil.mavlink.MAV_PARAM_TYPE_REAL32
    while time.time() < deadline:
        link.mav.param_set_send(link.target_system, link.target_component, name.encode(), value, real32)
        link.mav.param_request_read_send(link.target_system, link.target_component, name.encode(), -1)
        end = min(deadline, time.time() + 2)
        while time.time() < end:
            msg = link.recv_match(type="PARAM_VALUE", blocking=True, timeout=0.5)
            if msg is None or msg.param_id != name:
                continue
            if abs(msg.param_value - value) <= 1e-4 * max(1.0, abs(value)):
                return msg.param_value
    return None


def main(argv):
    try:
        url, wanted, timeout_s = parse(argv)
    except ValueError as e:
        print(f"ardupilot_params: {e}\n\n{__doc__.strip()}", file=sys.stderr)
        return 2
    deadline = time.time() + timeout_s
    try:
        link = connect(url, deadline)
    except (OSError, TimeoutError) as e:
        print(f"ardupilot_params: {e}", file=sys.stderr)
        return 1
    for name, value in wanted:
        read = set_and_read_back(link, name, value, deadline)
        if read is None:
            print(f"ardupilot_params: {name} did not read back as {value:g} within {timeout_s:g} s", file=sys.stderr)
            return 1
        print(f"{name} = {read:g} (read back)")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
