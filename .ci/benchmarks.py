#!/usr/bin/env python3
"""Regenerates BENCHMARKS.md: runs the commands whose figures the page gives and writes each
figure into the page between its markers, `<!-- figure: NAME -->` ... `<!-- /figure -->`. The
prose around the markers is hand-written and stays as it is; what lies between them is the
script's. The machine (CPU count and model, rustc) is named once, in the `machine` marker; each
group of figures records its command, date and the load average at its start in the `runs`
table.

    python3 .ci/benchmarks.py                  every group, written into BENCHMARKS.md (long:
                                               tens of minutes on two cores)
    python3 .ci/benchmarks.py od pdo demo      those groups only; the others' figures and rows
                                               stay as they are (refused when the machine
                                               differs from the one the page names)
    python3 .ci/benchmarks.py --quick [GROUP…] shortened runs (criterion's shortest settings,
                                               one round, one demo run) to exercise the script;
                                               written to target/BENCHMARKS.quick.md unless
                                               --out says otherwise, never over the page
    python3 .ci/benchmarks.py --list           the groups, their commands and figures
    python3 .ci/benchmarks.py --check          no run: every marker in the page is a figure
                                               this script writes, and every such figure has
                                               its marker (CI runs this)

A group that fails (its command fails, or its output lacks a figure: the parsers fail loudly
rather than guess) leaves its figures and row as they were; the script goes on with the others
and exits non-zero naming the failed groups. Python because the work is parsing (criterion's
JSON, the printed lines) and replacing text in place, which a shell script does badly; it
calls the same cargo commands a reader would type.
"""

import argparse
import glob
import json
import os
import re
import subprocess
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
PAGE = os.path.join(ROOT, "BENCHMARKS.md")
# The README's figures table repeats some of the page's figures between the same markers: the
# script writes them there too, and the check holds them equal to the page's.
README = os.path.join(ROOT, "README.md")
MARKER = re.compile(r"<!-- figure: ([\w.-]+) -->(.*?)<!-- /figure -->", re.S)
# A UDP bus in a private network namespace: loopback up, multicast routed to it.
NETNS = "unshare -rn sh -c 'ip link set lo up; ip route add 224.0.0.0/4 dev lo; {}'"


class Missing(Exception):
    """A figure the command's output should have given and did not."""


def target_dir():
    return os.environ.get("CARGO_TARGET_DIR") or os.path.join(ROOT, "target")


# ----- formatting -----

def num(x, digits=0):
    """1234.5 -> '1,234.5' (thousands separated, as the page writes numbers)."""
    return f"{x:,.{digits}f}"


def ns(x):
    """A time in nanoseconds, to two or three significant digits."""
    return f"{x:.1f} ns" if x < 10 else f"{x:.0f} ns"


def sig(x):
    """Two or three significant digits."""
    return f"{x:.2f}" if x < 1 else f"{x:.1f}" if x < 100 else f"{x:,.0f}"


def kib(text):
    """'65,052' -> '65,052 bytes (63.5 KiB)', as .ci/firmware-figures.py writes sizes."""
    n = int(text.replace(",", ""))
    return f"{n:,} bytes ({n / 1024:.1f} KiB)"


def find(pattern, text, what):
    m = re.search(pattern, text, re.M)
    if not m:
        raise Missing(f"{what}: no line matching {pattern!r} in the output")
    return m


# ----- criterion -----

def criterion(group, function, since):
    """The median of a criterion benchmark of this run (ns per iteration) and its throughput
    (elements per iteration, or None)."""
    d = os.path.join(target_dir(), "criterion", group, function, "new")
    est = os.path.join(d, "estimates.json")
    if not os.path.exists(est) or os.path.getmtime(est) < since:
        raise Missing(f"criterion {group}/{function}: no estimates of this run in {d}")
    with open(est) as f:
        median = json.load(f)["median"]["point_estimate"]
    elements = None
    try:
        with open(os.path.join(d, "benchmark.json")) as f:
            tp = json.load(f).get("throughput") or {}
        elements = tp.get("Elements")
    except FileNotFoundError:
        pass
    return median, elements


def criterion_all(group, since):
    """Every benchmark of a criterion group that this run measured: {function: median ns per
    element of its throughput (per iteration when it has none)}."""
    out = {}
    for est in glob.glob(os.path.join(target_dir(), "criterion", group, "*", "new", "estimates.json")):
        if os.path.getmtime(est) >= since:
            median, elements = criterion(group, est.split(os.sep)[-3], since)
            out[est.split(os.sep)[-3]] = median / (elements or 1)
    if not out:
        raise Missing(f"criterion {group}: no benchmark of this run")
    return out


# ----- the groups: each a command, the figures it gives, and how to read them -----

class Group:
    def __init__(self, name, title, commands, figures, parse, quick=None, needs=None):
        self.name, self.title = name, title
        self.commands = commands  # shell commands, run in turn; their output is parsed together
        self.quick = quick or commands
        self.figures = figures  # the names this group writes
        self.parse = parse  # (output, since, quick) -> {figure: text}
        self.needs = needs  # what the group needs beyond cargo (said when it fails)


def bench(args):
    """cargo bench with the criterion arguments of the mode."""
    return "cargo bench " + args + " -- {criterion}"


def parse_od(out, since, quick):
    s, _ = criterion("od_lookup_1500", "static", since)
    d, _ = criterion("od_lookup_1500", "dynamic", since)
    h, _ = criterion("od_lookup_1500", "published_hash_512", since)
    return {"od.static": ns(s), "od.dynamic": ns(d), "od.published": ns(h),
            "od.dynamic-ratio": f"{d / s:.2f}×", "od.published-ratio": f"{h / s:.2f}×"}


def parse_node(out, since, quick):
    t, _ = criterion("heartbeat_consumer_127", "per_heartbeat", since)
    return {"node.heartbeat": ns(t)}


def parse_sdo(out, since, quick):
    r = {}
    for mode, key in (("Block", "block"), ("Segmented", "segmented")):
        m = find(rf"^sdo {mode} download of 64 KiB at 1 Mbit/s \(simulated\): ([\d.]+) KiB/s in "
                 rf"([\d.]+)(m?s); bus limit of the protocol [\d.]+ KiB/s \([^,]+, (\d+) frames\): "
                 rf"([\d.]+) %", out, f"sdo {mode}")
        secs = float(m[2]) / (1000 if m[3] == "ms" else 1)
        r[f"sdo.{key}-rate"] = f"{float(m[1]):.1f} KiB/s"
        r[f"sdo.{key}-limit"] = f"{float(m[5]):.0f} %"
        r[f"sdo.{key}-frames"] = num(int(m[4]))
        if key == "block":
            r["sdo.block-time"] = f"{secs:.3f} s"
    server = criterion_all("sdo_server", since).values()
    client = criterion_all("sdo_client", since).values()
    r["sdo.server-cpu"] = f"{min(server):.0f}–{max(server):.0f} ns"
    r["sdo.client-cpu"] = f"{min(client):.0f}–{max(client):.0f} ns"
    return r


def parse_pdo(out, since, quick):
    b, _ = criterion("pdo", "tpdo_build_5_entries_64_bits", since)
    a, _ = criterion("pdo", "rpdo_apply_5_entries_64_bits", since)
    m, _ = criterion("pdo", "master_432_rpdos_per_frame", since)
    return {"pdo.build": ns(b), "pdo.apply": ns(a), "pdo.build-rate": f"{1e3 / b:.1f} M",
            "pdo.apply-rate": f"{1e3 / a:.1f} M", "pdo.railway": ns(m),
            "pdo.railway-rate": f"{1e3 / m:.1f} M"}


def parse_sim(out, since, quick):
    t, _ = criterion("sim", "40_devices_100ms_heartbeat_1_simulated_minute", since)
    return {"sim.minute": f"{t / 1e6:.0f} ms"}


def parse_eds(out, since, quick):
    imp, _ = criterion("eds", "import_2000_entries", since)
    dic, _ = criterion("eds", "dictionary_2000_entries", since)
    exp, _ = criterion("eds", "export_2000_entries", since)
    size = find(r"^EDS import, (\d+) bytes, 2,000 entries", out, "eds")
    return {"eds.size": f"{int(size[1]) / 1000:.0f} KB", "eds.import": f"{sig(imp / 1e6)} ms",
            "eds.dictionary": f"{sig(dic / 1e6)} ms", "eds.export": f"{sig(exp / 1e6)} ms"}


def parse_merge(out, since, quick):
    r = {}
    for fn, key in (("merger_50_50_duplicates", "merge.merger"), ("dual_bus_handle_rx", "merge.dual-bus")):
        t, n = criterion("merge", fn, since)
        if not n:
            raise Missing(f"criterion merge/{fn}: no throughput")
        r[key] = f"{n / t * 1e3:.1f} M"
    return r


def parse_usdo(out, since, quick):
    rate, ratio, frames = {}, [], {}
    for mbit in (2, 5):
        for what in ("usdo expedited 56 B", "sdo block 56 B", "usdo segmented 64 KiB", "sdo block 64 KiB"):
            m = find(rf"^fd 1/{mbit} Mbit/s {what} download \(simulated\): ([\d.]+) KiB/s in [^;]+; "
                     rf"bus-time bound [\d.]+ KiB/s \([^,]+, (\d+) frames\): ([\d.]+)x the bound", out,
                     f"usdo {what} at {mbit} Mbit/s")
            rate[(what, mbit)] = float(m[1])
            ratio.append(float(m[3]))
            frames[what] = int(m[2])
    two = lambda what: f"{rate[(what, 2)]:.1f} / {rate[(what, 5)]:.1f} KiB/s"
    speed = lambda a, b: f"{rate[(a, 2)] / rate[(b, 2)]:.2f}× / {rate[(a, 5)] / rate[(b, 5)]:.2f}×"
    r = {"usdo.expedited-rate": two("usdo expedited 56 B"), "usdo.block56-rate": two("sdo block 56 B"),
         "usdo.segmented-rate": two("usdo segmented 64 KiB"), "usdo.block-rate": two("sdo block 64 KiB"),
         "usdo.speedup56": speed("usdo expedited 56 B", "sdo block 56 B"),
         "usdo.speedup64": speed("usdo segmented 64 KiB", "sdo block 64 KiB"),
         "usdo.bound": f"{min(ratio):.3f}–{max(ratio):.3f}×" if min(ratio) != max(ratio) else f"{ratio[0]:.3f}×",
         "usdo.frames": ", ".join(num(frames[w]) for w in ("usdo expedited 56 B", "sdo block 56 B",
                                                             "usdo segmented 64 KiB", "sdo block 64 KiB"))}

    def cpu(fn):
        t = [criterion(g, fn, since)[0] for g in ("usdo_server", "usdo_client")]
        return " / ".join(ns(x) if x < 1000 else f"{sig(x / 1e3)} µs" for x in t)
    for fn, key in (("usdo_expedited_download_56", "expedited"), ("usdo_segmented_download_889", "segmented"),
                    ("sdo_block_download_56", "block56"), ("sdo_block_download_889", "block889")):
        r[f"usdo.{key}-cpu"] = cpu(fn)
    return r


def parse_fd_merge(out, since, quick):
    lat, ratio = {}, []
    for mbit in (2, 5):
        for cut in ("both buses", "one bus cut"):
            m = find(rf"^dual bus fd 1/{mbit} Mbit/s, 64-byte frame, {cut} \(simulated\): latency worst "
                     rf"([\d.]+)(m?s), mean [^;]+; wire time up to ([\d.]+)(m?s): ([\d.]+)x", out,
                     f"dual bus fd {mbit} Mbit/s {cut}")
            lat[mbit] = float(m[1]) * (1 if m[2] == "ms" else 1000)
            ratio.append(float(m[5]))
    fd, _ = criterion("dual_bus_fd", "handle_rx_fd_64_bytes_per_frame", since)
    classic, _ = criterion("dual_bus_fd", "handle_rx_classic_8_bytes_per_frame", since)
    n = 10_000  # frames per iteration (the bench's FRAMES)
    return {"fd.latency": f"{lat[2]:.3f} / {lat[5]:.3f} ms",
            "fd.ratio": f"{max(ratio):.3f}×",
            "fd.cpu": ns(fd / n), "fd.classic-cpu": ns(classic / n)}


def parse_supervisor(out, since, quick):
    t, _ = criterion("supervisor", "railway_4x54_pairs_one_simulated_second", since)
    return {"supervisor.cpu": f"{t / 1e6:.1f} ms", "supervisor.real-time": f"{1e9 / t:.0f}×"}


def parse_driver(out, since, quick):
    # One iteration is a millisecond of the board's traffic, its frames the throughput.
    g, gn = criterion("gateway_driver", "per_frame", since)
    m, mn = criterion("master_driver", "per_frame", since)
    if not gn or not mn:
        raise Missing("criterion gateway_driver/master_driver: no throughput (frames per millisecond)")
    return {"driver.gateway": ns(g / gn), "driver.master": ns(m / mn), "driver.gateway-ms": ns(g),
            "driver.master-ms": ns(m)}


def parse_boot(out, since, quick):
    m = find(r"network started at ([\d.]+) ms; the (\d+) frames on the bus by then take ([\d.]+) ms "
             r"of bus time: ([\d.]+)× the bus's bound", out, "network_boot")
    return {"boot.started": f"{m[1]} ms", "boot.frames": num(int(m[2])), "boot.bus-time": f"{m[3]} ms",
            "boot.ratio": f"{m[4]}×", "boot.per-slave": f"{int(m[2]) / 126:.0f}"}


def parse_alloc(out, since, quick):
    # Its own harness (a counting global allocator): every test run, none failed, each asserting
    # that nothing was allocated per frame.
    n = int(find(r"^running (\d+) tests", out, "alloc")[1])
    ok = len(re.findall(r"^test \S*allocates_nothing\S* \.\.\. ok$", out, re.M))
    if n == 0 or ok != n:
        raise Missing(f"alloc: {ok} of {n} tests passed")
    return {"alloc.count": "0"}


def parse_merge_memory(out, since, quick):
    find(r"^test result: ok\. [1-9]", out, "merge_memory")
    return {"merge-memory": "constant"}


def parse_concurrent(out, since, quick):
    m = find(r"^one read: ([\d.]+)(m?s|µs) of bus time; twenty at once: ([\d.]+)(m?s|µs) \(([\d.]+)× one\), "
             r"the bus time of their (\d+) frames being ([\d.]+)(m?s|µs)", out, "concurrent_sdo")
    ms = lambda v, u: float(v) * {"s": 1e3, "ms": 1, "µs": 1e-3}[u]
    return {"net.twenty": f"{ms(m[3], m[4]):.1f} ms", "net.frames": m[6],
            "net.bus-time": f"{ms(m[7], m[8]):.1f} ms", "net.ratio": f"{float(m[5]):.0f}×",
            "net.one": f"{ms(m[1], m[2]):.2f} ms"}


def parse_type_sizes(out, since, quick):
    # The gateway's board: a node on the railway profile borrowing its static dictionary.
    sizes = {m[1]: int(m[2]) for m in re.finditer(r"^print-type-size type: `([^`]+)`: (\d+) bytes", out, re.M)}
    nodes = {(m[1], sizes[m[0]]) for m in (re.fullmatch(r"duocan::Node<&mut (duocan::od::StaticDictionary<[^>]*>), "
                                                         r"&duocan::profile::railway::RailwayProfile, .*>", k)
                                           for k in sizes) if m}
    if len(nodes) != 1 or next(iter(nodes))[0] not in sizes:
        raise Missing(f"type sizes: not one railway node with a static dictionary but {sorted(nodes)}")
    (od, node), = nodes
    return {"nostd.node": f"{num(node + sizes[od])} bytes", "nostd.dictionary": f"{num(sizes[od])} bytes"}


def parse_firmware(out, since, quick):
    r = {}
    for img in ("gateway", "master"):
        flash = find(rf"^{img}: flash ([\d,]+) bytes", out, f"firmware {img} flash")
        static = find(rf"^{img}: static RAM ([\d,]+) bytes", out, f"firmware {img} static RAM")
        stack = find(rf"^{img}: deepest stack through direct calls ([\d,]+) bytes", out, f"firmware {img} stack")
        need = find(rf"^{img}: RAM needed with the stack, .*: ([\d,]+) bytes", out, f"firmware {img} RAM needed")
        for key, m in (("flash", flash), ("static", static), ("stack", stack), ("ram", need)):
            r[f"firmware.{img}-{key}"] = kib(m[1])
    heap = find(r"^master: heap arena .*; high-water mark on the host ([\d,]+) bytes", out, "firmware master heap")
    r["firmware.master-heap"] = f"{heap[1]} bytes"
    return r


def parse_demo(out, since, quick):
    runs = re.findall(r"of simulated time, (\d+) frames on 8 buses .* in ([\d.]+) s of wall time", out)
    if not runs:
        raise Missing("demo: no line 'N frames on 8 buses … in S s of wall time'")
    walls = [w for _, w in runs]
    text = ", ".join(walls[:-1]) + " and " + walls[-1] if len(walls) > 1 else walls[0]
    return {"demo.frames": num(int(runs[-1][0])), "demo.wall": f"{text} s",
            "demo.runs": {1: "one run", 2: "two runs", 3: "three runs"}.get(len(runs), f"{len(runs)} runs")}


def parse_station(out, since, quick):
    load = find(r"bus load: (\d+) % of 1 Mbit/s nominal .*, (\d+) frames/s received per bus", out, "station load")
    cpu = find(r"CPU: ([\d.]+) % of one core", out, "station CPU")
    frame = find(r"CPU per frame received: ([\d.]+) us; per CAN frame \(its two copies\): ([\d.]+) us", out,
                 "station CPU per frame")
    mem = find(r"resident memory: ([\d.]+) MiB \(after the latency runs ([\d.]+) MiB, peak ([\d.]+) MiB\)", out,
               "station memory")
    sse = find(r"event latency, .*, SSE: (.*)$", out, "station SSE latency")
    mqtt = re.search(r"event latency, .*, MQTT: (.*)$", out, re.M)
    return {"station.load": f"{load[1]} %", "station.frames": num(int(load[2])),
            "station.cpu": f"{cpu[1]} %", "station.cpu-frame": f"{frame[1]} µs",
            "station.cpu-can-frame": f"{frame[2]} µs", "station.rss": f"{mem[1]} MiB",
            "station.peak": f"{mem[3]} MiB", "station.sse": sse[1],
            "station.mqtt": mqtt[1] if mqtt else "not measured (no mosquitto)"}


def rt_rows(out, what):
    """rt_overhead's ratio lines: {row: (median, low, high)} of every run, in order."""
    rows = {}
    for m in re.finditer(r"^  (round trip|throughput|echo CPU per frame, window 16|echo CPU per frame, window 1) "
                         r"\([^)]*\)\s+\S+\s+\S+\s+([\d.]+) \(([\d.]+)–([\d.]+)\)$", out, re.M):
        rows.setdefault(m[1], []).append(tuple(float(x) for x in m.group(2, 3, 4)))
    if "round trip" not in rows:
        raise Missing(f"{what}: no 'round trip' ratio line of rt_overhead")
    return rows


def medians(v):
    return ", ".join(f"{m:.2f}" for m, _, _ in v) + "×"


def spread(v):
    lo, hi = min(m for m, _, _ in v), max(m for m, _, _ in v)
    return f"{lo:.2f}×" if f"{lo:.2f}" == f"{hi:.2f}" else f"{lo:.2f}–{hi:.2f}×"


def parse_rt(out, since, quick):
    rows = rt_rows(out, "rt")
    rtt = re.search(r"^  round trip \(µs\)\s+(\S+)\s+(\S+)", out, re.M)
    return {"rt.round-trip": medians(rows["round trip"]), "rt.throughput": medians(rows["throughput"]),
            "rt.cpu16": spread(rows["echo CPU per frame, window 16"]),
            "rt.cpu1": spread(rows["echo CPU per frame, window 1"]),
            "rt.first": f"{rtt[2]} vs {rtt[1]} µs"}


def parse_vcan(out, since, quick):
    rows = rt_rows(out, "vcan")
    kit = find(r"the bridge adds ([\d.]+) µs \(median\) per frame and carries (\d+) frames/s \(([\d.]+)× the bare",
               out, "vcan: the kit's bridge")
    return {"vcan.kit-added": f"{float(kit[1]):.0f} µs", "vcan.kit-rate": num(int(kit[2]), 0),
            "vcan.kit-ratio": f"{kit[3]}×","vcan.throughput": spread(rows["throughput"]),
            "vcan.cpu16": spread(rows["echo CPU per frame, window 16"]),
            "vcan.cpu1": spread(rows["echo CPU per frame, window 1"]),
            "vcan.round-trip": spread(rows["round trip"])}


def parse_kit(out, since, quick):
    m = find(r"the bridge adds ([\d.]+) µs \(median\) per frame and carries (\d+) frames/s \(([\d.]+)× the bare "
             r"path\), \d+ frames each way, 0 lost", out, "kit bench")
    return {"kit.added": f"{float(m[1]):.0f} µs", "kit.ratio": f"{m[3]}×"}


PYTHON_ROWS = [
    ("SDO segmented upload, 64 KiB", "KiB/s"), ("SDO segmented download, 64 KiB", "KiB/s"),
    ("SDO block upload, 64 KiB", "KiB/s"), ("SDO block download, 64 KiB", "KiB/s"),
    ("SDO expedited reads, 10,000", "reads/s"), ("PDO echo, window 16, 5,000", "echoes/s"),
]


def parse_python(out, since, quick):
    rounds = find(r"^duocan vs python canopen on one python-can udp_multicast bus, (\d+) rounds", out, "python_bench")
    lines = ["| median (min–max) | duocan | python `canopen` | ratio | CPU s duocan client / server "
             "| CPU s python client / server |", "| --- | --- | --- | --- | --- | --- |"]
    cpu = r"([\d.]+(?: / [\d.]+)?|-)"
    rate_ratios, cpu_ratios, expedited = [], [], None
    for name, unit in PYTHON_ROWS:
        m = find(rf"^{re.escape(name)} \({re.escape(unit)}\)\s+(\S+ \(\S+\))\s+(\S+ \(\S+\)(?: \[\d+ failed\])?|failed"
                 rf"(?: \[\d+ failed\])?)\s+(\S+)\s+{cpu}\s+{cpu}\s*$", out, f"python_bench {name}")
        py = re.sub(r" \[(\d+) failed\]", r", \1 failed", m[2])
        if m[3] != "-":
            rate_ratios.append(float(m[3].rstrip("×")))
        if m[4] != "-" and m[5] != "-":
            cpu_ratios.append(float(m[5].split(" / ")[0]) / float(m[4].split(" / ")[0]))
        if name.startswith("SDO expedited"):
            expedited = 1e6 / float(m[1].split()[0].replace(",", ""))
        sep = lambda t: re.sub(r"(?<![\d.])\d{4,}", lambda d: f"{int(d[0]):,}", t)  # 18664 -> 18,664
        lines.append(f"| {name} | {sep(m[1])} {unit} | {py if py.startswith('failed') else sep(py).replace(')', ') ' + unit, 1)} "
                     f"| {m[3]} | {m[4]} | {m[5]} |")
    many = find(r"nodes read at once through one handle \(segmented upload, 27 bytes\): (\S+ \(\S+\)) ms, against one "
                r"node alone (\S+ \(\S+\)) ms: ([\d.]+)×", out, "python_bench concurrent")
    bare = find(r"takes ([\d.]+) µs a round trip \((\d+) round trips/s", out, "python_bench bare transport")
    if not rate_ratios or not cpu_ratios or expedited is None:
        raise Missing("python_bench: no row with both stacks' rates and CPU")
    return {"python.rounds": rounds[1], "python.rate-ratio": f"{min(rate_ratios):.1f}–{max(rate_ratios):.1f}×",
            "python.cpu-ratio": f"{min(cpu_ratios):.1f}–{max(cpu_ratios):.1f}×",
            "python.expedited": f"{expedited:.0f} µs", "python.expedited-ratio": f"{expedited / float(bare[1]):.1f}×", "python.table": "\n" + "\n".join(lines) + "\n",
            "python.twenty": f"{many[1]} ms", "python.one": f"{many[2]} ms", "python.twenty-ratio": f"{many[3]}×",
            "python.bare": f"{bare[1]} µs ({num(int(bare[2]))} round trips/s"}


def parse_door(out, since, quick):
    rounds = find(r"^one-at-a-time SDO reads through the door against the bare ping-pong, (\d+) rounds", out, "door_speed")
    bare = find(r"^bare socket ping-pong, one bus: (\d+) round trips/s", out, "door_speed bare")
    one = find(r"^door, one bus: (\d+) reads/s, ([\d.]+) of the ping-pong", out, "door_speed one bus")
    two = find(r"^door, two buses \(redundant\): (\d+) reads/s, ([\d.]+) of the one-bus ping-pong", out,
               "door_speed two buses")
    two_bare = find(r"the redundant door ([\d.]+) of it", out, "door_speed two buses, bare")
    return {"door.rounds": rounds[1], "door.bare": f"{num(int(bare[1]))} round trips/s",
            "door.one": f"{one[2]} ({num(int(one[1]))} reads/s)", "door.two": two[2], "door.two-bare": two_bare[1]}


def parse_fuzz(out, since, quick):
    done = re.findall(r"^== fuzz: (\w+): (?:#(\d+) +DONE|Done (\d+) runs)", out, re.M)
    if not done:
        raise Missing("fuzz: no '== fuzz: TARGET: Done N runs' line")
    secs = find(r"^== fuzz: \d+ targets, (\d+) s each", out, "fuzz")
    rows = ["| Target | Executions |", "| --- | --- |"]
    rows += [f"| `{t}` | {num(int(a or b))} |" for t, a, b in done]
    return {"fuzz.seconds": secs[1], "fuzz.table": "\n" + "\n".join(rows) + "\n"}


CRIT = "{criterion}"
GROUPS = [
    Group("od", "dictionary lookup", [bench("--bench od")],
          ["od.static", "od.dynamic", "od.published", "od.dynamic-ratio", "od.published-ratio"], parse_od),
    Group("node", "heartbeat consumer", [bench("--bench node")], ["node.heartbeat"], parse_node),
    Group("sdo", "SDO transfers", [bench("--bench sdo")],
          ["sdo.block-rate", "sdo.block-limit", "sdo.block-frames", "sdo.block-time", "sdo.segmented-rate",
           "sdo.segmented-limit", "sdo.segmented-frames", "sdo.server-cpu", "sdo.client-cpu"], parse_sdo),
    Group("pdo", "PDOs", [bench("--bench pdo")],
          ["pdo.build", "pdo.apply", "pdo.build-rate", "pdo.apply-rate", "pdo.railway", "pdo.railway-rate"],
          parse_pdo),
    Group("sim", "simulator", [bench("--bench sim")], ["sim.minute"], parse_sim),
    Group("eds", "EDS import", [bench("--bench eds")],
          ["eds.size", "eds.import", "eds.dictionary", "eds.export"], parse_eds),
    Group("merge", "active-active merger", [bench("-p duocan-redundancy --bench merge")],
          ["merge.merger", "merge.dual-bus"], parse_merge),
    Group("usdo", "USDO against SDO block transfer on an FD bus", [bench("--bench usdo")],
          ["usdo.expedited-rate", "usdo.block56-rate", "usdo.segmented-rate", "usdo.block-rate", "usdo.speedup56",
           "usdo.speedup64", "usdo.bound", "usdo.frames", "usdo.expedited-cpu", "usdo.segmented-cpu",
           "usdo.block56-cpu", "usdo.block889-cpu"], parse_usdo),
    Group("fd-merge", "a 64-byte CAN FD frame through the dual bus",
          [bench("-p duocan-redundancy --bench fd")], ["fd.latency", "fd.ratio", "fd.cpu", "fd.classic-cpu"],
          parse_fd_merge),
    Group("merge-memory", "merger memory", ["cargo test -p duocan-redundancy --test link merge_memory"],
          ["merge-memory"], parse_merge_memory),
    Group("supervisor", "supervisor", [bench("-p duocan-redundancy --bench supervisor")],
          ["supervisor.cpu", "supervisor.real-time"], parse_supervisor),
    Group("boot", "network boot", ["cargo test --release --test master network_boot -- --nocapture"],
          ["boot.started", "boot.frames", "boot.bus-time", "boot.ratio", "boot.per-slave"], parse_boot),
    Group("alloc", "allocations on the runtime's path", ["cargo test --test alloc"], ["alloc.count"],
          parse_alloc),
    Group("net", "concurrent SDO reads", ["cargo test --test net concurrent_sdo -- --nocapture"],
          ["net.twenty", "net.frames", "net.bus-time", "net.ratio", "net.one"], parse_concurrent),
    Group("rt", "the runtime against a bare socket loop",
          ["cargo build --release --features udp --example rt_overhead"]
          + [NETNS.format("cargo run -q --offline --release --features udp --example rt_overhead udp 40000 5")] * 3,
          ["rt.round-trip", "rt.throughput", "rt.cpu16", "rt.cpu1", "rt.first"], parse_rt,
          quick=["cargo build --release --features udp --example rt_overhead",
                 NETNS.format("cargo run -q --offline --release --features udp --example rt_overhead udp 4000 1")],
          needs="unshare -rn (a user namespace) for the private UDP network"),
    Group("python", "duocan and python canopen side by side",
          ["cargo test --release -p duocan-tiers --features python --test python_bench --no-run",
           NETNS.format("DUOCAN_BENCH_ROUNDS=3 cargo test --release --offline -p duocan-tiers --features python "
                        "--test python_bench -- --nocapture")],
          ["python.rounds", "python.table", "python.twenty", "python.one", "python.twenty-ratio", "python.bare",
           "python.rate-ratio", "python.cpu-ratio", "python.expedited", "python.expedited-ratio"],
          parse_python,
          quick=["cargo test --release -p duocan-tiers --features python --test python_bench --no-run",
                 NETNS.format("DUOCAN_BENCH_ROUNDS=1 cargo test --release --offline -p duocan-tiers --features "
                              "python --test python_bench -- --nocapture")],
          needs="DUOCAN_PYTHON: a python with python-can and canopen (.ci/tier-python.sh makes one in "
                "target/pyenv), and unshare -rn"),
    Group("door", "one-at-a-time reads through the front door",
          ["cargo test --release -p duocan-tiers --features python --test door_speed --no-run",
           NETNS.format("DUOCAN_BENCH_ROUNDS=7 DUOCAN_BENCH_READS=3000 cargo test --release --offline -p duocan-tiers "
                        "--features python --test door_speed -- --nocapture")],
          ["door.rounds", "door.bare", "door.one", "door.two", "door.two-bare"], parse_door,
          quick=["cargo test --release -p duocan-tiers --features python --test door_speed --no-run",
                 NETNS.format("DUOCAN_BENCH_ROUNDS=1 DUOCAN_BENCH_READS=300 cargo test --release --offline -p "
                              "duocan-tiers --features python --test door_speed -- --nocapture")],
          needs="unshare -rn (a user namespace) for the private UDP networks"),
    Group("demo", "the demo",
          ["cargo build --release --example demo"]
          + ["cargo run -q --release --example demo -- --out target/demo"] * 3,
          ["demo.frames", "demo.wall", "demo.runs"], parse_demo,
          quick=["cargo build --release --example demo",
                 "cargo run -q --release --example demo -- --out target/demo"]),
    Group("nostd", "the no_std node's RAM",
          # Touched, and not incremental, so that rustc lays the types out again (a fresh build, or
          # one from the incremental cache, prints nothing).
          ["touch examples/safety_gateway/src/lib.rs && CARGO_INCREMENTAL=0 RUSTC_BOOTSTRAP=1 cargo rustc -p safety-gateway --lib "
           "--target thumbv7em-none-eabihf -- -Zprint-type-sizes"],
          ["nostd.node", "nostd.dictionary"], parse_type_sizes,
          needs="the thumbv7em-none-eabihf target (rustup target add thumbv7em-none-eabihf)"),
    Group("firmware", "firmware images", ["bash .ci/firmware.sh"],
          ["firmware.gateway-flash", "firmware.gateway-static", "firmware.gateway-stack", "firmware.gateway-ram",
           "firmware.master-flash", "firmware.master-static", "firmware.master-stack", "firmware.master-ram",
           "firmware.master-heap"], parse_firmware, needs="the thumbv7em-none-eabihf target and llvm-tools"),
    Group("driver", "firmware path per frame on the host",
          [bench("-p safety-gateway --bench driver"), bench("-p master-board --bench driver")],
          ["driver.gateway", "driver.master", "driver.gateway-ms", "driver.master-ms"], parse_driver),
    Group("vcan", "the runtime on vcan in the VM", ["bash .ci/tier-vcan.sh"],
          ["vcan.throughput", "vcan.cpu16", "vcan.cpu1", "vcan.round-trip", "vcan.kit-added", "vcan.kit-rate",
           "vcan.kit-ratio"], parse_vcan,
          needs="the qemu VM of .ci/vcanvm (its kernel and CAN modules, downloaded once)"),
    Group("kit", "the failover kit's fault bridge",
          ["cargo build -p duocan-cli",
           NETNS.format("cargo run -q --offline -p duocan-cli -- kit bench --bare udp:11 --a udp:12 --b udp:13 --frames 5000")],
          ["kit.added", "kit.ratio"], parse_kit, needs="unshare -rn"),
    Group("station", "the station under load",
          ["cargo build --release -p duocan-cli", NETNS.format("python3 .ci/station-figures.py")],
          ["station.load", "station.frames", "station.cpu", "station.cpu-frame", "station.cpu-can-frame",
           "station.rss", "station.peak", "station.sse", "station.mqtt"], parse_station,
          quick=["cargo build --release -p duocan-cli", NETNS.format("python3 .ci/station-figures.py --quick")],
          needs="unshare -rn (a user namespace) for the private UDP buses; mosquitto for the MQTT figure"),
    Group("fuzz", "fuzzing, five minutes per target, one at a time",
          ["FUZZ_SECONDS=300 FUZZ_JOBS=1 bash .ci/fuzz.sh"], ["fuzz.seconds", "fuzz.table"], parse_fuzz,
          quick=["FUZZ_SECONDS=2 bash .ci/fuzz.sh"], needs="cargo-fuzz"),
]
BY_NAME = {g.name: g for g in GROUPS}
# Written for every run rather than by a group.
SPECIAL = ["machine", "runs"]


def known_figures():
    names = list(SPECIAL)
    for g in GROUPS:
        names += g.figures
    return names


def loadavg():
    with open("/proc/loadavg") as f:
        return " ".join(f.read().split()[:3])


def machine():
    model = "unknown processor"
    try:
        for line in subprocess.run(["lscpu"], capture_output=True, text=True).stdout.splitlines():
            if line.startswith("Model name:"):
                model = line.split(":", 1)[1].strip()
                break
    except FileNotFoundError:
        pass
    rustc = subprocess.run(["rustc", "-V"], capture_output=True, text=True).stdout.strip()
    return f"{os.cpu_count()} CPUs, `lscpu` naming the processor \"{model}\"; {rustc}"


def check(text):
    """Every marker is a figure the script writes and every figure has a marker: the list of
    problems (empty when the page and the script agree)."""
    found = [m[1] for m in MARKER.finditer(text)]
    known = known_figures()
    problems = [f"marker '{n}' in BENCHMARKS.md is no figure of .ci/benchmarks.py" for n in found if n not in known]
    problems += [f"figure '{n}' of .ci/benchmarks.py has no marker in BENCHMARKS.md" for n in known if n not in found]
    opened = len(re.findall(r"<!-- figure:", text))
    if opened != len(found):
        problems.append(f"{opened - len(found)} marker(s) without their closing <!-- /figure -->")
    problems += check_readme(text)
    return problems


def check_readme(page):
    """The README's markers: each one of the page's, with the page's figure (the problems)."""
    with open(README) as f:
        readme = f.read()
    values = {m[1]: m[2] for m in MARKER.finditer(page)}
    problems = []
    for m in MARKER.finditer(readme):
        if m[1] not in values:
            problems.append(f"marker '{m[1]}' in README.md is no figure of BENCHMARKS.md")
        elif m[2] != values[m[1]]:
            problems.append(f"README.md's '{m[1]}' is {m[2]!r}, BENCHMARKS.md's {values[m[1]]!r}")
    opened = len(re.findall(r"<!-- figure:", readme))
    if opened != len(MARKER.findall(readme)):
        problems.append("README.md has a marker without its closing <!-- /figure -->")
    return problems


RUNS_HEAD = "| Group | Command | Date | Load average at its start |\n| --- | --- | --- | --- |"


def runs_rows(text):
    """The runs table's rows now in the page: {group: row}."""
    m = re.search(r"<!-- figure: runs -->(.*?)<!-- /figure -->", text, re.S)
    rows = {}
    for line in (m[1] if m else "").splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) == 4 and cells[0] in BY_NAME:
            rows[cells[0]] = line.strip()
    return rows


def shown(g, quick=False):
    """The commands that give a group's figures, as the runs table names them (builds left out,
    a command run several times named once with the count)."""
    cmds = [c.replace(CRIT, "").rstrip(" -") for c in (g.quick if quick else g.commands)]
    cmds = [c for c in cmds if not c.startswith("cargo build") and not c.endswith("--no-run")]
    out = []
    for c in dict.fromkeys(cmds):
        n = cmds.count(c)
        out.append(f"`{c}`" + (f" ({n} times)" if n > 1 else ""))
    return ", ".join(out)


def run_group(g, quick, log):
    crit = "--warm-up-time 0.5 --measurement-time 1 --sample-size 10" if quick else ""
    outputs = []
    for c in (g.quick if quick else g.commands):
        cmd = c.replace(CRIT, crit)
        print(f"=== {g.name}: {cmd}", flush=True)
        log.write(f"\n=== {cmd}\n")
        env = dict(os.environ)
        venv = os.path.join(target_dir(), "pyenv", "bin", "python")  # as .ci/tier-python.sh makes it
        if "DUOCAN_PYTHON" not in env and os.path.exists(venv):
            env["DUOCAN_PYTHON"] = venv
        p = subprocess.Popen(cmd, shell=True, cwd=ROOT, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                             text=True)
        for line in p.stdout:
            sys.stdout.write(line)
            log.write(line)
            outputs.append(line)
        if p.wait() != 0:
            raise Missing(f"`{cmd}` exited {p.returncode}" + (f" (needs {g.needs})" if g.needs else ""))
    return "".join(outputs)


def write(out, text, values, rows):
    """The page with the figures in place, written after every group (an interrupted run keeps
    the groups it finished)."""
    values["runs"] = "\n" + RUNS_HEAD + "\n" + "\n".join(
        rows.get(g.name, f"| {g.name} | {shown(g)} | not run | |") for g in GROUPS) + "\n"
    new = MARKER.sub(lambda m: f"<!-- figure: {m[1]} -->{values[m[1]]}<!-- /figure -->", text)
    with open(out + ".tmp", "w") as f:
        f.write(new)
    os.replace(out + ".tmp", out)
    if out == PAGE:
        with open(README) as f:
            readme = f.read()
        readme = MARKER.sub(lambda m: f"<!-- figure: {m[1]} -->{values.get(m[1], m[2])}<!-- /figure -->", readme)
        with open(README + ".tmp", "w") as f:
            f.write(readme)
        os.replace(README + ".tmp", README)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("groups", nargs="*", help="groups to run (default: every one)")
    ap.add_argument("--quick", action="store_true", help="shortened runs, written to target/BENCHMARKS.quick.md")
    ap.add_argument("--out", help="the page to write (default BENCHMARKS.md; with --quick target/BENCHMARKS.quick.md)")
    ap.add_argument("--list", action="store_true", help="the groups, their commands and figures")
    ap.add_argument("--check", action="store_true", help="only check the markers against the script's figures")
    a = ap.parse_args()

    with open(PAGE) as f:
        text = f.read()
    if a.list:
        for g in GROUPS:
            print(f"{g.name}: {g.title}")
            print(f"    {shown(g)}")
            print(f"    figures: {', '.join(g.figures)}")
        return 0
    problems = check(text)
    if problems or a.check:
        for p in problems:
            print(f"benchmarks: {p}", file=sys.stderr)
        if not problems:
            print(f"benchmarks: the {len(known_figures())} figures of .ci/benchmarks.py and BENCHMARKS.md's markers agree")
        return 1 if problems else 0
    unknown = [n for n in a.groups if n not in BY_NAME]
    if unknown:
        ap.error(f"no group {', '.join(unknown)} (--list names them)")
    chosen = [BY_NAME[n] for n in a.groups] if a.groups else GROUPS
    out = a.out or (os.path.join(target_dir(), "BENCHMARKS.quick.md") if a.quick else PAGE)

    values = {m[1]: m[2] for m in MARKER.finditer(text)}
    here = machine()
    if len(chosen) < len(GROUPS) and values.get("machine") not in (None, "", here) and not a.quick:
        print(f"benchmarks: the page's figures come from {values['machine']!r}, this machine is {here!r}: "
              "run every group here (no group names), so the page names one machine", file=sys.stderr)
        return 1
    values["machine"] = here
    rows = runs_rows(text)
    os.makedirs(target_dir(), exist_ok=True)
    failed = []
    with open(os.path.join(target_dir(), "benchmarks.log"), "w") as log:
        for g in chosen:
            load, date, since = loadavg(), time.strftime("%Y-%m-%d", time.gmtime()), time.time() - 1
            try:
                got = g.parse(run_group(g, a.quick, log), since, a.quick)
                if set(got) != set(g.figures):
                    raise Missing(f"the parser gave {sorted(got)}, the group declares {sorted(g.figures)}")
            except Missing as e:
                print(f"benchmarks: {g.name}: FAILED: {e}", file=sys.stderr)
                failed.append(g.name)
                continue
            values.update(got)
            write(out, text, values, rows)
            rows[g.name] = f"| {g.name} | {shown(g, a.quick)}{' (quick)' if a.quick else ''} | {date} | {load} |"
            print(f"--- {g.name}: " + "; ".join(f"{k} = {v.strip()}" for k, v in got.items() if "\n" not in v))
    write(out, text, values, rows)
    print(f"benchmarks: wrote {out} ({len(chosen) - len(failed)} of {len(chosen)} groups; log in "
          f"{os.path.join(target_dir(), 'benchmarks.log')})")
    if failed:
        print(f"benchmarks: FAILED groups, their figures left as they were: {', '.join(failed)}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
