"""Controlword writes back to back, as field programs send them: each SDO write of 6040h goes
out as soon as the answer to the one before has come, with no pause, on the default cell of
each CANopen personality (no `bitrate`: frames cross at once), from python-canopen and from raw
frames (python-can over socketcand, the Nanotec demo's short frames as printed). A drive that
answered a write has taken it, so the sequence reaches OPERATION ENABLED every time; then a
profile-position move started the same way (start word, then its reset, back to back) reaches
its target. Judged by what the program set out to do: enabled in 20 of 20 runs, moved,
reached."""

from __future__ import annotations

import can
import canopen
import pytest

from conftest import SDO_TIMEOUT, recv_id
from field_program import PERSONALITIES, enable_every_run, pp_move, setup


class CanopenSdo:
    """python-canopen's SDO client: `node.sdo[...].raw = value`, as every example does."""

    def __init__(self, node):
        self.node = node

    def _entry(self, index: int, sub: int):
        entry = self.node.sdo[index]
        return entry if isinstance(entry, canopen.sdo.SdoVariable) else entry[sub]

    def write(self, index: int, sub: int, value: int, size: int):
        self._entry(index, sub).raw = value

    def read(self, index: int, sub: int = 0) -> int:
        return self._entry(index, sub).raw


class RawSdo:
    """Expedited SDO frames written by hand on python-can, one request, then its answer."""

    def __init__(self, bus, node: int, short_frames: bool):
        self.bus = bus
        self.node = node
        # The Nanotec manual prints its requests without the unused bytes (DLC 5 / 6).
        self.short = short_frames

    def _exchange(self, data: bytes) -> bytes:
        self.bus.send(can.Message(arbitration_id=0x600 + self.node, data=data, is_extended_id=False))
        msg = recv_id(self.bus, 0x580 + self.node, SDO_TIMEOUT)
        assert msg is not None, f"no answer to {data.hex(' ')}"
        answer = bytes(msg.data)
        assert answer[0] != 0x80, (f"{data.hex(' ')} aborted: "
                                   f"{int.from_bytes(answer[4:8], 'little'):08X}h")
        return answer

    def write(self, index: int, sub: int, value: int, size: int):
        command = {1: 0x2F, 2: 0x2B, 4: 0x23}[size]
        data = bytes([command, index & 0xFF, index >> 8, sub]) + (value & 0xFFFFFFFF).to_bytes(4, "little")
        answer = self._exchange(data[:4 + size] if self.short else data)
        assert answer[:4] == bytes([0x60, index & 0xFF, index >> 8, sub]), answer.hex(" ")

    def read(self, index: int, sub: int = 0) -> int:
        answer = self._exchange(bytes([0x40, index & 0xFF, index >> 8, sub, 0, 0, 0, 0]))
        size = {0x4F: 1, 0x4B: 2, 0x43: 4}[answer[0]]
        value = int.from_bytes(answer[4:4 + size], "little")
        return value - (1 << 32) if size == 4 and value & 0x8000_0000 else value


CASES = [pytest.param(device, sequence, id=f"{device}-" + "-".join(f"{w:02X}" for w in sequence))
         for device, p in PERSONALITIES.items() for sequence in p.enable]


@pytest.mark.parametrize("client", ["python-canopen", "raw-frames"])
@pytest.mark.parametrize("device,sequence", CASES)
def test_back_to_back_enable_then_move(launch, node_of, raw_bus, device, sequence, client):
    p = PERSONALITIES[device]
    twin = launch(device, p.node)
    sdo = (CanopenSdo(node_of(twin)) if client == "python-canopen"
           else RawSdo(raw_bus(twin), p.node, short_frames=device.startswith("nanotec")))
    setup(sdo, p)
    enable_every_run(sdo, sequence)
    pp_move(sdo, p)
