#!/usr/bin/env python3
"""The station's figures (issue 36, "Figures"; BENCHMARKS.md, "The station under load").

Four networks of 110 nodes each (55 A/B pairs: the published railway design's limit per
network), each on two UDP buses (python-can's udp_multicast format, loopback only), loaded to
about 50 % of 1 Mbit/s on each bus; the station (`duocan station run`, release build) supervises
them with its audit trail, its HTTP access and, when `mosquitto` is installed, its MQTT reports.
Printed: the station process's CPU in total and per frame it received, its resident memory, and
the latency of an event to a server-sent-events client of `/api/events` and to an MQTT
subscriber.

    cargo build --release -j 2 -p duocan-cli
    python3 .ci/station-figures.py            # about a minute and a half
    python3 .ci/station-figures.py --quick    # a few seconds of each, to try it out

Why a plant in a process of its own and not the station's simulated racks (`sim-pairs`): each
simulated board is a full node on an in-memory bus that hands every frame to every port, so at
50 % load 112 ports per bus would cost the process far more than the station does (millions of
deliveries a second), and the figure would be the simulation's. Here a second process plays the
110 nodes of each network on both buses, as cheaply as it can: boot-ups, heartbeats at the
producer time the station file gives, the state the master's NMT commands give, SDO answers
(expedited: every upload reads 0, every download is confirmed) and, from each operational node,
an 8-byte TPDO at the period that brings the bus to the load asked for. The station's CPU is
read from /proc for its process alone. Not part of `cargo test`: a benchmark, not a timed test.

Latency: a forced switch-over of a pair (REST, control open to loopback) every 0.6 s (the
control rate bound is 2 a second); from just before the request is sent to the moment the
pair's role change arrives at each client. It includes the HTTP request's handling, which a
failover seen on the bus does not: an upper bound of the path from the network's event to the
client.
"""

import argparse
import http.client
import json
import os
import shutil
import socket
import statistics
import struct
import subprocess
import sys
import tempfile
import threading
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
NETWORKS = 4
PAIRS = 55  # 110 nodes a network
A_FIRST = 0x03  # A boards 0x03…0x39, B boards 0x43…0x79; the master is node 1
B_OFFSET = 0x40
BITRATE = 1_000_000
BUS_BASE = 41  # udp:41 … udp:48 (python-can's groups 239.74.163.43…, ports 43154…)
HEARTBEAT_MS = 100
SYNC_MS = 100
TPDO_DLC = 8
# Events and MQTT messages a client keeps (the latency of each sample is read within a second
# of it): bounded memory however long a run.
KEPT = 10_000


def frame_bits(dlc):
    """A classic base frame's bits on the bus with its interframe space, stuffing left out."""
    return 47 + 8 * dlc


def bus_group(n):
    """python-can's numbered bus `udp:n` as duocan opens it (UdpBusConfig::numbered)."""
    return ("239.74.163.%d" % (2 + n), 43113 + n)


def tpdo_period_ms(load):
    """The TPDO period of each of the 55 operational nodes that brings a bus to `load` of
    1 Mbit/s with the 110 heartbeats and the master's SYNC and heartbeat."""
    fixed = (
        2 * PAIRS * (1000 / HEARTBEAT_MS) * frame_bits(1)
        + (1000 / SYNC_MS) * frame_bits(0)
        + (1000 / HEARTBEAT_MS) * frame_bits(1)
    )
    per_s = (load * BITRATE - fixed) / frame_bits(TPDO_DLC) / PAIRS
    return max(1, round(1000 / per_s))


def nominal_load(period_ms):
    bits = (
        PAIRS * (1000 / period_ms) * frame_bits(TPDO_DLC)
        + 2 * PAIRS * (1000 / HEARTBEAT_MS) * frame_bits(1)
        + (1000 / SYNC_MS) * frame_bits(0)
        + (1000 / HEARTBEAT_MS) * frame_bits(1)
    )
    return bits / BITRATE


# ----- python-can's udp_multicast wire format (msgpack), the part this plant needs -----


def mp_str(s):
    b = s.encode()
    return bytes([0xA0 | len(b)]) + b


def mp_uint(v):
    if v < 0x80:
        return bytes([v])
    if v < 0x100:
        return bytes([0xCC, v])
    if v < 0x10000:
        return b"\xcd" + struct.pack(">H", v)
    return b"\xce" + struct.pack(">I", v)


def encode(cob, data):
    """One frame as python-can packs it (11 keys, timestamp 0: duocan stamps on receipt)."""
    t, f = b"\xc3", b"\xc2"
    return b"".join(
        [
            b"\x8b",
            mp_str("timestamp") + b"\xcb" + struct.pack(">d", 0.0),
            mp_str("arbitration_id") + mp_uint(cob),
            mp_str("is_extended_id") + f,
            mp_str("is_remote_frame") + f,
            mp_str("is_error_frame") + f,
            mp_str("channel") + b"\xc0",
            mp_str("dlc") + mp_uint(len(data)),
            mp_str("data") + b"\xc4" + bytes([len(data)]) + bytes(data),
            mp_str("is_fd") + f,
            mp_str("bitrate_switch") + f,
            mp_str("error_state_indicator") + f,
        ]
    )


def decode(d):
    """(arbitration_id, data) of a datagram, or None: a reader of the map duocan sends."""

    def value(i):
        b = d[i]
        if b <= 0x7F or b in (0xC0, 0xC2, 0xC3):
            return b, i + 1
        if 0xA0 <= b <= 0xBF:
            n = b & 0x1F
            return d[i + 1 : i + 1 + n], i + 1 + n
        if b == 0xCB:
            return None, i + 9
        if b == 0xCA:
            return None, i + 5
        if b == 0xCC:
            return d[i + 1], i + 2
        if b == 0xCD:
            return struct.unpack(">H", d[i + 1 : i + 3])[0], i + 3
        if b == 0xCE:
            return struct.unpack(">I", d[i + 1 : i + 5])[0], i + 5
        if b == 0xC4:
            n = d[i + 1]
            return bytes(d[i + 2 : i + 2 + n]), i + 2 + n
        if b == 0xD9:
            n = d[i + 1]
            return d[i + 2 : i + 2 + n], i + 2 + n
        raise ValueError("unexpected msgpack byte 0x%02x" % b)

    try:
        if not 0x80 <= d[0] <= 0x8F:
            return None
        i, cob, data = 1, None, None
        for _ in range(d[0] & 0x0F):
            k, i = value(i)
            v, i = value(i)
            if k == b"arbitration_id":
                cob = v
            elif k == b"data":
                data = v
        return (cob, data) if cob is not None and data is not None else None
    except (IndexError, ValueError, struct.error):
        return None


# ----- the plant -----


class Node:
    __slots__ = ("id", "state", "hb", "tpdo")

    def __init__(self, node_id):
        self.id = node_id
        self.state = 0x7F  # pre-operational after its boot-up
        self.hb = {s: encode(0x700 + node_id, [s]) for s in (0x00, 0x04, 0x05, 0x7F)}
        self.tpdo = encode(0x180 + node_id, [node_id, 0, 1, 2, 3, 4, 5, 6])


def plant(period_ms, seconds):
    """Plays the 110 nodes of every network on both of its buses until killed (or `seconds`)."""
    send = socket.socket(socket.AF_INET, socket.SOCK_DGRAM, socket.IPPROTO_UDP)
    send.setsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_IF, socket.inet_aton("127.0.0.1"))
    send.setsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_TTL, 1)
    send.setsockopt(socket.SOL_SOCKET, socket.SO_SNDBUF, 4 << 20)
    send.bind(("127.0.0.1", 0))
    me = send.getsockname()
    nets = []
    for n in range(NETWORKS):
        groups = [bus_group(BUS_BASE + 2 * n), bus_group(BUS_BASE + 2 * n + 1)]
        rx = []
        for g, p in groups:
            r = socket.socket(socket.AF_INET, socket.SOCK_DGRAM, socket.IPPROTO_UDP)
            r.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
            r.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4 << 20)
            r.bind((g, p))
            mreq = socket.inet_aton(g) + socket.inet_aton("127.0.0.1")
            r.setsockopt(socket.IPPROTO_IP, socket.IP_ADD_MEMBERSHIP, mreq)
            r.setblocking(False)
            rx.append(r)
        ids = [A_FIRST + i for i in range(PAIRS)] + [A_FIRST + B_OFFSET + i for i in range(PAIRS)]
        nodes = {i: Node(i) for i in ids}
        # Who sends in which millisecond, worked out once (a scan of 440 nodes every
        # millisecond would cost this plant more than the station's work it is there to load).
        tpdo = [[] for _ in range(period_ms)]
        hb = [[] for _ in range(HEARTBEAT_MS)]
        for node in nodes.values():
            tpdo[node.id % period_ms].append(node)
            hb[(7 * node.id) % HEARTBEAT_MS].append(node)
        nets.append({"groups": groups, "rx": rx, "nodes": nodes, "seen": {}, "tpdo": tpdo, "hb": hb})

    def out(net, payload):
        for g in net["groups"]:
            try:
                send.sendto(payload, g)
            except BlockingIOError:
                pass  # the socket's buffer is full: a frame lost, as on a loaded bus

    for net in nets:
        for node in net["nodes"].values():
            out(net, node.hb[0x00])  # boot-up

    def handle(net, cob, data):
        nodes = net["nodes"]
        if cob == 0 and len(data) >= 2:
            cs, target = data[0], data[1]
            new = {0x01: 0x05, 0x02: 0x04, 0x80: 0x7F, 0x81: 0x00, 0x82: 0x00}.get(cs)
            for node in [nodes[target]] if target in nodes else (nodes.values() if target == 0 else []):
                if new is None:
                    continue
                if new == 0x00:
                    out(net, node.hb[0x00])
                    node.state = 0x7F
                else:
                    node.state = new
                    out(net, node.hb[new])  # a state change is announced at once
        elif 0x600 < cob <= 0x67F and (cob - 0x600) in nodes and len(data) == 8:
            node = nodes[cob - 0x600]
            ccs, idx = data[0] >> 5, bytes(data[1:4])
            if ccs == 2:  # upload: every entry reads 0
                reply = [0x43] + list(idx) + [0, 0, 0, 0]
            elif ccs == 1:  # download: confirmed
                if idx == b"\x17\x10\x00" and (data[4] | data[5] << 8) != HEARTBEAT_MS:
                    # The plant beats at HEARTBEAT_MS, the station file's pair_heartbeat_ms.
                    print("plant: 0x1017 of 0x%02X written %d ms" % (node.id, data[4] | data[5] << 8))
                reply = [0x60] + list(idx) + [0, 0, 0, 0]
            elif ccs == 4:
                return
            else:  # what an expedited-only server cannot do
                reply = [0x80] + list(idx) + [0x01, 0x00, 0x04, 0x05]
            out(net, encode(0x580 + node.id, reply))

    start = time.monotonic()
    tick = 0
    while seconds is None or time.monotonic() - start < seconds:
        for net in nets:
            for r in net["rx"]:
                while True:
                    try:
                        d, src = r.recvfrom(4096)
                    except BlockingIOError:
                        break
                    if src == me:
                        continue  # this plant's own frames, back through multicast loopback
                    f = decode(d)
                    if f is None:
                        continue
                    # The master sends everything on both buses: act on the first copy.
                    key = (f[0], f[1])
                    now = time.monotonic()
                    seen = net["seen"]
                    if now - seen.get(key, -1.0) < 0.005:
                        continue
                    seen[key] = now
                    if len(seen) > 4096:
                        seen.clear()  # bounded
                    handle(net, f[0], f[1])
            for node in net["tpdo"][tick % period_ms]:
                if node.state == 0x05:
                    out(net, node.tpdo)
            for node in net["hb"][tick % HEARTBEAT_MS]:
                out(net, node.hb[node.state])
        tick += 1
        # One millisecond a tick, on the clock: a late tick is made up at once.
        delay = start + tick / 1000 - time.monotonic()
        if delay > 0:
            time.sleep(delay)


# ----- the station's side -----


def free_port():
    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
    s.close()
    return port


def station_file(folder, http_port, mqtt_port):
    lines = [
        "[station]",
        'name = "figures"',
        'http = "127.0.0.1:%d"' % http_port,
        'http_control = "loopback"',
        'audit_dir = "audit"',
    ]
    if mqtt_port:
        lines.append('mqtt = "127.0.0.1:%d"' % mqtt_port)
    for n in range(NETWORKS):
        pairs = ", ".join(
            "[0x%02X, 0x%02X]" % (A_FIRST + i, A_FIRST + B_OFFSET + i) for i in range(PAIRS)
        )
        lines += [
            "",
            "[[network]]",
            'name = "net%d"' % (n + 1),
            'buses = "udp:%d,udp:%d"' % (BUS_BASE + 2 * n, BUS_BASE + 2 * n + 1),
            "node_id = 1",
            "heartbeat_ms = %d" % HEARTBEAT_MS,
            "master_timeout_ms = 300",
            "sync_ms = %d" % SYNC_MS,
            "pairs = [%s]" % pairs,
            "pair_heartbeat_ms = %d" % HEARTBEAT_MS,
            "pair_timeout_ms = 300",
        ]
    path = os.path.join(folder, "figures.toml")
    with open(path, "w") as f:
        f.write("\n".join(lines) + "\n")
    return path


def get(port, path):
    c = http.client.HTTPConnection("127.0.0.1", port, timeout=5)
    c.request("GET", path)
    r = c.getresponse()
    body = r.read()
    c.close()
    return r.status, body


def running_a(port):
    """How many pairs run their A board, over every network."""
    status, body = get(port, "/api/networks")
    if status != 200:
        return 0
    nets = json.loads(body)
    nets = nets.get("networks", nets) if isinstance(nets, dict) else nets
    count = 0
    for net in nets:
        for p in net.get("pairs", []):
            if p.get("active") == "A":
                count += 1
    return count


def rx_frames(port):
    status, body = get(port, "/metrics")
    total = 0.0
    for line in body.decode().splitlines():
        if line.startswith("duocan_port_rx_frames_total"):
            total += float(line.rsplit(" ", 1)[1])
    return total


def proc_cpu(pid):
    """The process's user + system CPU seconds (every thread)."""
    with open("/proc/%d/stat" % pid) as f:
        fields = f.read().rsplit(")", 1)[1].split()
    tick = os.sysconf("SC_CLK_TCK")
    return (int(fields[11]) + int(fields[12])) / tick


def proc_memory(pid):
    out = {}
    with open("/proc/%d/status" % pid) as f:
        for line in f:
            key, _, value = line.partition(":")
            if key in ("VmRSS", "VmHWM"):
                out[key] = int(value.split()[0])  # KiB
    return out


class SseClient(threading.Thread):
    """Reads /api/events and keeps (arrival, network, line) of each event."""

    def __init__(self, port):
        super().__init__(daemon=True)
        self.sock = socket.create_connection(("127.0.0.1", port))
        self.sock.sendall(b"GET /api/events HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n")
        self.events = []

    def run(self):
        f = self.sock.makefile("rb")
        name = None
        for raw in f:
            now = time.monotonic()
            line = raw.decode(errors="replace").rstrip("\r\n")
            if line.startswith("event:"):
                name = line[6:].strip()
            elif line.startswith("data:"):
                self.events.append((now, name, line[5:].strip()))
                if len(self.events) > KEPT:
                    del self.events[: KEPT // 2]  # bounded: only the recent ones are looked at


class MqttClient(threading.Thread):
    """A minimal MQTT 3.1.1 subscriber (QoS 0) keeping (arrival, topic, payload)."""

    def __init__(self, port, topic):
        super().__init__(daemon=True)
        self.sock = socket.create_connection(("127.0.0.1", port))
        cid = b"figures-sub"
        var = b"\x00\x04MQTT\x04\x02\x00\x3c" + struct.pack(">H", len(cid)) + cid
        self.sock.sendall(bytes([0x10, len(var)]) + var)
        t = topic.encode()
        sub = b"\x00\x01" + struct.pack(">H", len(t)) + t + b"\x00"
        self.sock.sendall(bytes([0x82, len(sub)]) + sub)
        self.messages = []

    def read(self, n):
        b = b""
        while len(b) < n:
            chunk = self.sock.recv(n - len(b))
            if not chunk:
                raise EOFError
            b += chunk
        return b

    def run(self):
        try:
            while True:
                head = self.read(1)[0]
                length, mult = 0, 1
                while True:
                    b = self.read(1)[0]
                    length += (b & 0x7F) * mult
                    mult *= 128
                    if not b & 0x80:
                        break
                body = self.read(length)
                now = time.monotonic()
                if head >> 4 == 3:
                    tl = struct.unpack(">H", body[:2])[0]
                    topic = body[2 : 2 + tl].decode(errors="replace")
                    rest = body[2 + tl :]
                    if head & 0x06:
                        rest = rest[2:]  # a packet id (QoS > 0)
                    self.messages.append((now, topic, rest.decode(errors="replace")))
                    if len(self.messages) > KEPT:
                        del self.messages[: KEPT // 2]
        except (EOFError, OSError):
            pass


def switch(port, pair, to):
    c = http.client.HTTPConnection("127.0.0.1", port, timeout=5)
    body = json.dumps({"to": to})
    c.request(
        "POST",
        "/api/networks/net1/pairs/0x%02X/switch" % pair,
        body,
        {"Content-Type": "application/json"},
    )
    r = c.getresponse()
    r.read()
    c.close()
    return r.status


def first_after(items, t0, match):
    for item in items:
        if item[0] >= t0 and match(item):
            return item[0] - t0
    return None


def summary(xs):
    xs = sorted(xs)
    if not xs:
        return "none arrived"
    return "median %.1f ms, max %.1f ms (%d samples)" % (
        statistics.median(xs) * 1e3,
        xs[-1] * 1e3,
        len(xs),
    )


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--duocan", default=None, help="the duocan binary (default: the release build)")
    ap.add_argument("--load", type=float, default=0.5, help="bus load to reach (default 0.5)")
    ap.add_argument("--seconds", type=float, default=30, help="CPU window (default 30 s)")
    ap.add_argument("--samples", type=int, default=20, help="switch-overs timed (default 20)")
    ap.add_argument("--quick", action="store_true", help="5 s and 4 samples: to try it out")
    ap.add_argument("--plant", type=int, default=None, help=argparse.SUPPRESS)
    ap.add_argument("--plant-seconds", type=float, default=None, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.plant is not None:
        return plant(args.plant, args.plant_seconds)
    if args.quick:
        args.seconds, args.samples = 5, 4
    target = os.environ.get("CARGO_TARGET_DIR", os.path.join(ROOT, "target"))
    duocan = args.duocan or os.path.join(target, "release", "duocan")
    if not os.path.exists(duocan):
        sys.exit("%s not found: cargo build --release -j 2 -p duocan-cli" % duocan)
    period = tpdo_period_ms(args.load)
    folder = tempfile.mkdtemp(prefix="station-figures-")
    procs = []
    try:
        broker = shutil.which("mosquitto") or (
            "/usr/sbin/mosquitto" if os.path.exists("/usr/sbin/mosquitto") else None
        )
        mqtt_port = None
        if broker:
            mqtt_port = free_port()
            conf = os.path.join(folder, "mosquitto.conf")
            with open(conf, "w") as f:
                # As whoever runs this: in a user namespace (unshare -rn) the broker's usual
                # drop to the `mosquitto` user fails and it would not start.
                user = "root" if os.geteuid() == 0 else os.environ.get("USER", "root")
                f.write("listener %d 127.0.0.1\nallow_anonymous true\nuser %s\n" % (mqtt_port, user))
            procs.append(
                subprocess.Popen(
                    [broker, "-c", conf], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL
                )
            )
            for _ in range(50):
                try:
                    socket.create_connection(("127.0.0.1", mqtt_port), timeout=1).close()
                    break
                except OSError:
                    time.sleep(0.1)
            else:
                print("mosquitto did not start: MQTT not measured", file=sys.stderr)
                mqtt_port = None
        http_port = free_port()
        toml = station_file(folder, http_port, mqtt_port)
        log = open(os.path.join(folder, "station.log"), "w")
        station = subprocess.Popen(
            [duocan, "station", "run", toml], cwd=folder, stdout=log, stderr=log
        )
        procs.append(station)
        for _ in range(100):
            try:
                get(http_port, "/api/networks")
                break
            except OSError:
                time.sleep(0.1)
        else:
            sys.exit("the station did not answer: see %s/station.log" % folder)
        gen = subprocess.Popen([sys.executable, os.path.abspath(__file__), "--plant", str(period)])
        procs.append(gen)
        started = time.monotonic()
        want = NETWORKS * PAIRS
        while running_a(http_port) < want:
            if time.monotonic() - started > 120 or station.poll() is not None:
                sys.exit(
                    "only %d of %d pairs run A: see %s/station.log"
                    % (running_a(http_port), want, folder)
                )
            time.sleep(0.5)
        up = time.monotonic() - started
        time.sleep(2)  # the configurations' traffic is over: steady state

        cpu0, frames0, t0 = proc_cpu(station.pid), rx_frames(http_port), time.monotonic()
        time.sleep(args.seconds)
        cpu1, frames1, t1 = proc_cpu(station.pid), rx_frames(http_port), time.monotonic()
        mem = proc_memory(station.pid)
        wall = t1 - t0
        frames = frames1 - frames0
        cpu = cpu1 - cpu0

        sse = SseClient(http_port)
        sse.start()
        mqtt = None
        if mqtt_port:
            mqtt = MqttClient(mqtt_port, "duocan/figures/net1/events")
            mqtt.start()
        time.sleep(1)
        sse_lat, mqtt_lat = [], []
        for i in range(args.samples):
            to = "B" if i % 2 == 0 else "A"
            t = time.monotonic()
            status = switch(http_port, A_FIRST, to)
            if status != 200:
                print("switch-over refused: HTTP %d" % status, file=sys.stderr)
            time.sleep(0.6)

            def role(item, to=to):
                return "0x%02X" % A_FIRST in item[-1] and (to + " active") in item[-1]

            def sse_role(item, to=to):
                return item[1] == "net1" and role(item, to)

            x = first_after(sse.events, t, sse_role)
            if x is not None:
                sse_lat.append(x)
            if mqtt:
                y = first_after(mqtt.messages, t, role)
                if y is not None:
                    mqtt_lat.append(y)
        mem_end = proc_memory(station.pid)

        per_bus = frames / wall / (2 * NETWORKS)
        print("Station figures: %d networks x %d nodes, 2 UDP buses each" % (NETWORKS, 2 * PAIRS))
        print("  machine: %d CPUs, load average %.2f %.2f %.2f" % ((os.cpu_count(),) + os.getloadavg()))
        print(
            "  bus load: %.0f %% of 1 Mbit/s nominal (TPDO every %d ms from each of the %d "
            "running boards, 8 bytes; stuffing left out), %.0f frames/s received per bus"
            % (100 * nominal_load(period), period, PAIRS, per_bus)
        )
        print("  all %d pairs running A %.1f s after the plant started" % (want, up))
        print(
            "  CPU: %.1f %% of one core over %.0f s (%.3f s), %.0f frames received (both buses)"
            % (100 * cpu / wall, wall, cpu, frames)
        )
        print(
            "  CPU per frame received: %.2f us; per CAN frame (its two copies): %.2f us"
            % (1e6 * cpu / frames, 2e6 * cpu / frames)
        )
        print(
            "  resident memory: %.1f MiB (after the latency runs %.1f MiB, peak %.1f MiB)"
            % (mem["VmRSS"] / 1024, mem_end["VmRSS"] / 1024, mem_end["VmHWM"] / 1024)
        )
        print("  event latency, switch-over request -> event, SSE: %s" % summary(sse_lat))
        if mqtt:
            print("  event latency, switch-over request -> event, MQTT: %s" % summary(mqtt_lat))
        else:
            print("  MQTT: no mosquitto on this machine, not measured")
        return 0
    finally:
        for p in reversed(procs):
            p.terminate()
            try:
                p.wait(timeout=10)
            except subprocess.TimeoutExpired:
                p.kill()
        shutil.rmtree(folder, ignore_errors=True)


if __name__ == "__main__":
    sys.exit(main())
