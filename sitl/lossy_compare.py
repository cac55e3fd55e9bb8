"""Mission transfer over a bad radio, emplan beside two other ground stations, all against MAVSDK's
autopilot-side MissionRawServer (PyPI mavsdk 4.1.0) through a seeded relay that drops each UDP
datagram with probability p in each direction.

Clients, each uploading the same items and reading them back:
  emplan     `emplan upload MISSION --order listed --json` with its default settings
  mavsdk     MAVSDK 4.1.0's MissionRaw client: upload_mission() then download_mission()
  pymavlink  a plain pymavlink loop as a user would write it: resend after 1.5 s, 5 retries

A trial counts as "verified ok" when the client claims success (emplan: exit 0 with a verified
report; the others: upload accepted and the read-back equal to what was sent) AND the autopilot
holds exactly the items sent. A "false success" is a claim while the autopilot holds something
else. Usage (the venv with mavsdk and pymavlink: sitl/lossy-compare.sh makes it):

  python sitl/lossy_compare.py run [--trials 20] [--p 0.1,0.3] [--items 50] [--jobs 4]
                                   [--clients emplan,mavsdk,pymavlink] [--emplan BIN]
  python sitl/lossy_compare.py speed [--items 500] [--reps 5] [--emplan BIN]

Internal subcommands (one process each, so no client shares MAVSDK state with the server):
  serve PORT              the autopilot; prints one JSON line per incoming mission
  mavsdk-client PORT FILE / pymavlink-client PORT FILE   upload FILE's items (emplan's JSON)
"""

import argparse
import concurrent.futures
import json
import math
import os
import random
import select
import socket
import statistics
import subprocess
import sys
import tempfile
import threading
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
FIELDS = ["seq", "frame", "command", "autocontinue", "param1", "param2", "param3", "param4", "x", "y", "z"]


def same(a, b):
    """Floats within 1e-4 relative (NaN equals NaN / null), integers exact."""
    nan = lambda v: v is None or (isinstance(v, float) and math.isnan(v))
    if nan(a) or nan(b):
        return nan(a) and nan(b)
    if isinstance(a, float) or isinstance(b, float):
        return abs(a - b) <= 1e-4 * max(abs(a), abs(b), 1.0)
    return a == b


def same_items(got, want):
    return len(got) == len(want) and all(same(g[f], w[f]) for g, w in zip(got, want) for f in FIELDS)


def free_port():
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class Relay(threading.Thread):
    """UDP relay: the client talks to `listen`, the autopilot listens on `target`; each datagram
    is dropped with probability p, per direction, from a generator seeded with `seed`."""

    def __init__(self, listen, target, p, seed):
        super().__init__(daemon=True)
        self.p = p
        self.up = random.Random(seed * 2 + 1)
        self.down = random.Random(seed * 2 + 2)
        self.client_side = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.client_side.bind(("127.0.0.1", listen))
        self.server_side = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.server_side.bind(("127.0.0.1", 0))
        self.server_side.connect(("127.0.0.1", target))
        self.client = None
        self.stop = threading.Event()
        self.counts = {"up": 0, "up_dropped": 0, "down": 0, "down_dropped": 0}

    def run(self):
        while not self.stop.is_set():
            ready, _, _ = select.select([self.client_side, self.server_side], [], [], 0.1)
            for sock in ready:
                try:
                    data, addr = sock.recvfrom(65536)
                except OSError:
                    continue
                if sock is self.client_side:
                    self.client = addr
                    self.counts["up"] += 1
                    if self.up.random() < self.p:
                        self.counts["up_dropped"] += 1
                        continue
                    try:
                        self.server_side.send(data)
                    except OSError:
                        pass
                else:
                    self.counts["down"] += 1
                    if self.down.random() < self.p:
                        self.counts["down_dropped"] += 1
                        continue
                    if self.client is not None:
                        self.client_side.sendto(data, self.client)

    def close(self):
        self.stop.set()
        self.join(1)
        self.client_side.close()
        self.server_side.close()


def serve(port):
    from mavsdk import ComponentType, Configuration, Mavsdk
    from mavsdk.plugins.mission_raw_server import MissionRawServer

    autopilot = Mavsdk(Configuration.create_with_component_type(ComponentType.AUTOPILOT))
    autopilot.add_any_connection(f"udpin://127.0.0.1:{port}")
    server = MissionRawServer(autopilot.server_component())

    def on_mission(result, plan, *_):
        items = [{f: getattr(i, f) for f in FIELDS} for i in plan.mission_items]
        print(json.dumps({"result": result.name, "items": items}), flush=True)

    server.subscribe_incoming_mission(on_mission)
    print(json.dumps({"ready": True}), flush=True)
    while True:
        time.sleep(1)


def load_items(path):
    with open(path) as f:
        return json.load(f)


def mavsdk_client(port, path):
    from mavsdk import ComponentType, Configuration, Mavsdk
    from mavsdk.plugins.mission_raw import MissionItem, MissionRaw, MissionRawError

    want = load_items(path)
    gcs = Mavsdk(Configuration.create_with_component_type(ComponentType.GROUND_STATION))
    gcs.add_any_connection(f"udpout://127.0.0.1:{port}")
    out = {"claimed": False}
    system = gcs.first_autopilot(15.0)
    if system is None:
        out["error"] = "no autopilot"
    else:
        mission = MissionRaw(system)
        items = [
            MissionItem(
                w["seq"], w["frame"], w["command"], 1 if w["seq"] == 0 else 0, w["autocontinue"],
                *(float("nan") if w[p] is None else w[p] for p in ["param1", "param2", "param3", "param4"]),
                w["x"], w["y"], w["z"], 0,
            )
            for w in want
        ]
        started = time.monotonic()
        try:
            mission.upload_mission(items)
            out["upload_s"] = time.monotonic() - started
            read = mission.download_mission()
            out["verify_s"] = time.monotonic() - started - out["upload_s"]
            got = [{f: getattr(i, f) for f in FIELDS} for i in read]
            out["claimed"] = same_items(got, want)
            if not out["claimed"]:
                out["error"] = "read-back differs"
        except MissionRawError as e:
            out["error"] = str(e)
    print(json.dumps(out), flush=True)
    os._exit(0)  # MAVSDK's threads


def pymavlink_client(port, path, timeout_s=1.5, retries=5):
    """A plain pymavlink loop: resend the last message after 1.5 s, give up after 5 resends."""
    os.environ["MAVLINK20"] = "1"
    from pymavlink import mavutil

    want = load_items(path)
    m = mavutil.mavlink_connection(f"udpout:127.0.0.1:{port}", source_system=255, source_component=190)
    out = {"claimed": False}
    deadline = time.monotonic() + 15
    hb = None
    while hb is None and time.monotonic() < deadline:
        m.mav.heartbeat_send(6, 8, 0, 0, 0)
        hb = m.recv_match(type="HEARTBEAT", blocking=True, timeout=1)
    if hb is None:
        out["error"] = "no autopilot"
        print(json.dumps(out), flush=True)
        return
    ts, tc = hb.get_srcSystem(), hb.get_srcComponent()
    nan = lambda v: float("nan") if v is None else v

    def send_item(seq):
        w = want[seq]
        m.mav.mission_item_int_send(ts, tc, seq, w["frame"], w["command"], 0, w["autocontinue"],
                                    nan(w["param1"]), nan(w["param2"]), nan(w["param3"]), nan(w["param4"]),
                                    w["x"], w["y"], w["z"], 0)

    started = time.monotonic()
    # Upload.
    last = lambda: m.mav.mission_count_send(ts, tc, len(want), 0)
    last()
    tries = 0
    acked = False
    while True:
        msg = m.recv_match(type=["MISSION_REQUEST_INT", "MISSION_REQUEST", "MISSION_ACK"], blocking=True, timeout=timeout_s)
        if msg is None:
            tries += 1
            if tries > retries:
                out["error"] = "upload: no answer after 5 resends"
                break
            last()
            continue
        if msg.get_type() == "MISSION_ACK":
            if msg.type == 0:
                acked = True
            else:
                out["error"] = f"upload: refused {msg.type}"
            break
        if msg.seq < len(want):
            tries = 0
            seq = msg.seq
            last = lambda seq=seq: send_item(seq)
            last()
    if not acked:
        print(json.dumps(out), flush=True)
        return
    out["upload_s"] = time.monotonic() - started
    # Read-back.
    got = []
    tries = 0
    count = None
    while count is None:
        m.mav.mission_request_list_send(ts, tc, 0)
        msg = m.recv_match(type="MISSION_COUNT", blocking=True, timeout=timeout_s)
        if msg is not None:
            count = msg.count
        else:
            tries += 1
            if tries > retries:
                out["error"] = "read-back: no count"
                print(json.dumps(out), flush=True)
                return
    while len(got) < count:
        seq = len(got)
        m.mav.mission_request_int_send(ts, tc, seq, 0)
        msg = m.recv_match(type="MISSION_ITEM_INT", blocking=True, timeout=timeout_s)
        if msg is not None and msg.seq == seq:
            got.append({f: getattr(msg, f) for f in FIELDS})
            tries = 0
        elif msg is None:
            tries += 1
            if tries > retries:
                out["error"] = f"read-back: item {seq}: no answer after 5 resends"
                print(json.dumps(out), flush=True)
                return
    m.mav.mission_ack_send(ts, tc, 0, 0)
    out["verify_s"] = time.monotonic() - started - out["upload_s"]
    out["claimed"] = same_items(got, want)
    if not out["claimed"]:
        out["error"] = "read-back differs"
    print(json.dumps(out), flush=True)


class Server:
    """The MAVSDK autopilot in its own process; collects the missions it received."""

    def __init__(self, port):
        self.proc = subprocess.Popen(
            [sys.executable, __file__, "serve", str(port)],
            stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True,
        )
        self.missions = []
        self.ready = threading.Event()
        self.reader = threading.Thread(target=self._read, daemon=True)
        self.reader.start()
        self.ready.wait(15)

    def _read(self):
        for line in self.proc.stdout:
            try:
                doc = json.loads(line)
            except ValueError:
                continue
            if doc.get("ready"):
                self.ready.set()
            else:
                self.missions.append(doc)

    def held(self):
        """The mission the autopilot holds: the last one received completely."""
        done = [m for m in self.missions if m["result"] == "SUCCESS"]
        return done[-1]["items"] if done else None

    def stop(self):
        self.proc.terminate()
        try:
            self.proc.wait(5)
        except subprocess.TimeoutExpired:
            self.proc.kill()


def run_client(client, port, mission, items_file, emplan):
    started = time.monotonic()
    if client == "emplan":
        # MAVSDK's mission server says nothing of where it is: the mission's origin is asked for
        # explicitly (emplan waits its 30 s for a home, then uploads with a warning).
        cmd = [emplan, "upload", mission, "--connect", f"udpout:127.0.0.1:{port}", "--order", "listed",
               "--allow-infeasible", "--json", "--time-limit", "2", "--origin", "mission"]
    else:
        cmd = [sys.executable, __file__, f"{client}-client", str(port), items_file]
    try:
        run = subprocess.run(cmd, capture_output=True, text=True, timeout=400)
        text = run.stdout.strip().splitlines()
        doc = json.loads("\n".join(text) if client == "emplan" else text[-1]) if text else {}
    except (subprocess.TimeoutExpired, ValueError, IndexError) as e:
        return {"claimed": False, "error": f"client: {e}", "wall_s": time.monotonic() - started}
    if client == "emplan":
        ok = run.returncode == 0 and doc.get("report", {}).get("verified") is True
        out = {"claimed": ok}
        if ok:
            out["upload_s"] = doc["report"]["upload_s"]
            out["verify_s"] = doc["report"]["verify_s"]
        else:
            out["error"] = doc.get("error", run.stderr.strip()[-300:])
            out["stage"] = doc.get("stage")
            out["accepted"] = doc.get("accepted")
        doc = out
    doc["wall_s"] = time.monotonic() - started
    return doc


def trial(client, p, seed, mission, items_file, want, emplan, direct=False):
    """One upload and read-back through the relay (or `direct`ly to the autopilot)."""
    ap_port, relay_port = free_port(), free_port()
    server = Server(ap_port)
    relay = Relay(relay_port, ap_port, p, seed)
    relay.start()
    try:
        result = run_client(client, ap_port if direct else relay_port, mission, items_file, emplan)
        time.sleep(0.3)
    finally:
        relay.close()
        server.stop()
    held = server.held()
    result["holds"] = held is not None and same_items(held, want)
    result["ok"] = result["claimed"] and result["holds"]
    result["false_success"] = result["claimed"] and not result["holds"]
    result.update(client=client, p=p, seed=seed, relay=relay.counts)
    return result


def prepare(items, emplan, workdir):
    """A mission of `items` items (takeoff, waypoints, back over the origin, land) and the items
    emplan sends for it."""
    mission = os.path.join(workdir, f"lossy-{items}.toml")
    subprocess.run([emplan, "generate", mission, "--waypoints", str(items - 3), "--xy", "50", "--z", "20",
                    "--seed", "1"], check=True, capture_output=True)
    # A clean upload to the built-in mock gives the items (what every client then sends).
    run = subprocess.run([emplan, "upload", mission, "--order", "listed", "--allow-infeasible", "--json",
                          "--time-limit", "2"], check=True, capture_output=True, text=True)
    want = json.loads(run.stdout)["items"]
    items_file = os.path.join(workdir, f"lossy-{items}.json")
    with open(items_file, "w") as f:
        json.dump(want, f)
    assert len(want) == items, f"{len(want)} items"
    return mission, items_file, want


def table(results, ps, clients):
    lines = ["| client | " + " | ".join(f"p = {p}: verified ok | false successes" for p in ps) + " |",
             "|---|" + "---:|---:|" * len(ps)]
    for c in clients:
        cells = []
        for p in ps:
            rs = [r for r in results if r["client"] == c and r["p"] == p]
            cells.append(f"{sum(r['ok'] for r in rs)}/{len(rs)}")
            cells.append(f"{sum(r['false_success'] for r in rs)}")
        lines.append(f"| {c} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def main():
    parser = argparse.ArgumentParser()
    sub = parser.add_subparsers(dest="command", required=True)
    s = sub.add_parser("serve")
    s.add_argument("port", type=int)
    for name in ["mavsdk-client", "pymavlink-client"]:
        c = sub.add_parser(name)
        c.add_argument("port", type=int)
        c.add_argument("items")
    r = sub.add_parser("run")
    r.add_argument("--trials", type=int, default=20)
    r.add_argument("--p", default="0.1,0.3")
    r.add_argument("--items", type=int, default=50)
    r.add_argument("--jobs", type=int, default=4)
    r.add_argument("--clients", default="emplan,mavsdk,pymavlink")
    r.add_argument("--emplan", default=os.path.join(ROOT, "target/release/emplan"))
    r.add_argument("--json", help="write every trial's result to this file")
    sp = sub.add_parser("speed")
    sp.add_argument("--items", type=int, default=500)
    sp.add_argument("--reps", type=int, default=5)
    sp.add_argument("--clients", default="emplan,mavsdk,pymavlink")
    sp.add_argument("--emplan", default=os.path.join(ROOT, "target/release/emplan"))
    args = parser.parse_args()

    if args.command == "serve":
        return serve(args.port)
    if args.command == "mavsdk-client":
        return mavsdk_client(args.port, args.items)
    if args.command == "pymavlink-client":
        return pymavlink_client(args.port, args.items)

    workdir = tempfile.mkdtemp(prefix="emplan-lossy-")
    mission, items_file, want = prepare(args.items, args.emplan, workdir)
    clients = args.clients.split(",")
    if args.command == "speed":
        print(f"clean loopback, {args.items} items, MAVSDK MissionRawServer, {args.reps} runs each "
              f"(upload + read-back, median; emplan's from its report, without start-up and planning)")
        for c in clients:
            times = []
            for rep in range(args.reps):
                r = trial(c, 0.0, rep, mission, items_file, want, args.emplan, direct=True)
                if not r["ok"]:
                    print(f"  {c} run {rep} failed: {r.get('error')}")
                    continue
                times.append(r["upload_s"] + r["verify_s"])
            if times:
                print(f"  {c}: median {statistics.median(times) * 1e3:.1f} ms "
                      f"(upload + read-back; runs: {', '.join(f'{t * 1e3:.1f}' for t in times)})")
        return 0

    ps = [float(p) for p in args.p.split(",")]
    jobs = [(c, p, 1000 * k + t) for k, p in enumerate(ps) for c in clients for t in range(args.trials)]
    results = []
    with concurrent.futures.ThreadPoolExecutor(args.jobs) as pool:
        futures = {pool.submit(trial, c, p, seed, mission, items_file, want, args.emplan): (c, p, seed)
                   for c, p, seed in jobs}
        for f in concurrent.futures.as_completed(futures):
            r = f.result()
            results.append(r)
            flag = "ok" if r["ok"] else ("FALSE SUCCESS" if r["false_success"] else "failed")
            print(f"{r['client']:9} p={r['p']} seed={r['seed']}: {flag} ({r['wall_s']:.1f} s)"
                  + (f" {r.get('error', '')}"[:200] if not r["ok"] else ""), flush=True)
    if args.json:
        with open(args.json, "w") as f:
            json.dump(results, f, indent=1)
    print()
    print(f"{args.items} mission items, {args.trials} trials per cell, MAVSDK 4.1.0 MissionRawServer "
          f"behind a relay dropping each datagram with probability p each way (seeded):")
    print(table(results, ps, clients))
    return 0


if __name__ == "__main__":
    sys.exit(main())
