"""What a field program for a CiA 402 drive does, whatever carries its requests (SDO, the CI
terminal, the Kinco's RS232 telegrams): write what the drive's manual prints, each write after
the answer to the one before, with no pause; then poll the statusword until the drive shows
what the program wanted, or give up. A client is any object with `write(index, sub, value,
size)` (size in bytes; returns once the drive has answered) and `read(index, sub=0)` (32-bit
values signed).

The states are CiA 402's (the masks every drive manual prints); the personalities say what a
program for each drive writes, in the drive's units."""

from __future__ import annotations

from dataclasses import dataclass

import pytest

from conftest import wait_until

# (mask, value, state) in the order CiA 402 lists them.
STATES = (
    (0x4F, 0x00, "NOT READY TO SWITCH ON"),
    (0x4F, 0x40, "SWITCH ON DISABLED"),
    (0x6F, 0x21, "READY TO SWITCH ON"),
    (0x6F, 0x23, "SWITCHED ON"),
    (0x6F, 0x27, "OPERATION ENABLED"),
    (0x6F, 0x07, "QUICK STOP ACTIVE"),
    (0x4F, 0x0F, "FAULT REACTION ACTIVE"),
    (0x4F, 0x08, "FAULT"),
)
TARGET_REACHED = 0x0400

RUNS = 20
# How long a program polls the statusword after its last write before it gives up: a drive
# is enabled within a few of its cycles.
ENABLE_TIMEOUT = 0.5
MOVE_TIMEOUT = 5.0
POLL = 0.005  # s between statusword reads while waiting


def state_of(statusword: int) -> str:
    for mask, value, name in STATES:
        if statusword & mask == value:
            return name
    return f"statusword {statusword:#06x}"


def enabled(statusword: int) -> bool:
    return statusword & 0x6F == 0x27


# Kinco units (docs/kinco.md): velocity DEC of 1 rpm, acceleration DEC of 1 rps/s.
KINCO_DEC_PER_RPM = 512 * 10_000 / 1875
KINCO_DEC_PER_RPS2 = 65536 * 10_000 / 4_000_000


@dataclass(frozen=True)
class Personality:
    """What a program written for one drive sends it."""

    device: str
    node: int
    # Writes (index, sub, value, size) a program for this drive makes once, before the rest.
    setup: tuple[tuple[int, int, int, int], ...]
    # The enable sequences printed for the drive.
    enable: tuple[tuple[int, ...], ...]
    # Profile-position move: speed 6081h, acceleration 6083h = deceleration 6084h, target
    # 607Ah, the controlword pair that starts it, the position object the program reads.
    speed: int
    acceleration: int
    target: int
    start: tuple[int, int]
    position: int = 0x6064


PERSONALITIES = {
    # CMMP-AS: positions in increments (65536 per revolution), speeds in rpm; PP started by
    # 1Fh and bit 4 reset with 0Fh.
    "cmmp-as": Personality("cmmp-as", 1, setup=((0x6060, 0, 1, 1),),
                           enable=((0x06, 0x07, 0x0F),),
                           speed=1200, acceleration=12000, target=4 * 65536, start=(0x1F, 0x0F)),
    # Nanotec: the manual's first steps (§2.4-2.7, node 34 = 622h / 5A2h) and the demo's
    # 00h, 80h, 06h, 07h, 0Fh; 2000 units per revolution, speeds in units/s.
    "nanotec-smci47s": Personality("nanotec-smci47s", 34, setup=((0x6060, 0, 1, 1),),
                                   enable=((0x06, 0x07, 0x0F), (0x00, 0x80, 0x06, 0x07, 0x0F)),
                                   speed=4000, acceleration=16000, target=4000,
                                   start=(0x1F, 0x0F)),
    # Kinco FD3: a master frees the controlword and the mode from the factory inputs
    # (Din1_Function 2010h:03, Din3_Function 2010h:05 = 0, manual L1287), mode 1; the move is
    # Tab. 6-5's 2Fh → 3Fh; Pos_Actual 6063h.
    "kinco-fd3": Personality("kinco-fd3", 1,
                             setup=((0x2010, 3, 0, 2), (0x2010, 5, 0, 2), (0x6060, 0, 1, 1)),
                             enable=((0x06, 0x07, 0x0F),),
                             speed=int(600 * KINCO_DEC_PER_RPM),
                             acceleration=int(100 * KINCO_DEC_PER_RPS2), target=50_000,
                             start=(0x2F, 0x3F), position=0x6063),
}


def statusword_until(client, done, timeout: float) -> tuple[bool, int]:
    """Polls 6041h until `done(sw)` or `timeout` s: (done, last statusword)."""
    last = [0]

    def check():
        last[0] = client.read(0x6041)
        return done(last[0])

    try:
        wait_until(check, timeout, interval=POLL)
        return True, last[0]
    except pytest.fail.Exception:
        return False, last[0]


def setup(client, p: Personality):
    for index, sub, value, size in p.setup:
        client.write(index, sub, value, size)


def enable_every_run(client, sequence: tuple[int, ...]):
    """RUNS times: 00h and wait for SWITCH ON DISABLED, then `sequence` back to back and poll
    for OPERATION ENABLED; fails naming the runs that did not get there and the state they were
    left in. Stops after three runs that all failed (the rest would say the same)."""
    failed: dict[str, list[int]] = {}
    runs = 0
    for run in range(1, RUNS + 1):
        runs = run
        client.write(0x6040, 0, 0x00, 2)
        ok, sw = statusword_until(client, lambda sw: state_of(sw) == "SWITCH ON DISABLED", 1.0)
        assert ok, f"run {run}: 00h did not disable the drive: {state_of(sw)} ({sw:#06x})"
        for word in sequence:
            client.write(0x6040, 0, word, 2)
        ok, sw = statusword_until(client, enabled, ENABLE_TIMEOUT)
        if not ok:
            failed.setdefault(f"{state_of(sw)} (6041h = {sw:04X}h)", []).append(run)
            if run == 3 and sum(map(len, failed.values())) == 3:
                break
    left = "; ".join(f"runs {', '.join(map(str, numbers))} in {state}"
                     for state, numbers in failed.items())
    assert not failed, (f"6040h := {', '.join(f'{w:02X}h' for w in sequence)} back to back: "
                        f"OPERATION ENABLED in {runs - sum(map(len, failed.values()))} of {runs} "
                        f"runs; {left} {ENABLE_TIMEOUT} s after the last answer")


def pp_move(client, p: Personality):
    """The move a program for the drive makes once enabled: profile, target, the start word and
    the next one back to back, then the statusword polled until target reached at the target."""
    client.write(0x6081, 0, p.speed, 4)
    client.write(0x6083, 0, p.acceleration, 4)
    client.write(0x6084, 0, p.acceleration, 4)
    client.write(0x607A, 0, p.target, 4)
    window = client.read(0x6067)
    for word in p.start:
        client.write(0x6040, 0, word, 2)

    def reached(sw):
        return sw & TARGET_REACHED and abs(client.read(p.position) - p.target) <= window

    ok, sw = statusword_until(client, reached, MOVE_TIMEOUT)
    position = client.read(p.position)
    assert ok, (f"target {p.target} not reached within {MOVE_TIMEOUT} s: position {position}, "
                f"{state_of(sw)} (6041h = {sw:04X}h)")
