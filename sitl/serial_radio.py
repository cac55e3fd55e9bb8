#!/usr/bin/env python3
"""A telemetry radio on a serial pair: a pseudo-terminal for the ground station, a UDP link to
the autopilot, and between them a SiK-like radio's limits: a serial rate (57 600 baud, 8N1: 5 760
bytes a second), shared by both directions unless --full-duplex (a SiK radio shares its air time
between the two ends), a latency added to every frame, and a transmit buffer that drops whole
frames once it holds --buffer bytes (as a radio does when more is sent than it can carry).

usage: serial_radio.py AUTOPILOT_HOST:PORT [--baud 57600] [--latency-ms 100] [--buffer 2048]
                       [--full-duplex] [--device-file PATH] [--stats PATH]

Prints the ground station's device (/dev/pts/N) on its first line (and writes it to
--device-file), then relays until killed (SIGTERM or SIGINT), when it writes its counts (bytes
and frames each way, frames dropped, the most bytes queued, the share of the line in use) as
JSON to --stats and to standard error. MAVLink frames (v1 and v2, signed or not) are cut from the
serial byte stream so each reaches the autopilot as one datagram, as a ground station's UDP link
would send it; bytes between frames are counted and dropped. Standard library only.
"""

import heapq
import json
import os
import select
import signal
import socket
import sys
import termios
import time
import tty

V1, V2 = 0xFE, 0xFD


def frame_length(buf):
    """The length of the MAVLink frame at the start of `buf`, or None if more bytes are needed."""
    if len(buf) < 3:
        return None
    if buf[0] == V1:
        return buf[1] + 8
    signed = buf[2] & 0x01
    return buf[1] + 12 + (13 if signed else 0)


def message_id(frame):
    """The message id of a whole frame."""
    if frame[0] == V1:
        return frame[5]
    return int.from_bytes(frame[7:10], "little")


def cut_frames(buf):
    """Whole frames cut from the front of `buf`: (frames, bytes skipped, the rest)."""
    frames, skipped = [], 0
    while buf:
        if buf[0] not in (V1, V2):
            start = min((i for i in (buf.find(bytes([V1])), buf.find(bytes([V2]))) if i >= 0),
                        default=len(buf))
            skipped += start
            buf = buf[start:]
            continue
        n = frame_length(buf)
        if n is None or len(buf) < n:
            break
        frames.append(bytes(buf[:n]))
        buf = buf[n:]
    return frames, skipped, buf


class Line:
    """The radio's serial line: frames queue for it and go out one after another at the byte
    rate; each is delivered `latency_s` after its last byte left."""

    def __init__(self, bytes_per_s, latency_s, buffer_bytes):
        self.bytes_per_s = bytes_per_s
        self.latency_s = latency_s
        self.buffer_bytes = buffer_bytes
        self.free_at = 0.0
        self.busy_s = 0.0

    def send(self, now, frame, queued_bytes):
        """When `frame` arrives at the far end, or None when the buffer has no room for it."""
        if queued_bytes + len(frame) > self.buffer_bytes:
            return None
        start = max(now, self.free_at)
        duration = len(frame) / self.bytes_per_s
        self.free_at = start + duration
        self.busy_s += duration
        return self.free_at + self.latency_s


def parse_args(argv):
    opts = {"baud": 57600, "latency_ms": 100.0, "buffer": 2048, "full_duplex": False,
            "device_file": None, "stats": None}
    rest = []
    it = iter(argv)
    for arg in it:
        if arg == "--full-duplex":
            opts["full_duplex"] = True
        elif arg in ("--baud", "--latency-ms", "--buffer", "--device-file", "--stats"):
            value = next(it, None)
            if value is None:
                sys.exit(f"serial_radio: {arg} needs a value")
            key = arg[2:].replace("-", "_")
            opts[key] = value if key in ("device_file", "stats") else float(value)
        else:
            rest.append(arg)
    if len(rest) != 1 or ":" not in rest[0]:
        sys.exit(__doc__)
    host, port = rest[0].rsplit(":", 1)
    return (host, int(port)), opts


def main():
    autopilot, opts = parse_args(sys.argv[1:])
    bytes_per_s = opts["baud"] / 10.0  # 8 data bits, a start and a stop bit
    latency_s = opts["latency_ms"] / 1000.0
    buffer_bytes = int(opts["buffer"])
    up_line = Line(bytes_per_s, latency_s, buffer_bytes)
    down_line = up_line if not opts["full_duplex"] else Line(bytes_per_s, latency_s, buffer_bytes)

    master, slave = os.openpty()
    tty.setraw(slave)
    attrs = termios.tcgetattr(slave)
    attrs[3] &= ~termios.ECHO
    termios.tcsetattr(slave, termios.TCSANOW, attrs)
    device = os.ttyname(slave)
    os.set_blocking(master, False)
    udp = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    udp.bind(("127.0.0.1", 0))
    udp.setblocking(False)
    print(device, flush=True)
    if opts["device_file"]:
        with open(opts["device_file"], "w") as f:
            f.write(device + "\n")

    stats = {"baud": opts["baud"], "latency_ms": opts["latency_ms"], "buffer_bytes": buffer_bytes,
             "duplex": "full" if opts["full_duplex"] else "half",
             "up_frames": 0, "up_bytes": 0, "down_frames": 0, "down_bytes": 0,
             "up_dropped_frames": 0, "down_dropped_frames": 0, "skipped_bytes": 0,
             "max_queued_bytes": 0, "down_bytes_by_message": {}, "up_bytes_by_message": {}}
    # Frames in flight: (delivery time, order, direction, frame); bytes queued each way.
    pending, order = [], 0
    queued = {"up": 0, "down": 0}
    from_ground = bytearray()
    started = time.monotonic()
    stop = []
    signal.signal(signal.SIGTERM, lambda *_: stop.append(1))
    signal.signal(signal.SIGINT, lambda *_: stop.append(1))

    def enqueue(direction, frame, now):
        nonlocal order
        line = up_line if direction == "up" else down_line
        shared = queued["up"] + queued["down"] if line is up_line and line is down_line \
            else queued[direction]
        at = line.send(now, frame, shared)
        if at is None:
            stats[f"{direction}_dropped_frames"] += 1
            return
        queued[direction] += len(frame)
        stats["max_queued_bytes"] = max(stats["max_queued_bytes"], queued["up"] + queued["down"])
        heapq.heappush(pending, (at, order, direction, frame))
        order += 1

    while not stop:
        now = time.monotonic()
        timeout = max(0.0, pending[0][0] - now) if pending else 0.5
        try:
            ready, _, _ = select.select([master, udp], [], [], min(timeout, 0.5))
        except InterruptedError:
            continue
        now = time.monotonic()
        if master in ready:
            try:
                data = os.read(master, 65536)
            except (BlockingIOError, OSError):
                data = b""
            from_ground.extend(data)
            frames, skipped, rest = cut_frames(from_ground)
            from_ground = bytearray(rest)
            stats["skipped_bytes"] += skipped
            for frame in frames:
                enqueue("up", frame, now)
        if udp in ready:
            while True:
                try:
                    data, _ = udp.recvfrom(65536)
                except BlockingIOError:
                    break
                frames, skipped, _ = cut_frames(bytearray(data))
                stats["skipped_bytes"] += skipped
                for frame in frames:
                    enqueue("down", frame, now)
        while pending and pending[0][0] <= now:
            _, _, direction, frame = heapq.heappop(pending)
            queued[direction] -= len(frame)
            stats[f"{direction}_frames"] += 1
            stats[f"{direction}_bytes"] += len(frame)
            by_message = stats[f"{direction}_bytes_by_message"]
            key = str(message_id(frame))
            by_message[key] = by_message.get(key, 0) + len(frame)
            if direction == "up":
                udp.sendto(frame, autopilot)
            else:
                try:
                    os.write(master, frame)
                except OSError:
                    pass  # nobody reading the device: the frame is lost, as on a real line

    elapsed = time.monotonic() - started
    stats["seconds"] = round(elapsed, 1)
    stats["line_in_use"] = round((up_line.busy_s + (0 if down_line is up_line else
                                                     down_line.busy_s)) / max(elapsed, 1e-9), 3)
    for direction in ("up", "down"):
        stats[f"{direction}_bytes_per_s"] = round(stats[f"{direction}_bytes"] / max(elapsed, 1e-9))
    text = json.dumps(stats)
    print(text, file=sys.stderr, flush=True)
    if opts["stats"]:
        with open(opts["stats"], "w") as f:
            f.write(text + "\n")


if __name__ == "__main__":
    main()
