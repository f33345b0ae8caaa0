"""The CMMP-AS CI terminal (debug console, manual §3.2.3) served by `drivetwin run
--ci-terminal`: SDO simulation lines over a plain TCP socket, checked against python-canopen's
view of the same dictionary, and driven the way a program written for the device drives it
(pyserial, `?606100` CR out, the answer read up to CR)."""

import socket

import serial

from conftest import HOST, free_port, run_cli, wait_until


def _console(twin, port):
    wait_until(lambda: any(l.startswith("CI terminal of drive 1 on") for l in twin.stdout_lines),
               5.0, what="the CI terminal line")
    s = socket.create_connection((HOST, port), timeout=3)
    f = s.makefile("rwb", buffering=0)
    return s, f


def _ask(f, line: str) -> str:
    """A request ended with CR LF gets one answer, ended with CR alone."""
    f.write(line.encode() + b"\r\n")
    answer = b""
    while not answer.endswith(b"\r"):
        byte = f.read(1)
        assert byte, f"connection closed after {answer!r}"
        answer += byte
    assert b"\n" not in answer, answer
    return answer[:-1].decode()


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


def _device_program(port):
    """The serial side of a stage controller written for the CMMP-AS: pyserial on the
    console, a request ended with CR, the answer read up to CR."""
    link = serial.serial_for_url(f"socket://{HOST}:{port}", timeout=3)

    def ask(line: str) -> str:
        link.write(line.encode() + b"\r")
        answer = link.read_until(b"\r")
        assert answer.endswith(b"\r"), f"{line}: no answer up to CR, got {answer!r}"
        assert b"\n" not in answer, f"{line}: LF in {answer!r}"
        return answer[:-1].decode()

    def read(index: int, sub: int) -> int:
        answer = ask(f"?{index:04X}{sub:02X}")
        assert answer.startswith(f"={index:04X}{sub:02X}:"), answer
        return int(answer[8:], 16)

    def write(index: int, sub: int, value: int, digits: int):
        line = f"={index:04X}{sub:02X}:{value:0{digits}X}"
        assert ask(line) == line

    return link, ask, read, write


def test_a_device_program_enables_and_moves_reading_up_to_cr(launch):
    """A whole CiA 402 enable (6040h 06h, 07h, 0Fh) and a profile-position move over the CI
    terminal alone; every answer is `=` or `!` up to CR, no LF before or after."""
    port = free_port()
    twin = launch("cmmp-as", 1, extra=("--ci-terminal", f"{HOST}:{port}"))
    wait_until(lambda: any(l.startswith("CI terminal of drive 1 on") for l in twin.stdout_lines),
               5.0, what="the CI terminal line")
    link, ask, read, write = _device_program(port)
    try:
        assert ask("?606100").startswith("=606100:")
        write(0x6060, 0, 0x01, 2)
        wait_until(lambda: read(0x6061, 0) == 0x01, 2.0, what="profile position mode")
        for cw, mask, state in ((0x06, 0x6F, 0x21), (0x07, 0x6F, 0x23), (0x0F, 0x6F, 0x27)):
            write(0x6040, 0, cw, 4)
            wait_until(lambda: read(0x6041, 0) & mask == state, 2.0,
                       what=f"statusword {state:02X}h after controlword {cw:02X}h")
        target = 4 * 65536
        write(0x607A, 0, target, 8)
        write(0x6081, 0, 1200, 8)
        write(0x6083, 0, 12000, 8)
        write(0x6084, 0, 12000, 8)
        write(0x6040, 0, 0x1F, 4)
        wait_until(lambda: read(0x6041, 0) & 0x1000, 2.0, what="set-point acknowledge")
        write(0x6040, 0, 0x0F, 4)
        wait_until(lambda: read(0x6041, 0) & 0x0400, 5.0, what="target reached")
        window = read(0x6067, 0)
        position = read(0x6064, 0)
        assert abs(position - target) <= window, position
        assert ask("=604100:0000") == "!06010002"
        # Nothing is left over: no LF, no second answer.
        link.timeout = 0.2
        assert link.read(1) == b""
    finally:
        link.close()
