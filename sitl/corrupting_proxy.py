"""A MAVLink TCP proxy that changes one mission item on its way to the autopilot: the autopilot
then accepts and stores a mission that differs from what the ground station sent, and the
ground station's read-back must catch it.

Usage: python sitl/corrupting_proxy.py LISTEN_PORT AUTOPILOT_PORT SEQ
Listens on 127.0.0.1:LISTEN_PORT (one client), connects to 127.0.0.1:AUTOPILOT_PORT and forwards
both ways; every MISSION_ITEM_INT with seq SEQ from the client reaches the autopilot with its
latitude (x) 10 degE7 (about 1 m) north, re-encoded with the sender's ids and a valid checksum.
"""

import os
import select
import socket
import sys

os.environ["MAVLINK20"] = "1"
from pymavlink.dialects.v20 import ardupilotmega as mavlink  # noqa: E402


def main():
    listen, target, seq = int(sys.argv[1]), int(sys.argv[2]), int(sys.argv[3])
    server = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    server.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    server.bind(("127.0.0.1", listen))
    server.listen(1)
    print("listening", flush=True)
    client, _ = server.accept()
    autopilot = socket.create_connection(("127.0.0.1", target))
    parser = mavlink.MAVLink(None)
    parser.robust_parsing = True
    changed = 0
    while True:
        ready, _, _ = select.select([client, autopilot], [], [])
        if autopilot in ready:
            data = autopilot.recv(65536)
            if not data:
                break
            client.sendall(data)
        if client in ready:
            data = client.recv(65536)
            if not data:
                break
            out = b""
            for msg in parser.parse_buffer(data) or []:
                if msg.get_type() == "MISSION_ITEM_INT" and msg.seq == seq:
                    msg.x += 10
                    encoder = mavlink.MAVLink(None, srcSystem=msg.get_srcSystem(), srcComponent=msg.get_srcComponent())
                    encoder.seq = msg.get_seq()
                    out += msg.pack(encoder)
                    changed += 1
                    print(f"item {seq}: latitude changed on its way ({changed})", flush=True)
                else:
                    out += msg.get_msgbuf()
            if out:
                autopilot.sendall(out)


if __name__ == "__main__":
    main()
