"""python `canopen`'s side of the side-by-side benchmark (tiers/tests/python_bench.rs): the
same SDO transfers and PDO echo duocan does, on the same python-can udp_multicast bus, timed
here with the wall clock and this process's own CPU clock.

    bench.py client NODE GROUP PORT   SDO client of NODE; stdin names each measurement:
                                      "seg_up I S", "seg_down I S N", "block_up I S",
                                      "block_down I S N", "expedited I S COUNT"
    bench.py echo GROUP PORT          answers every frame 0x181 with 0x1A1 (same data), through
                                      canopen's network dispatch; stdin "cpu" asks for its CPU

Stdout: "READY", then per measurement "RESULT <name> <wall s> <cpu s> <bytes or ops>", or
"CPU <s>" for the echo; "ERROR <what> <exception>" if a measurement failed.
"""
import sys
import time

import canopen
from canopen import objectdictionary as odm


def say(*words):
    sys.stdout.write(" ".join(str(w) for w in words) + "\n")
    sys.stdout.flush()


def pattern(n, seed):
    return bytes(((i * 31) + seed) & 0xFF for i in range(n))


def measure(name, what, amount):
    """Runs what(), says its wall and CPU time and `amount` (what it moved)."""
    wall, cpu = time.perf_counter(), time.process_time()
    what()
    say("RESULT", name, "%.6f" % (time.perf_counter() - wall), "%.6f" % (time.process_time() - cpu),
        amount)


def client(node_id, group, port):
    network = canopen.Network()
    network.connect(interface="udp_multicast", channel=group, port=port)
    remote = canopen.RemoteNode(node_id, odm.ObjectDictionary())
    network.add_node(remote)
    sdo = remote.sdo
    sdo.RESPONSE_TIMEOUT = 2.0
    say("READY")
    for line in sys.stdin:
        words = line.split()
        if not words:
            continue
        cmd, index, sub = words[0], int(words[1], 16), int(words[2])
        try:
            if cmd == "seg_up":
                got = []
                measure(cmd, lambda: got.append(sdo.upload(index, sub)), 0)
                say("SIZE", len(got[0]))
            elif cmd == "seg_down":
                data = pattern(int(words[3]), 5)
                measure(cmd, lambda: sdo.download(index, sub, data, force_segment=True),
                        len(data))
            elif cmd == "block_up":
                def up():
                    with sdo.open(index, sub, "rb", block_transfer=True) as f:
                        got.append(f.read())
                got = []
                measure(cmd, up, 0)
                say("SIZE", len(got[0]))
            elif cmd == "block_down":
                data = pattern(int(words[3]), 7)

                def down():
                    with sdo.open(index, sub, "wb", size=len(data), block_transfer=True) as f:
                        f.write(data)
                measure(cmd, down, len(data))
            elif cmd == "expedited":
                count = int(words[3])

                def reads():
                    for _ in range(count):
                        sdo.upload(index, sub)
                measure(cmd, reads, count)
        except Exception as e:  # say what failed; the test fails on it
            say("ERROR", cmd, repr(e))
    network.disconnect()


def echo(group, port):
    network = canopen.Network()
    network.connect(interface="udp_multicast", channel=group, port=port)

    def answer(can_id, data, timestamp):
        network.send_message(0x1A1, data)

    network.subscribe(0x181, answer)
    say("READY")
    for line in sys.stdin:
        if line.strip() == "cpu":
            say("CPU", "%.6f" % time.process_time())
    network.disconnect()


def main(argv):
    if argv[1] == "client":
        client(int(argv[2], 0), argv[3], int(argv[4]))
    elif argv[1] == "echo":
        echo(argv[2], int(argv[3]))
    else:
        say("ERROR", "usage", "bench.py client NODE GROUP PORT | echo GROUP PORT")


if __name__ == "__main__":
    main(sys.argv)
