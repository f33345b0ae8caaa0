"""The CMMP-AS CI terminal (debug console, manual §3.2.3) served by `drivetwin run
--ci-terminal`: SDO simulation lines over a plain TCP socket, checked against python-canopen's
view of the same dictionary."""

import socket

from conftest import HOST, free_port, run_cli, wait_until


def _console(twin, port):
    wait_until(lambda: any(l.startswith("CI terminal of drive 1 on") for l in twin.stdout_lines),
               5.0, what="the CI terminal line")
    s = socket.create_connection((HOST, port), timeout=3)
    f = s.makefile("rwb", buffering=0)
    return s, f


def _ask(f, line: str) -> str:
    f.write(line.encode() + b"\r\n")
    answer = f.readline()
    assert answer.endswith(b"\r\n"), answer
    return answer[:-2].decode()


def test_ci_terminal_vectors_over_tcp(launch, node_of):
    """CMMP-CI-01, CMMP-CI-02, CMMP-CI-03, CMMP-CI-04 through the binary's console."""
    port = free_port()
    twin = launch("cmmp-as", 1, extra=("--ci-terminal", f"{HOST}:{port}"))
    node = node_of(twin)
    s, f = _console(twin, port)
    try:
        node.sdo[0x6060].raw = 1
        wait_until(lambda: node.sdo[0x6061].raw == 1, 2.0, what="profile position mode")
        assert _ask(f, "?606100") == "=606100:01"
        assert _ask(f, "=604000:000F") == "=604000:000F"
        assert node.sdo[0x6040].raw == 0x000F, "the console wrote the drive's controlword"
        assert _ask(f, "?609301") == "=609301:00000001"
        assert _ask(f, "=604100:0000") == "!06010002"
        # A value written over CAN reads back on the console, most significant digit first.
        node.sdo[0x6093][2].raw = 0x13
        node.sdo[0x6093][1].raw = 0x12345678
        assert _ask(f, "?609301") == "=609301:12345678"
        # Garbage gets an answer and the console keeps serving.
        assert _ask(f, "hello") == "!05040001"
        assert _ask(f, "x" * 200) == "!05040001"
        assert _ask(f, "?606100") == "=606100:01"
    finally:
        s.close()


def test_ci_terminal_only_on_loopback():
    r = run_cli("run", "--device", "cmmp-as", "--socketcand", f"{HOST}:{free_port()}",
                "--ci-terminal", "0.0.0.0:29999", timeout=10)
    assert r.returncode != 0
    assert "loopback only" in r.stderr, r.stderr
