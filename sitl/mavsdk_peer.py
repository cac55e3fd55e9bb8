"""Independent peer test: MAVSDK's autopilot-side MissionRawServer (PyPI `mavsdk` 4.x) receives
an `emplan upload`, and the items MAVSDK received must equal the items emplan says it sent.

Usage: python sitl/mavsdk_peer.py EMPLAN_BINARY MISSION [PORT]
Exit 0 when emplan reports a verified upload (its read-back from MAVSDK matched) AND MAVSDK's
received mission equals emplan's items field by field; 1 otherwise.
"""

import json
import math
import subprocess
import sys
import threading
import time

from mavsdk import ComponentType, Configuration, Mavsdk
from mavsdk.plugins.mission_raw_server import MissionRawServer


def same(a, b):
    """Floats within 1e-4 relative (NaN equals NaN / null), integers exact."""
    if a is None or b is None or (isinstance(a, float) and math.isnan(a)) or (isinstance(b, float) and math.isnan(b)):
        norm = lambda v: v is None or (isinstance(v, float) and math.isnan(v))
        return norm(a) and norm(b)
    if isinstance(a, float) or isinstance(b, float):
        return abs(a - b) <= 1e-4 * max(abs(a), abs(b), 1.0)
    return a == b


def main():
    emplan, mission = sys.argv[1], sys.argv[2]
    port = int(sys.argv[3]) if len(sys.argv) > 3 else 14561
    received = []
    done = threading.Event()

    autopilot = Mavsdk(Configuration.create_with_component_type(ComponentType.AUTOPILOT))
    autopilot.add_any_connection(f"udpin://127.0.0.1:{port}")
    server = MissionRawServer(autopilot.server_component())

    def on_mission(result, plan, *_):
        received.clear()
        received.extend(plan.mission_items)
        print(f"mavsdk: incoming mission {result.name}, {len(plan.mission_items)} items", flush=True)
        done.set()

    server.subscribe_incoming_mission(on_mission)
    time.sleep(0.5)

    # MAVSDK's mission server sends no home and no position: the mission's origin is asked for
    # explicitly (emplan waits its 30 s for a home, then uploads with a warning).
    run = subprocess.run(
        [emplan, "upload", mission, "--connect", f"udpout:127.0.0.1:{port}", "--order", "energy", "--json", "--discover-s", "15", "--origin", "mission"],
        capture_output=True,
        text=True,
        timeout=120,
    )
    sys.stderr.write(run.stderr)
    if run.returncode != 0:
        print(f"FAIL: emplan upload exited {run.returncode}")
        return 1
    report = json.loads(run.stdout)
    sent = report["items"]
    if not report["report"]["verified"]:
        print("FAIL: emplan did not verify the upload")
        return 1
    if not done.wait(10):
        print("FAIL: MAVSDK never reported an incoming mission")
        return 1
    if len(received) != len(sent):
        print(f"FAIL: MAVSDK received {len(received)} items, emplan sent {len(sent)}")
        return 1
    fields = ["seq", "frame", "command", "autocontinue", "param1", "param2", "param3", "param4", "x", "y", "z"]
    for got, want in zip(received, sent):
        for f in fields:
            if not same(getattr(got, f), want[f]):
                print(f"FAIL: item {want['seq']} field {f}: MAVSDK received {getattr(got, f)!r}, emplan sent {want[f]!r}")
                return 1
    print(f"mavsdk peer: 1 passed, 0 failed ({len(sent)} items of {report['mission']} received exactly by MAVSDK "
          f"{report['autopilot']['flavour']} autopilot, emplan verified by read-back)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
