"""Fly `fly`'s mission layout on PX4 SITL and print what PX4 reports, with PX4's own clock.

Uploads take-off (20 m), three waypoints (hold 3 s), a waypoint at the origin (hold 0) and LAND
at the origin, arms, sends MAV_CMD_MISSION_START and prints every change of MISSION_CURRENT
(seq, total, mission_state, mission_mode), EXTENDED_SYS_STATE landed state, armed flag and
custom mode, each MISSION_ITEM_REACHED, and the relative altitude near the ground, stamped with
time_boot_ms. The mock autopilot's PX4 flavour (src/sim/vehicle.rs) follows what this showed.

Usage (pymavlink installed; PX4 SITL running, see sitl/README.md):
    python3 sitl/px4_fly_land.py [udpin:127.0.0.1:14550]
"""
import math
import sys
import time

from pymavlink import mavutil

URL = sys.argv[1] if len(sys.argv) > 1 else "udpin:127.0.0.1:14550"
LAT0, LON0 = 38.5362, -121.7875  # PX4_HOME_LAT/LON of ../shared/sitl/px4
R = mavutil.mavlink
NAN = float("nan")

m = mavutil.mavlink_connection(URL, source_system=255, source_component=190)
m.wait_heartbeat(timeout=60)
state = dict(armed=None, landed=None, current=None, boot=0, alt=None)


def say(*what):
    print(f"boot {state['boot'] / 1000:8.2f} s", *what, flush=True)


def at(east_m, north_m):
    lat = LAT0 + north_m / 111_111.0
    lon = LON0 + east_m / (111_111.0 * math.cos(math.radians(LAT0)))
    return int(round(lat * 1e7)), int(round(lon * 1e7))


items = [(R.MAV_CMD_NAV_TAKEOFF, [0, 0, 0, NAN], (0, 0), 20.0)]
for east, north, up in [(-20, 20, 30), (20, -20, 15), (12, 12, 25)]:
    items.append((R.MAV_CMD_NAV_WAYPOINT, [3, 2, 0, NAN], (east, north), up))
items.append((R.MAV_CMD_NAV_WAYPOINT, [0, 2, 0, NAN], (0, 0), 20.0))
items.append((R.MAV_CMD_NAV_LAND, [0, 0, 0, NAN], (0, 0), 0.0))

m.mav.mission_count_send(1, 1, len(items), 0)
deadline = time.time() + 20
while time.time() < deadline:
    msg = m.recv_match(type=["MISSION_REQUEST_INT", "MISSION_REQUEST", "MISSION_ACK"],
                       blocking=True, timeout=1)
    if msg is None:
        continue
    if msg.get_type() == "MISSION_ACK":
        print("upload ack", msg.type)
        break
    cmd, p, (east, north), z = items[msg.seq]
    x, y = at(east, north)
    m.mav.mission_item_int_send(1, 1, msg.seq, R.MAV_FRAME_GLOBAL_RELATIVE_ALT, cmd, 0, 1,
                                p[0], p[1], p[2], p[3], x, y, z, 0)

# Landed state at 20 Hz and position at 10 Hz, to time the landing.
for msgid, hz in [(245, 20), (33, 10)]:
    m.mav.command_long_send(1, 1, R.MAV_CMD_SET_MESSAGE_INTERVAL, 0, msgid, 1e6 / hz, 0, 0, 0, 0, 0)


def handle(msg):
    kind = msg.get_type()
    if kind == "GLOBAL_POSITION_INT":
        state["boot"] = msg.time_boot_ms
        alt = round(msg.relative_alt / 1000.0, 1)
        if state["armed"] and alt < 2 and alt != state["alt"]:
            say("relative altitude", alt, "m, vz", msg.vz, "cm/s")
        state["alt"] = alt
    elif kind == "HEARTBEAT" and msg.get_srcSystem() == 1 and msg.get_srcComponent() == 1:
        armed = bool(msg.base_mode & R.MAV_MODE_FLAG_SAFETY_ARMED)
        if armed != state["armed"]:
            say("armed", armed, "custom_mode", hex(msg.custom_mode))
            state["armed"] = armed
    elif kind == "EXTENDED_SYS_STATE" and msg.landed_state != state["landed"]:
        say("landed_state", msg.landed_state)
        state["landed"] = msg.landed_state
    elif kind == "MISSION_CURRENT":
        current = (msg.seq, msg.total, msg.mission_state, msg.mission_mode)
        if current != state["current"]:
            say("MISSION_CURRENT (seq, total, state, mode)", current)
            state["current"] = current
    elif kind == "MISSION_ITEM_REACHED":
        say("MISSION_ITEM_REACHED", msg.seq)
    elif kind == "COMMAND_ACK":
        say("COMMAND_ACK", msg.command, msg.result)
    elif kind == "STATUSTEXT":
        say("STATUSTEXT", msg.text)


def pump(seconds):
    end = time.time() + seconds
    while time.time() < end:
        msg = m.recv_match(blocking=True, timeout=0.2)
        if msg is not None:
            handle(msg)


pump(3)
# Arm, then start at once (armed and idle on the ground PX4 disarms after COM_DISARM_PRFLT).
m.mav.command_long_send(1, 1, R.MAV_CMD_COMPONENT_ARM_DISARM, 0, 1, 0, 0, 0, 0, 0, 0)
pump(0.3)
m.mav.command_long_send(1, 1, R.MAV_CMD_MISSION_START, 0, 0, 0, 0, 0, 0, 0, 0)
flew = False
deadline = time.time() + 240
while time.time() < deadline:
    pump(1)
    flew |= bool(state["armed"])
    if flew and not state["armed"]:
        pump(3)
        break
say("done")
