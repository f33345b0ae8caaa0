"""The Kinco FD3 (`drivetwin run --device kinco-fd3 --node 1`) driven by python-canopen's
BaseNode402 over socketcand, as a bus master sets up the real drive: the factory inputs own the
controlword (SDO abort 0800 0021h; the manual's text, kept beside the project as
seeds/001_da459f46c7138f7b.txt, L1287) until Din1_Function / Din3_Function are 0; then the CiA
402 state machine, mode 3 at 300 rpm in the drive's DEC units (spec/kinco-fd-cd.md §6 item 12),
and the absolute move of §8.15 (KINCO-CW-01: 2Fh → 607Ah → 3Fh)."""

from __future__ import annotations

import canopen
import pytest
from canopen.profiles.p402 import BaseNode402

from conftest import SDO_TIMEOUT, wait_until

DEC_PER_RPM = 512 * 10_000 / 1875  # velocity DEC of 1 rpm
DEC_PER_RPS2 = 65536 * 10_000 / 4_000_000  # acceleration DEC of 1 rps/s


@pytest.fixture
def node(launch, connect, eds_files):
    twin = launch("kinco-fd3", 1)
    net = connect(twin)
    n = BaseNode402(1, str(eds_files["kinco-fd3"]))
    net.add_node(n)
    n.sdo.RESPONSE_TIMEOUT = SDO_TIMEOUT
    return n


@pytest.fixture
def drive(node):
    # Give the controlword and the mode to the bus (EA02 = 8 "protocol" does the same).
    node.sdo[0x2010][3].raw = 0
    node.sdo[0x2010][5].raw = 0
    # The power-on mode is Din_Mode0 (−4, pulse), which CiA 402 (and BaseNode402) does not
    # name: a master selects its mode first.
    node.sdo[0x6060].raw = 1
    node.setup_402_state_machine(read_pdos=False)
    return node


def test_factory_inputs_own_the_controlword(node):
    with pytest.raises(canopen.SdoAbortedError) as e:
        node.sdo[0x6040].raw = 0x0F
    assert e.value.code == 0x08000021
    assert node.sdo[0x6061].raw == -4  # Din_Mode0


def test_profile_velocity_at_300_rpm(drive):
    drive.op_mode = "PROFILED VELOCITY"
    drive.sdo[0x6083].raw = int(100 * DEC_PER_RPS2)
    drive.sdo[0x6084].raw = int(100 * DEC_PER_RPS2)
    drive.state = "OPERATION ENABLED"
    assert drive.statusword & 0x6F == 0x27
    drive.sdo[0x60FF].raw = int(300 * DEC_PER_RPM)
    wait_until(lambda: abs(drive.sdo[0x2FF0][0x14].raw - 300) <= 3, 3.0, what="300 rpm")
    assert abs(drive.sdo[0x606C].raw - 300 * DEC_PER_RPM) < 5 * DEC_PER_RPM
    drive.state = "SWITCH ON DISABLED"


def test_kinco_cw_01_absolute_move(drive):
    drive.op_mode = "PROFILED POSITION"
    drive.sdo[0x6081].raw = int(600 * DEC_PER_RPM)
    drive.sdo[0x6083].raw = int(100 * DEC_PER_RPS2)
    drive.sdo[0x6084].raw = int(100 * DEC_PER_RPS2)
    drive.controlword = 0x06
    drive.controlword = 0x2F
    wait_until(lambda: drive.statusword & 0x6F == 0x27, 1.0, what="enabled by 2Fh")
    drive.sdo[0x607A].raw = 50_000
    drive.controlword = 0x3F
    wait_until(lambda: drive.statusword & 0x0400, 3.0, interval=0.01, what="target reached")
    assert abs(drive.sdo[0x6063].raw - 50_000) <= 20
