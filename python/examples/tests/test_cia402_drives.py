"""CiA 402 drives of two vendors enabled and moved by python-canopen's BaseNode402 (the
`drivetwin_node` fixture), each on a cell of its own, named by indirect parametrization."""

import pytest


def give_the_bus_control(node, device):
    """What a master does first on each drive, as its manual says."""
    if device == "kinco-fd3":
        # At power-on the Kinco's digital inputs own the controlword (DIN1 Enable, 2010h:03)
        # and the mode (2010h:05), and its mode is Din_Mode0 (-4), which CiA 402 does not name.
        node.sdo[0x2010][3].raw = 0
        node.sdo[0x2010][5].raw = 0
        node.sdo[0x6060].raw = 1  # profile position


@pytest.mark.parametrize("drivetwin_cell", ["cmmp-as", "kinco-fd3"], indirect=True)
def test_enable_reaches_operation_enabled(drivetwin_cell, drivetwin_node):
    give_the_bus_control(drivetwin_node, drivetwin_cell.drive_specs[0]["device"])
    drivetwin_node.state = "OPERATION ENABLED"
    assert drivetwin_node.statusword & 0x6F == 0x27
    assert drivetwin_cell.api.drive(0).state == "OPERATION ENABLED"
    drivetwin_node.state = "SWITCH ON DISABLED"


def test_cmmp_as_profile_position_move(drivetwin_cell, drivetwin_node):
    drive = drivetwin_node
    drive.op_mode = "PROFILED POSITION"
    drive.state = "OPERATION ENABLED"
    target = 2 * 65536  # two revolutions, 65536 increments each
    drive.sdo[0x607A].raw = target
    drive.sdo[0x6081].raw = 1200  # rpm
    drive.controlword = 0x1F  # new set-point
    drivetwin_cell.wait_until(lambda: drive.statusword & 0x1000, 1.0, what="set-point acknowledge")
    drive.controlword = 0x0F
    drivetwin_cell.wait_until(lambda: drive.statusword & 0x0400, 5.0, what="target reached")
    # The REST API sees the plant the master moved.
    assert abs(drivetwin_cell.api.plant(0).position - target) < 200
    assert abs(drive.sdo[0x6064].raw - target) < 200


def test_a_raised_diagnostic_reaches_the_master_as_a_fault(drivetwin_cell, drivetwin_node):
    drivetwin_node.state = "OPERATION ENABLED"
    drivetwin_cell.api.raise_diagnostic(0, "08-2")  # CMMP-AS: a Hall sensor fault
    drivetwin_cell.wait_until(lambda: drivetwin_node.sdo[0x6041].raw & 0x08, 2.0,
                              what="the FAULT bit of the statusword")
    assert drivetwin_cell.api.motion(0).active_error is not None
