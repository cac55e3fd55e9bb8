#!/usr/bin/env python3
"""Measures what a SITL autopilot takes and keeps of a mission's action commands.

For each action command (camera, gimbal, region of interest, yaw, payload, delay, speed, spline)
and each frame tried (2 MAV_FRAME_MISSION, 3 MAV_FRAME_GLOBAL_RELATIVE_ALT), uploads a mission of
take-off, a waypoint and that command (ArduPilot: with a home item 0 first), notes the upload's
MISSION_ACK, reads the mission back with MISSION_REQUEST_INT and prints, field by field, what was
sent and what came back. Writes the measurements in the format of tests/fixtures/actions/*.txt
(read by link::readback's tests and sim::storage's).

Usage: probe_actions.py CONNECTION NAME OUT
  CONNECTION: pymavlink address, e.g. tcp:127.0.0.1:5830 (ArduCopter SITL instance 7) or
  udpin:127.0.0.1:14550 (PX4 SITL); NAME: px4 or ardupilot (the autopilot, for the file's header);
  OUT: the measurement file written.
Needs pymavlink (MAVLINK20=1 is set here; dialect ardupilotmega). Start the SITL first
(sitl/probe-actions.sh does both).
"""
import math
import os
import sys
import time

os.environ["MAVLINK20"] = "1"
from pymavlink import mavutil  # noqa: E402

HOME = (385362000, -1217875000)
# The waypoint the actions follow, about 50 m north-east of home.
WP = (385366500, -1217869300)
# A location near the waypoint (a region of interest).
ROI = (385367000, -1217868000)

# (name, command, params p1..p4, x, y, z, has_position)
ACTIONS = [
    ("DO_DIGICAM_CONTROL shoot", 203, (1.0, 2.0, 0.0, 0.0), 1, 3, 0.0, False),
    ("IMAGE_START_CAPTURE one", 2000, (0.0, 0.0, 1.0, 0.0), 0, 0, 0.0, False),
    ("IMAGE_START_CAPTURE every 2.5 s", 2000, (0.0, 2.5, 3.0, 4.0), 0, 0, 0.0, False),
    ("IMAGE_STOP_CAPTURE", 2001, (0.0, 0.0, 0.0, 0.0), 0, 0, 0.0, False),
    ("VIDEO_START_CAPTURE", 2500, (0.0, 1.5, 0.0, 0.0), 0, 0, 0.0, False),
    ("VIDEO_STOP_CAPTURE", 2501, (0.0, 0.0, 0.0, 0.0), 0, 0, 0.0, False),
    ("DO_SET_CAM_TRIGG_DIST 12.5 m", 206, (12.5, 0.0, 1.0, 0.0), 0, 0, 0.0, False),
    ("DO_MOUNT_CONTROL pitch -90 yaw 30 mode 2", 205, (-90.0, 0.0, 30.0, 0.0), 0, 0, 2.0, False),
    ("DO_GIMBAL_MANAGER_PITCHYAW", 1000, (-45.5, 30.5, 0.0, 0.0), 0, 0, 0.0, False),
    ("DO_SET_ROI_LOCATION", 195, (0.0, 0.0, 0.0, 0.0), ROI[0], ROI[1], 10.55, True),
    ("DO_SET_ROI_NONE", 197, (0.0, 0.0, 0.0, 0.0), 0, 0, 0.0, False),
    ("DO_SET_ROI location", 201, (3.0, 0.0, 0.0, 0.0), ROI[0], ROI[1], 10.55, True),
    ("CONDITION_YAW 90 at 20 cw", 115, (90.0, 20.0, 1.0, 0.0), 0, 0, 0.0, False),
    ("DO_SET_SERVO 9 1900", 183, (9.0, 1900.0, 0.0, 0.0), 0, 0, 0.0, False),
    ("DO_SET_RELAY 0 on", 181, (0.0, 1.0, 0.0, 0.0), 0, 0, 0.0, False),
    ("DO_GRIPPER 1 release", 211, (1.0, 0.0, 0.0, 0.0), 0, 0, 0.0, False),
    ("DO_WINCH length 2.5 rate 0.5", 42600, (1.0, 1.0, 2.5, 0.5), 0, 0, 0.0, False),
    ("NAV_DELAY 7.5 s", 93, (7.5, -1.0, -1.0, -1.0), 0, 0, 0.0, False),
    ("NAV_LOITER_TIME 12.5 s", 19, (12.5, 0.0, 0.0, 0.0), WP[0], WP[1], 25.55, True),
    ("DO_CHANGE_SPEED ground 8.5", 178, (1.0, 8.5, -1.0, 0.0), 0, 0, 0.0, False),
    ("NAV_SPLINE_WAYPOINT hold 2.5 s", 82, (2.5, 0.0, 0.0, 0.0), WP[0], WP[1], 25.55, True),
    # Fractions, and x, y, z set where the command has no position: what is kept of each.
    ("DO_DIGICAM_CONTROL fractions and z", 203, (1.5, 2.5, -3.5, 1.5), 1, 3, 3.5, False),
    ("IMAGE_START_CAPTURE fractions and x y z", 2000, (1.5, 2.5, 3.5, 4.5), 7, 8, 9.5, False),
    ("DO_MOUNT_CONTROL fractions", 205, (-45.5, 1.25, 30.75, 4.5), 7, 8, 2.0, False),
    ("DO_GIMBAL_MANAGER_PITCHYAW flags 12 gimbal 1", 1000, (-45.0, 30.0, 5.5, -6.5), 12, 8, 1.0, False),
    ("CONDITION_YAW fractions", 115, (90.5, 20.5, -1.0, 1.0), 7, 8, 9.5, False),
    ("DO_SET_SERVO fractions", 183, (9.5, 1900.5, 3.0, 4.0), 7, 8, 9.5, False),
    ("DO_SET_RELAY fractions", 181, (1.5, 1.0, 3.0, 4.0), 7, 8, 9.5, False),
    ("DO_GRIPPER fractions", 211, (1.5, 1.0, 3.0, 4.0), 7, 8, 9.5, False),
    ("DO_WINCH fractions", 42600, (1.5, 2.0, -2.5, 0.75), 7, 8, 9.5, False),
    ("NAV_DELAY fractions", 93, (7.5, 2.5, 3.5, 4.5), 7, 8, 9.5, False),
    ("DO_CHANGE_SPEED x y z", 178, (1.5, 8.5, 50.5, 4.0), 7, 8, 9.5, False),
    ("DO_SET_CAM_TRIGG_DIST fractions", 206, (12.5, 2.5, 1.5, 4.0), 7, 8, 9.5, False),
    ("VIDEO_START_CAPTURE fractions", 2500, (1.5, 2.5, 3.0, 4.0), 7, 8, 9.5, False),
    ("IMAGE_STOP_CAPTURE fractions", 2001, (1.5, 2.5, 3.0, 4.0), 7, 8, 9.5, False),
    ("VIDEO_STOP_CAPTURE fractions", 2501, (1.5, 2.5, 3.0, 4.0), 7, 8, 9.5, False),
    ("DO_SET_ROI_NONE fractions", 197, (1.5, 2.5, 3.0, 4.0), 7, 8, 9.5, False),
    ("DO_SET_ROI_LOCATION gimbal 1 and params", 195, (1.0, 2.5, 3.0, 4.0), ROI[0], ROI[1], 10.55, True),
    ("DO_SET_ROI location and params", 201, (3.0, 2.5, 3.0, 4.0), ROI[0], ROI[1], 10.55, True),
    ("NAV_LOITER_TIME heading radius ccw xtrack", 19, (12.5, 1.0, -20.5, 1.0), WP[0], WP[1], 25.55, True),
    ("NAV_SPLINE_WAYPOINT params", 82, (2.5, 1.5, 2.5, 3.5), WP[0], WP[1], 25.55, True),
]
FRAMES = (2, 3)
FIELDS = ("frame", "command", "param1", "param2", "param3", "param4", "x", "y", "z", "autocontinue")


class Item:
    def __init__(self, seq, frame, command, p, x, y, z, autocontinue=1):
        self.seq, self.frame, self.command = seq, frame, command
        self.param1, self.param2, self.param3, self.param4 = p
        self.x, self.y, self.z, self.autocontinue = x, y, z, autocontinue

    @staticmethod
    def of(msg):
        return Item(msg.seq, msg.frame, msg.command,
                    (msg.param1, msg.param2, msg.param3, msg.param4),
                    msg.x, msg.y, msg.z, msg.autocontinue)

    def line(self):
        def f(v):
            return "nan" if math.isnan(v) else repr(float(v))
        return " ".join([str(self.seq), str(self.frame), str(self.command),
                         f(self.param1), f(self.param2), f(self.param3), f(self.param4),
                         str(self.x), str(self.y), f(self.z), str(self.autocontinue)])


def mission(ardupilot, command, params, x, y, z, frame):
    items = []
    if ardupilot:
        items.append(Item(0, 0, 16, (0, 0, 0, 0), HOME[0], HOME[1], 16.0))
    items.append(Item(len(items), 3, 22, (0, 0, 0, math.nan), HOME[0], HOME[1], 20.0))
    items.append(Item(len(items), 3, 16, (0, 0, 0, math.nan), WP[0], WP[1], 25.0))
    items.append(Item(len(items), frame, command, params, x, y, z))
    return items


def recv(m, types, timeout):
    end = time.time() + timeout
    while time.time() < end:
        msg = m.recv_match(type=types, blocking=True, timeout=max(0.05, end - time.time()))
        if msg is not None and msg.get_srcSystem() == m.target_system:
            return msg
    return None


def upload(m, items):
    """The final MISSION_ACK type (or the first refusal), None on silence."""
    for attempt in range(20):
        m.mav.mission_count_send(m.target_system, m.target_component, len(items), 0)
        while True:
            msg = recv(m, ["MISSION_REQUEST_INT", "MISSION_REQUEST", "MISSION_ACK"], 3)
            if msg is None:
                return None
            if msg.get_type() == "MISSION_ACK":
                if msg.type == 4 and attempt < 19:  # NO_SPACE: ArduPilot's storage still booting
                    time.sleep(1)
                    break
                return msg.type
            it = items[msg.seq]
            m.mav.mission_item_int_send(m.target_system, m.target_component, it.seq, it.frame,
                                        it.command, 0, it.autocontinue, it.param1, it.param2,
                                        it.param3, it.param4, it.x, it.y, it.z, 0)
    return None


def download(m):
    for _ in range(5):
        m.mav.mission_request_list_send(m.target_system, m.target_component, 0)
        msg = recv(m, ["MISSION_COUNT", "MISSION_ACK"], 3)
        if msg is None:
            continue
        if msg.get_type() == "MISSION_ACK":  # ArduPilot: DENIED until its deferred final ack
            time.sleep(0.5)
            continue
        items = []
        for seq in range(msg.count):
            m.mav.mission_request_int_send(m.target_system, m.target_component, seq, 0)
            it = recv(m, ["MISSION_ITEM_INT"], 3)
            if it is None or it.seq != seq:
                break
            items.append(Item.of(it))
        if len(items) == msg.count:
            m.mav.mission_ack_send(m.target_system, m.target_component, 0, 0)
            return items
    raise SystemExit("no read-back")


def show(v):
    if isinstance(v, float):
        return "nan" if math.isnan(v) else f"{v:.7g}"
    return str(v)


def main():
    if len(sys.argv) != 4:
        raise SystemExit(__doc__)
    url, name, out = sys.argv[1:]
    ardupilot = name == "ardupilot"
    m = mavutil.mavlink_connection(url, source_system=255, source_component=190,
                                   dialect="ardupilotmega")
    hb = m.wait_heartbeat(timeout=60)
    if hb is None:
        raise SystemExit(f"no heartbeat on {url}")
    print(f"{name}: heartbeat from system {m.target_system} autopilot {hb.autopilot}")
    lines = [f"# {name}: what the SITL answered (sitl/probe_actions.py {url} {name} ...)",
             "# case: command frame ack label; then the items sent and (if accepted) read, one a line:",
             "# seq frame command param1 param2 param3 param4 x y z autocontinue"]
    for label, command, params, x, y, z, positional in ACTIONS:
        for frame in FRAMES:
            items = mission(ardupilot, command, params, x, y, z, frame)
            ack = upload(m, items)
            verdict = "ACCEPTED" if ack == 0 else f"REFUSED (MISSION_ACK type {ack})"
            print(f"\n{label} ({command}) in frame {frame}: {verdict}")
            lines.append(f"case {command} {frame} {ack if ack is not None else -1} {label}")
            lines.extend("sent " + s.line() for s in items)
            if ack != 0:
                continue
            read = download(m)
            if len(read) != len(items):
                print(f"  read back {len(read)} items, sent {len(items)}")
                continue
            sent, got = items[-1], read[-1]
            for field in FIELDS:
                a, b = getattr(sent, field), getattr(got, field)
                same = (a == b) or (isinstance(a, float) and math.isnan(a) and math.isnan(b))
                print(f"  {field:12} sent {show(a):>14}  read {show(b):>14}{'' if same else '  *'}")
            lines.extend("read " + r.line() for r in read)
    with open(out, "w") as f:
        f.write("\n".join(lines) + "\n")
    print(f"\nwritten {out}")


if __name__ == "__main__":
    main()
