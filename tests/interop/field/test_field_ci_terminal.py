"""The CMMP-AS CI terminal as a stage controller written for the real drive uses it: pyserial on
the terminal's port (`socket://` for the twin's TCP console), each SDO simulation command (the
CMMP-AS manual's extract kept beside the project, spec/cmmp-as-1-communication.md §2.5) ended by
CR alone, each answer read up to CR and taken as the whole answer. The device ends an answer
with CR and nothing else, so an answer never starts with the rest of the one before. The program
enables the drive (06h, 07h, 0Fh, each after its answer, 20 times) and makes a profile-position
move (field_program.py), judged by what it set out to do: enabled, moved, reached, with every
answer `=IIIISS:…` or `!…` and no LF before or after."""

from __future__ import annotations

import pytest

from conftest import HOST, free_port, wait_until
from field_program import PERSONALITIES, enable_every_run, pp_move, setup

serial = pytest.importorskip("serial")


class StageController:
    """The serial side of a program for the CMMP-AS: one command, one answer up to CR."""

    def __init__(self, port: int):
        self.s = serial.serial_for_url(f"socket://{HOST}:{port}", timeout=2.0)

    def ask(self, command: str) -> str:
        self.s.write(command.encode("ascii") + b"\r")
        raw = self.s.read_until(b"\r")
        assert raw.endswith(b"\r"), f"{command}: no CR within 2 s, got {raw!r}"
        answer = raw[:-1].decode("ascii", "replace")
        # What the stage controller checks before it trusts an answer.
        assert answer[:1] in ("=", "!") and "\n" not in answer, (
            f"Failed SDO access {command!r}: rs:{answer!r}")
        return answer

    def write(self, index: int, sub: int, value: int, size: int):
        command = f"={index:04X}{sub:02X}:{value & ((1 << 8 * size) - 1):0{2 * size}X}"
        answer = self.ask(command)
        assert answer == command, f"{command} answered {answer}"

    def read(self, index: int, sub: int = 0) -> int:
        answer = self.ask(f"?{index:04X}{sub:02X}")
        head = f"={index:04X}{sub:02X}:"
        assert answer.startswith(head), f"?{index:04X}{sub:02X} answered {answer}"
        value = int(answer[len(head):], 16)
        return value - (1 << 32) if len(answer) == len(head) + 8 and value >> 31 else value

    def close(self):
        self.s.close()


def test_stage_controller_enables_and_moves_over_the_ci_terminal(launch):
    port = free_port()
    twin = launch("cmmp-as", 1, extra=("--ci-terminal", f"{HOST}:{port}"))
    wait_until(lambda: any(l.startswith("CI terminal of drive 1 on") for l in twin.stdout_lines),
               5.0, what="the CI terminal line")
    ctl = StageController(port)
    p = PERSONALITIES["cmmp-as"]
    try:
        setup(ctl, p)
        enable_every_run(ctl, p.enable[0])
        pp_move(ctl, p)
        # Nothing after the last answer: no LF left for the next command to read first.
        ctl.s.timeout = 0.1
        rest = ctl.s.read(16)
        assert rest == b"", f"after the last answer: {rest!r}"
    finally:
        ctl.close()
