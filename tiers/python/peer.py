"""An independent CANopen peer for duocan's tests: python `canopen` over python-can's
udp_multicast bus. Driven by tests/python_peer.rs; talks to it through stdout lines.

    peer.py node ID HB_MS GROUP PORT     LocalNode: SDO server, heartbeat, NMT slave
    peer.py client NODE GROUP PORT        SDO client: reads and writes NODE's dictionary
    peer.py junk GROUP PORT              python-can sends frames duocan must refuse, then one good
    peer.py storage NODE GROUP PORT       stores and restores NODE's parameters (0x1010/0x1011)
    peer.py eds NODE FILE GROUP PORT      a RemoteNode whose dictionary is the EDS FILE: reads and
                                          writes NODE's entries by name, as stdin asks
    peer.py lss NODE GROUP PORT           python's LSS master: finds the non-configured slave by
                                          fastscan, gives it NODE, stores, watches it boot
    peer.py fd GROUP PORT                 python-can with fd=True: sends CAN FD frames (and one
                                          classic), then reports every frame it receives
    peer.py rawfd GROUP PORT              python-can with fd=True, driven line by line: "send <id
                                          hex> <ext> <brs> <esi> <data hex or ->" sends one CAN FD
                                          frame (answered "SENT <id hex>"); reports every frame
                                          it receives (a raw peer: USDO requests built by hand)
Stdout: one line per event: "READY", "STATE <name>", "WRITE <index> <sub> <hex>" (a write to the
LocalNode), "READ <index> <sub> <hex>", "WROTE <index> <sub>", "ABORT <index> <sub> <code>",
"READ-NO-CRC …"/"WROTE-NO-CRC …" (block transfers that did not ask for CRC), "DONE", "SENT <n>",
"VALUE\t<name>\t<value>", "NAMES <count>", "ERROR <command> <exception>",
"RX <id hex> <ext> <fd> <brs> <esi> <dlc> <data hex>" (a frame the fd peer received). Ends when
stdin closes.
"""
import faulthandler
import signal
import struct
import sys
import threading
import time

import can
import canopen
from canopen import objectdictionary as odm
from canopen.objectdictionary import datatypes as dt


_say_lock = threading.Lock()


def say(*words):
    # One write per line under a lock: print() from two threads (the NMT state loop and the
    # command thread) can interleave the words of one line with the newline of another.
    with _say_lock:
        sys.stdout.write(" ".join(str(w) for w in words) + "\n")
        sys.stdout.flush()


def var(name, index, sub, data_type, access, default):
    v = odm.ODVariable(name, index, sub)
    v.data_type = data_type
    v.access_type = access
    v.default = default
    return v


def dictionary(node_id, hb_ms):
    od = odm.ObjectDictionary()
    od.node_id = node_id
    od.add_object(var("Device type", 0x1000, 0, dt.UNSIGNED32, "ro", 0x00020192))
    od.add_object(var("Producer heartbeat time", 0x1017, 0, dt.UNSIGNED16, "rw", hb_ms))
    ident = odm.ODRecord("Identity object", 0x1018)
    ident.add_member(var("Number of entries", 0x1018, 0, dt.UNSIGNED8, "ro", 1))
    ident.add_member(var("Vendor-ID", 0x1018, 1, dt.UNSIGNED32, "ro", 0xD0CA))
    od.add_object(ident)
    od.add_object(var("Expedited value", 0x2000, 0, dt.UNSIGNED32, "rw", 0x12345678))
    od.add_object(var("Segmented text", 0x2001, 0, dt.VISIBLE_STRING, "rw",
                      "python canopen peer: a string longer than four bytes"))
    od.add_object(var("Domain", 0x2002, 0, dt.DOMAIN, "rw", b""))
    od.add_object(var("Process value", 0x6000, 0, dt.UNSIGNED16, "rw", 0))
    tpdo = odm.ODRecord("TPDO1 communication parameter", 0x1800)
    tpdo.add_member(var("Highest sub-index", 0x1800, 0, dt.UNSIGNED8, "ro", 5))
    tpdo.add_member(var("COB-ID", 0x1800, 1, dt.UNSIGNED32, "rw", 0x180 + node_id))
    tpdo.add_member(var("Transmission type", 0x1800, 2, dt.UNSIGNED8, "rw", 254))
    od.add_object(tpdo)
    tmap = odm.ODRecord("TPDO1 mapping parameter", 0x1A00)
    tmap.add_member(var("Number of entries", 0x1A00, 0, dt.UNSIGNED8, "rw", 1))
    tmap.add_member(var("Entry 1", 0x1A00, 1, dt.UNSIGNED32, "rw", 0x60000010))
    od.add_object(tmap)
    return od


def watch_stdin(stop, local=None):
    """Commands from the test; end of input stops the peer.
    `tpdo VALUE`: TPDO1 (0x6000, 16 bits) carries VALUE, sent every 50 ms."""
    tpdo = None
    for line in sys.stdin:
        words = line.split()
        if local is not None and words[:1] == ["tpdo"]:
            try:
                if tpdo is None:
                    tpdo = local.tpdo[1]
                    tpdo.clear()
                    tpdo.add_variable(0x6000)
                    tpdo.cob_id = 0x180 + local.id
                    tpdo.enabled = True
                    tpdo.map[0].raw = int(words[1], 0)
                    tpdo.start(0.05)
                else:
                    tpdo.map[0].raw = int(words[1], 0)
                    tpdo.update()
            except Exception as e:  # the test fails with this line instead of a silent timeout
                say("ERROR", line.strip(), repr(e))
                continue
            say("TPDO", words[1])
    if tpdo is not None:
        tpdo.stop()
    stop.set()


def node(node_id, hb_ms, group, port):
    network = canopen.Network()
    network.connect(interface="udp_multicast", channel=group, port=port)
    local = canopen.LocalNode(node_id, dictionary(node_id, hb_ms))
    network.add_node(local)

    def on_write(index, subindex, od, data):
        say("WRITE", "%04X" % index, subindex, bytes(data).hex())

    local.add_write_callback(on_write)
    stop = threading.Event()
    threading.Thread(target=watch_stdin, args=(stop, local), daemon=True).start()
    say("READY")
    local.nmt.state = "INITIALISING"  # boot-up message
    local.nmt.state = "PRE-OPERATIONAL"  # starts the heartbeat
    last = None
    while not stop.is_set():
        st = local.nmt.state
        if st != last:
            say("STATE", st)
            last = st
        time.sleep(0.01)
    network.disconnect()


def pattern(n, seed):
    return bytes(((i * 31) + seed) & 0xFF for i in range(n))


def remote_on_bus(node_id, group, port, description=None):
    """A network on the UDP bus with one remote node (an empty dictionary, or the EDS at
    `description`), its SDO client patient enough for a loaded CI machine; says READY."""
    network = canopen.Network()
    network.connect(interface="udp_multicast", channel=group, port=port)
    if description is None:
        remote = canopen.RemoteNode(node_id, odm.ObjectDictionary())
        network.add_node(remote)
    else:
        remote = network.add_node(node_id, description)
    remote.sdo.RESPONSE_TIMEOUT = 2.0
    say("READY")
    return network, remote


def client(node_id, group, port):
    network, remote = remote_on_bus(node_id, group, port)
    sdo = remote.sdo
    sys.stdin.readline()  # the test says when duocan's node is up

    def read(index, sub):
        say("READ", "%04X" % index, sub, sdo.upload(index, sub).hex())

    def write(index, sub, data, force_segment=False):
        sdo.download(index, sub, data, force_segment=force_segment)
        say("WROTE", "%04X" % index, sub)

    read(0x1018, 1)                                   # expedited upload
    read(0x2001, 0)                                   # segmented upload
    write(0x2000, 0, struct.pack("<I", 0x11223344))   # expedited download
    write(0x2001, 0, b"written by python canopen over segmented SDO", force_segment=True)
    blob = pattern(1000, 9)
    with sdo.open(0x2002, 0, "wb", size=len(blob), block_transfer=True) as f:
        f.write(blob)                                 # block download
    say("WROTE", "2002", 0)
    with sdo.open(0x2002, 0, "rb", block_transfer=True) as f:
        say("READ", "2002", 0, f.read().hex())        # block upload
    sys.stdin.readline()  # the test has checked the first blob: the next write replaces it
    # Block transfers without asking for CRC: python's client still checks (upload) and sends
    # (download) the CRC whenever the server's initiate response sets its support bit.
    try:
        blob = pattern(700, 77)
        with sdo.open(0x2002, 0, "wb", size=len(blob), block_transfer=True,
                      request_crc_support=False) as f:
            f.write(blob)
        say("WROTE-NO-CRC", "2002", 0)
        with sdo.open(0x2002, 0, "rb", block_transfer=True, request_crc_support=False) as f:
            say("READ-NO-CRC", "2002", 0, f.read().hex())
    except Exception as e:  # a CRC mismatch raises SdoCommunicationError: say so, go on
        say("ERROR", "block transfer without CRC", repr(e))
    try:
        sdo.upload(0x2100, 0)
    except canopen.SdoAbortedError as e:
        say("ABORT", "2100", 0, "0x%08X" % e.code)
    say("DONE")
    for _ in sys.stdin:
        pass
    network.disconnect()


def storage(node_id, group, port):
    network, remote = remote_on_bus(node_id, group, port)
    sdo = remote.sdo
    sys.stdin.readline()  # the test says when duocan's node is up

    def read(index, sub):
        say("READ", "%04X" % index, sub, sdo.upload(index, sub).hex())

    # python canopen's wait_for_bootup listens only from when it is called: a boot-up that came
    # first (duocan's node answers a reset within a millisecond) is missed. Listen before asking.
    booted = threading.Event()

    def on_boot_up(can_id, data, timestamp):
        if data[:1] == b"\x00":
            booted.set()

    network.subscribe(0x700 + node_id, on_boot_up)

    def reset(command):
        booted.clear()
        remote.nmt.send_command(command)
        if not booted.wait(5):
            raise RuntimeError("no boot-up within 5 s of NMT command 0x%02X" % command)
        say("BOOTED")

    read(0x1010, 2)                                   # the capability: stores on command
    sdo.download(0x1017, 0, struct.pack("<H", 300))   # a volatile write over SDO
    try:
        sdo.download(0x1010, 2, b"nope")
    except canopen.SdoAbortedError as e:
        say("ABORT", "1010", 2, "0x%08X" % e.code)
    remote.store(2)                                   # "save": the communication parameters
    say("STORED")
    reset(0x81)                                       # reset node: the stored value comes back
    read(0x1017, 0)
    remote.restore(1)                                 # "load": not at once...
    say("RESTORED")
    read(0x1017, 0)
    reset(0x82)                                       # ...at the next reset
    read(0x1017, 0)
    say("DONE")
    for _ in sys.stdin:
        pass
    network.disconnect()


def by_name(node, name):
    """An entry by name: "Record/Member" for a member of a record or array."""
    parts = name.split("/")
    var = node.sdo[parts[0]]
    for p in parts[1:]:
        var = var[int(p) if p.isdigit() else p]
    return var


def eds(node_id, path, group, port):
    network, node = remote_on_bus(node_id, group, port, path)
    # The objects, less the data-type dummies python adds for [DummyUsage].
    say("NAMES", len([i for i in node.object_dictionary.keys() if isinstance(i, int) and i >= 0x20]))
    # Tab-separated commands: "read<TAB>name", "write<TAB>name<TAB>value".
    for line in sys.stdin:
        words = line.rstrip("\n").split("\t")
        try:
            if words[0] == "read":
                say("VALUE\t%s\t%s" % (words[1], by_name(node, words[1]).raw))
            elif words[0] == "write":
                var = by_name(node, words[1])
                var.raw = int(words[2], 0) if var.od.data_type not in (dt.VISIBLE_STRING, dt.UNICODE_STRING) else words[2]
                say("WROTE\t%s" % words[1])
        except Exception as e:  # the test fails with this line instead of a silent timeout
            say("ERROR", line.strip(), repr(e))
    network.disconnect()


def junk(group, port):
    bus = can.Bus(interface="udp_multicast", channel=group, port=port)
    say("READY")
    sent = 0
    # A CAN FD frame and an error frame: valid python-can messages, not classic CAN frames.
    bus.send(can.Message(arbitration_id=0x123, is_fd=True, data=bytes(range(12)), is_extended_id=False))
    sent += 1
    bus.send(can.Message(arbitration_id=0x0, is_error_frame=True, data=bytes(8)))
    sent += 1
    # Then a good one that must arrive.
    bus.send(can.Message(arbitration_id=0x5A5, data=[1, 2, 3], is_extended_id=False))
    say("SENT", sent)
    for _ in sys.stdin:
        pass
    bus.shutdown()


def fd_peer(group, port):
    """python-can's own CAN FD frames to duocan, and duocan's back: each received frame as an
    RX line with its flags and bytes."""
    bus = can.Bus(interface="udp_multicast", channel=group, port=port, fd=True)
    say("READY")
    sys.stdin.readline()  # the test says when its port listens
    sent = [
        can.Message(arbitration_id=0x181, is_extended_id=False, is_fd=True, bitrate_switch=True,
                    data=bytes(range(12))),
        can.Message(arbitration_id=0x1ABCDE, is_extended_id=True, is_fd=True,
                    error_state_indicator=True, data=bytes([0xA5] * 64)),
        can.Message(arbitration_id=0x182, is_extended_id=False, is_fd=True, bitrate_switch=True,
                    error_state_indicator=True, data=bytes(range(100, 148))),
        can.Message(arbitration_id=0x183, is_extended_id=False, is_fd=True, data=b""),
        can.Message(arbitration_id=0x701, is_extended_id=False, data=[0x05]),
    ]
    for m in sent:
        bus.send(m)
    say("SENT", len(sent))

    def listen():
        while True:
            m = bus.recv(0.1)
            if m is None:
                continue
            say("RX", "%x" % m.arbitration_id, int(m.is_extended_id), int(m.is_fd),
                int(m.bitrate_switch), int(m.error_state_indicator), m.dlc, bytes(m.data).hex() or "-")

    threading.Thread(target=listen, daemon=True).start()
    for _ in sys.stdin:
        pass
    bus.shutdown()


def raw_fd_peer(group, port):
    """python-can's CAN FD bus as a raw peer: sends the frames stdin names, byte for byte, and
    reports every frame it receives as an RX line."""
    bus = can.Bus(interface="udp_multicast", channel=group, port=port, fd=True)

    def listen():
        while True:
            m = bus.recv(0.1)
            if m is None:
                continue
            say("RX", "%x" % m.arbitration_id, int(m.is_extended_id), int(m.is_fd),
                int(m.bitrate_switch), int(m.error_state_indicator), m.dlc, bytes(m.data).hex() or "-")

    threading.Thread(target=listen, daemon=True).start()
    say("READY")
    for line in sys.stdin:
        words = line.split()
        if len(words) != 6 or words[0] != "send":
            say("ERROR", line.strip(), "expected: send ID EXT BRS ESI DATA")
            continue
        data = b"" if words[5] == "-" else bytes.fromhex(words[5])
        bus.send(can.Message(arbitration_id=int(words[1], 16), is_extended_id=words[2] == "1",
                             is_fd=True, bitrate_switch=words[3] == "1",
                             error_state_indicator=words[4] == "1", data=data))
        say("SENT", words[1])
    bus.shutdown()


def lss_master(node_id, group, port):
    """python `canopen`'s LSS master against one non-configured slave: LSS lines on stdout
    ("NON-CONFIGURED yes", "FASTSCAN True <4 parts hex>", "INQUIRED <what> <value>",
    "CONFIGURED <id>", "STORED", "BOOT <id> <first NMT byte>", "SERIAL <hex>", "SELECTED",
    "NON-CONFIGURED no", "DONE")."""
    from canopen import lss as lssm
    network = canopen.Network()
    network.connect(interface="udp_multicast", channel=group, port=port)
    lss = network.lss
    lss.RESPONSE_TIMEOUT = 0.3  # each unanswered fastscan step costs this
    say("READY")
    sys.stdin.readline()  # the test says when the slave is up

    answers = []
    network.subscribe(0x7E4, lambda can_id, data, timestamp: answers.append(bytes(data)))

    def non_configured():
        # python's master sends identify non-configured without waiting for the answers (any
        # number of slaves may give one): listen for them here. The master's own queue holds
        # them too; its next request clears it.
        answers.clear()
        lss.send_identify_non_configured_remote_slave()
        time.sleep(0.3)
        return "yes" if any(a[0] == lssm.CS_IDENTIFY_NON_CONFIGURED_SLAVE for a in answers) else "no"

    say("NON-CONFIGURED", non_configured())
    found, ident = lss.fast_scan()  # the slave found is in configuration mode
    say("FASTSCAN", found, *("%08X" % x for x in (ident or [])))
    if not found:
        return
    say("INQUIRED", "node-id", lss.inquire_node_id())
    for name, cs in (("vendor", lssm.CS_INQUIRE_VENDOR_ID),
                     ("product", lssm.CS_INQUIRE_PRODUCT_CODE),
                     ("revision", lssm.CS_INQUIRE_REVISION_NUMBER),
                     ("serial", lssm.CS_INQUIRE_SERIAL_NUMBER)):
        say("INQUIRED", name, "%08X" % lss.inquire_lss_address(cs))
    lss.configure_node_id(node_id)
    say("CONFIGURED", node_id)
    lss.store_configuration()
    say("STORED")
    # Back to waiting: a slave that had no node-ID enters reset-communication by itself and
    # boots with the new one. Watch its NMT error control identifier before switching.
    heard = []
    booted = threading.Event()

    def on_nmt(can_id, data, timestamp):
        heard.append(data[0])
        booted.set()

    network.subscribe(0x700 + node_id, on_nmt)
    lss.send_switch_state_global(lss.WAITING_STATE)
    booted.wait(5)
    say("BOOT", node_id, heard[0] if heard else "none")
    remote = canopen.RemoteNode(node_id, odm.ObjectDictionary())
    network.add_node(remote)
    remote.sdo.RESPONSE_TIMEOUT = 2.0
    say("SERIAL", remote.sdo.upload(0x1018, 4).hex())
    lss.send_switch_state_selective(*ident)
    say("SELECTED")
    say("INQUIRED", "node-id", lss.inquire_node_id())
    lss.send_switch_state_global(lss.WAITING_STATE)
    say("NON-CONFIGURED", non_configured())
    say("DONE")
    for _ in sys.stdin:
        pass
    network.disconnect()


def main(argv):
    if argv[1] == "node":
        node(int(argv[2], 0), int(argv[3]), argv[4], int(argv[5]))
    elif argv[1] == "client":
        client(int(argv[2], 0), argv[3], int(argv[4]))
    elif argv[1] == "junk":
        junk(argv[2], int(argv[3]))
    elif argv[1] == "storage":
        storage(int(argv[2], 0), argv[3], int(argv[4]))
    elif argv[1] == "fd":
        fd_peer(argv[2], int(argv[3]))
    elif argv[1] == "rawfd":
        raw_fd_peer(argv[2], int(argv[3]))
    elif argv[1] == "lss":
        lss_master(int(argv[2], 0), argv[3], int(argv[4]))
    elif argv[1] == "eds":
        eds(int(argv[2], 0), argv[3], argv[4], int(argv[5]))
    else:
        raise SystemExit("unknown mode " + argv[1])


if __name__ == "__main__":
    # SIGUSR1 prints every thread's stack to stderr: the test asks for it when the peer hangs.
    faulthandler.register(signal.SIGUSR1, all_threads=True)
    main(sys.argv)
