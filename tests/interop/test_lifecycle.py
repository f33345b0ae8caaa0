"""Starting and stopping the process: banner, SIGINT/SIGTERM with clients attached, a taken port."""

import signal
import socket
import subprocess
import time

from conftest import CHANNEL, DRIVETWIN_BIN, HOST, RawClient, recv_id


def test_banner_lines(cmmp):
    lines = cmmp.stdout_lines
    assert lines[0].startswith("drive cmmp-as node 1"), lines
    assert f"socketcand server on {cmmp.addr}, channel {CHANNEL}" in lines
    # "running" follows the server line (it may still be in the pipe)
    deadline = time.monotonic() + 2
    while "running; Ctrl-C stops" not in cmmp.stdout_lines and time.monotonic() < deadline:
        time.sleep(0.02)
    assert "running; Ctrl-C stops" in cmmp.stdout_lines


def test_sigint_stops_cleanly(cmmp, node_of):
    assert node_of(cmmp).sdo[0x1018][1].raw == 0x1D
    cmmp.proc.send_signal(signal.SIGINT)
    assert cmmp.proc.wait(5) == 0
    cmmp.stop()  # checks exit 0 and "stopped"


def test_sigterm_with_clients_in_the_middle_of_transfers(bench, node_of, raw_bus):
    node = node_of(bench)
    assert node.sdo[0x2005].raw == 42
    bus = raw_bus(bench)
    hand = RawClient(bench.port)
    hand.handshake()
    hand.send(b"< send 601 8 40 08 10 00 00 00 00 00 >")  # a segmented upload left open
    assert recv_id(bus, 0x581, 1.0) is not None
    t0 = time.monotonic()
    bench.stop()  # SIGTERM; asserts exit 0 and "stopped"
    assert time.monotonic() - t0 < 3
    # the hand-made client sees the connection end
    deadline = time.monotonic() + 2
    while hand.read_message(0.2) is not None or not hand.closed:
        assert time.monotonic() < deadline, "client connection still open after the server stopped"
    hand.close()


def test_port_already_taken_fails_fast():
    with socket.socket() as s:
        s.bind((HOST, 0))
        s.listen()
        port = s.getsockname()[1]
        t0 = time.monotonic()
        r = subprocess.run([str(DRIVETWIN_BIN), "run", "--socketcand", f"{HOST}:{port}",
                            "--channel", CHANNEL], capture_output=True, text=True, timeout=10)
        assert time.monotonic() - t0 < 5
    assert r.returncode != 0
    assert str(port) in r.stderr and "in use" in r.stderr.lower(), r.stderr
