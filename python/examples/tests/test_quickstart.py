"""The README's first example: a CMMP-AS on a cell of its own, read with python-canopen."""


def test_a_festo_drive_answers(drivetwin_node):  # one CMMP-AS, node 1, its own cell
    assert drivetwin_node.sdo[0x1018][1].raw == 0x1D  # vendor-ID: Festo
