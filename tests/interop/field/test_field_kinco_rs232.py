"""A Kinco FD3 driven over its RS232 port the way an AGV's driver does it: pyserial on the port
(`--rs232 PATH`, a pty of the twin), 38400 8N1, 80 ms read timeout; each request one 10-byte
telegram (station, command, index, sub, 4 data bytes, negated-sum checksum; the Kinco manual's
extract kept beside the project, spec/kinco-fd-cd.md §2.1-2.2), then a read of the 10-byte
answer, the next telegram as soon as the answer is in. The driver frees the controlword and the
mode from the factory inputs, enables the drive (06h, 07h, 0Fh, 20 times), and moves it (2Fh →
3Fh), reading the statusword and Pos_Actual (field_program.py). Judged by what it set out to do:
enabled every time, moved, reached."""

from __future__ import annotations

from pathlib import Path

import pytest

from conftest import wait_until
from field_program import PERSONALITIES, enable_every_run, pp_move, setup

serial = pytest.importorskip("serial")

WRITE = {1: 0x2F, 2: 0x2B, 4: 0x23}
READ_ANSWER = {0x4F: 1, 0x4B: 2, 0x43: 4}


class AgvKincoDriver:
    """The serial part of an AGV driver for the Kinco: write a telegram, read 10 bytes."""

    def __init__(self, path: Path, station: int = 1):
        self.station = station
        self.s = serial.Serial(str(path), 38400, bytesize=8, parity="N", stopbits=1, timeout=0.08,
                               exclusive=True)

    def _exchange(self, command: int, index: int, sub: int, value: int = 0) -> bytes:
        body = bytes([self.station, command, index & 0xFF, index >> 8, sub]) + (
            value & 0xFFFFFFFF).to_bytes(4, "little")
        self.s.write(body + bytes([-sum(body) & 0xFF]))
        answer = self.s.read(10)
        assert len(answer) == 10 and sum(answer) & 0xFF == 0, (
            f"telegram {body.hex(' ')}: answer {answer.hex(' ')}")
        assert answer[1] != 0x80, (f"{index:04X}h:{sub:02X}: error answer "
                                   f"{int.from_bytes(answer[5:9], 'little'):08X}h")
        return answer

    def write(self, index: int, sub: int, value: int, size: int):
        answer = self._exchange(WRITE[size], index, sub, value)
        assert answer[1] == 0x60, answer.hex(" ")

    def read(self, index: int, sub: int = 0) -> int:
        answer = self._exchange(0x40, index, sub)
        size = READ_ANSWER[answer[1]]
        value = int.from_bytes(answer[5:5 + size], "little")
        return value - (1 << 32) if size == 4 and value >> 31 else value

    def close(self):
        self.s.close()


def serial_line(twin, kind: str, path: Path):
    """Waits for the twin's `RS232 line on PATH` (or RS485) line."""
    wait_until(lambda: any(l.startswith(f"{kind} line on {path}") for l in twin.stdout_lines), 5.0,
               what=f"the {kind} line")


def test_agv_driver_enables_and_moves_over_rs232(launch, tmp_path):
    path = tmp_path / "ttyKINCO"
    p = PERSONALITIES["kinco-fd3"]
    twin = launch(p.device, p.node, extra=("--rs232", str(path)))
    serial_line(twin, "RS232", path)
    driver = AgvKincoDriver(path, p.node)
    try:
        setup(driver, p)
        enable_every_run(driver, p.enable[0])
        pp_move(driver, p)
    finally:
        driver.close()
