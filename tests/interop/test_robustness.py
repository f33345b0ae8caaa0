"""7. Bad input never crashes or wedges the server.

A cell with two drives: node 2 (cmmp-as) is read by a well-behaved python-canopen client the whole
time; node 1 (testbench) takes the malformed and random SDO frames (two masters on one SDO channel
would disturb each other on a real bus too). Raw TCP clients send socketcand garbage at the same
time. At the end every good read has succeeded, node 1 answers again, and the process runs.
"""

import random
import threading
import time

import can
import pytest

from conftest import add_node, RawClient, abort_frame, recv_id, write_cell


class GoodClient(threading.Thread):
    def __init__(self, node):
        super().__init__(daemon=True)
        self.node = node
        self.stop = threading.Event()
        self.ok = 0
        self.failures: list[str] = []

    def run(self):
        while not self.stop.is_set():
            try:
                assert self.node.sdo[0x1018][1].raw == 0x1D
                assert self.node.sdo.upload(0x1008, 0) == b"CMMP-AS-C2-3A-M3"  # segmented
                self.ok += 1
            except Exception as e:  # noqa: BLE001 - every failure counts
                self.failures.append(repr(e))


@pytest.fixture
def cell(launch, tmp_path):
    cfg = write_cell(tmp_path / "cell.toml", [("testbench", 1, {"1017:00": 1000}),
                                              ("cmmp-as", 2, {"1017:00": 1000})])
    return launch(config=cfg)


def _garbage_socketcand(port: int, seed: int) -> list[str]:
    """Messages a confused client sends; returns what the server answered (errors)."""
    answers = []
    rng = random.Random(seed)

    # random bytes before and instead of the handshake
    c = RawClient(port)
    c.expect("< hi >")
    c.send(rng.randbytes(4096))
    msg = c.reply(1.0)
    answers.append(msg if msg is not None else ("<closed>" if c.closed else "<silent>"))
    c.close()

    # a session that opens the bus and then sends nonsense
    c = RawClient(port)
    c.handshake()
    bad = [
        b"< send 601 9 40 08 10 00 00 00 00 00 00 >",  # DLC 9
        b"< send 601 8 40 08 10 00 >",  # fewer bytes than the DLC
        b"< send 801 1 00 >",  # identifier out of range
        b"< send 6g1 1 00 >",  # not hex
        b"< send 601 2 400 01 >",  # byte out of range
        b"< frobnicate 1 2 3 >",  # unknown command
        b"< >",  # empty
        b"<\x00\xff\x80\x7f>",  # not printable
        b"< " + b"A" * 5120,  # 5 KiB without ">" (last: the server may drop up to the next ">")
    ]
    for m in bad:
        if not c.send(m):
            answers.append("<closed>")
            break
        msg = c.reply(1.0)
        answers.append(msg if msg is not None else ("<closed>" if c.closed else "<silent>"))
    c.close()

    # a bus that is not served
    c = RawClient(port)
    c.expect("< hi >")
    c.send(b"< open wrongbus >")
    answers.append(c.reply(1.0) or "<closed>")
    c.close()
    return answers


def test_bad_input_never_crashes_or_wedges(cell, connect, eds_files, raw_bus):
    net = connect(cell)
    good = add_node(net, 2, eds_files["cmmp-as"])
    client = GoodClient(good)
    client.start()
    listener = raw_bus(cell)

    try:
        answers = _garbage_socketcand(cell.port, seed=1)
        for a in answers:
            assert a.startswith("< error ") or a == "<closed>", answers
        assert answers[-1] in ("< error could not open bus >", "<closed>")
        assert "< error unknown command >" in answers
        assert "<silent>" not in answers, answers

        # a client that starts a segmented upload on node 1 and disconnects in the middle
        c = RawClient(cell.port)
        c.handshake()
        c.send(b"< send 601 8 40 08 10 00 00 00 00 00 >")
        t0 = time.monotonic()
        c.close()
        # node 1 answered the initiate, then times the transfer out (0504 0000h) by itself
        msg = recv_id(listener, 0x581, 1.0)
        assert msg is not None and bytes(msg.data) == bytes.fromhex("41 08 10 00 14 00 00 00")
        msg = recv_id(listener, 0x581, 3.0)
        assert msg is not None and bytes(msg.data) == abort_frame(0x1008, 0, 0x05040000)
        assert time.monotonic() - t0 > 0.8

        # SDO requests of the wrong length and random SDO frames on node 1
        bad_bus = raw_bus(cell)
        for data in (b"", b"\x40\x08\x10", b"\x40", b"\x60", b"\x80"):
            bad_bus.send(can.Message(arbitration_id=0x601, data=data, is_extended_id=False))
        rng = random.Random(7)
        for _ in range(300):
            data = rng.randbytes(rng.randint(0, 8))
            bad_bus.send(can.Message(arbitration_id=0x601, data=data, is_extended_id=False))
        # and a burst of frames to identifiers nobody uses
        for i in range(100):
            bad_bus.send(can.Message(arbitration_id=0x100 + i, data=rng.randbytes(8),
                                     is_extended_id=False))
        bad_bus.send(can.Message(arbitration_id=0x1ABCDEF, data=b"\x01", is_extended_id=True))
        # a marker after the storm: once the listener sees it, the server has put every frame
        # of the storm on the bus (the drives see them in bus order)
        marker = b"END-MARK"
        bad_bus.send(can.Message(arbitration_id=0x0FF, data=marker, is_extended_id=False))
        deadline = time.monotonic() + 10
        while True:
            msg = recv_id(listener, 0x0FF, max(0.0, deadline - time.monotonic()))
            assert msg is not None, "the storm's end marker never came through"
            if bytes(msg.data) == marker:
                break

        # the good client keeps reading for a moment after the storm
        ok_before = client.ok
        deadline = time.monotonic() + 5
        while client.ok < ok_before + 5 and time.monotonic() < deadline and not client.failures:
            time.sleep(0.02)
    finally:
        client.stop.set()
        client.join(5)

    assert not client.failures, client.failures[:5]
    assert client.ok >= 10, f"only {client.ok} good reads"
    assert cell.running(), f"drivetwin died: {cell.stderr()[-2000:]}"

    # node 1 is not wedged: once any half-done transfer has timed out it answers correctly
    import canopen

    node1 = add_node(net, 1, eds_files["testbench"])
    node1.sdo.RESPONSE_TIMEOUT = 1.0
    deadline = time.monotonic() + 8
    while True:
        try:
            value = node1.sdo[0x2005].raw
            break
        except (canopen.SdoCommunicationError, canopen.SdoAbortedError):
            assert time.monotonic() < deadline, "node 1 never answered again"
    assert value == 42
    assert node1.sdo.upload(0x1008, 0) == b"drivetwin test bench"
    # and new socketcand clients are still served
    c = RawClient(cell.port)
    c.handshake()
    c.close()


def test_short_sdo_frames_get_a_defined_answer(bench, raw_bus):
    """Short SDO requests (DLC < 8) are taken as zero-padded; DLC 0 is an unknown command."""
    from conftest import sdo_request

    bus = raw_bus(bench)
    assert sdo_request(bus, 1, b"") == abort_frame(0, 0, 0x05040001)
    # a 4-byte upload initiate of 2005h is answered like the full one
    assert sdo_request(bus, 1, b"\x40\x05\x20\x00") == bytes.fromhex("4F 05 20 00 2A 00 00 00")


def test_many_clients_connect_and_disconnect(bench, node_of):
    """Client churn leaves the server serving."""
    for _ in range(30):
        c = RawClient(bench.port)
        c.handshake()
        c.send(b"< send 601 8 40 05 20 00 00 00 00 00 >")
        c.close()
    node = node_of(bench)
    assert node.sdo[0x2005].raw == 42
    assert bench.running()
