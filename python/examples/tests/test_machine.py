"""A CMMP-AS on CANopen and a CMMO-ST on Modbus TCP in one cell: python-canopen enables the
servo, pymodbus reads the stepper's FHPP input telegram (CMMO-ST FHPP manual §2.5)."""

import struct

import pytest
from pymodbus.client import ModbusTcpClient

pytestmark = pytest.mark.drivetwin(devices=["cmmp-as", "cmmo-st"])


def fhpp_status(client):
    """SCON, SPOS and the actual position of the FHPP input telegram (registers 0…3)."""
    rr = client.read_holding_registers(0, count=4)
    assert not rr.isError(), rr
    scon, spos, _, _, actual = struct.unpack(">BBBBi", struct.pack(">4H", *rr.registers))
    return scon, spos, actual


def test_servo_on_canopen_and_stepper_on_modbus(drivetwin_cell, drivetwin_node):
    drivetwin_node.state = "OPERATION ENABLED"
    assert drivetwin_node.statusword & 0x6F == 0x27

    modbus = drivetwin_cell.modbus[0]
    client = ModbusTcpClient(modbus.host, port=modbus.port, timeout=2, retries=0)
    assert client.connect()
    try:
        scon, spos, _ = fhpp_status(client)
        assert (scon, spos) == (0x10, 0x04)  # power-on: supply on, motion complete
        rr = client.read_device_information(read_code=0x01, object_id=0)
        assert rr.information[0] == b"Festo AG & Co. KG"
    finally:
        client.close()

    drives = [(d.device, d.interface) for d in drivetwin_cell.api.drives()]
    assert drives == [("cmmp-as", "canopen"), ("cmmo-st", "modbus-tcp")]
