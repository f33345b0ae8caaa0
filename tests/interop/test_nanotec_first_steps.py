"""The Nanotec manual's "first steps" (§2.2-2.7; its extract, kept beside the project as
spec/nanotec-canopen.md, §8.3-8.7), sent frame by frame with python-can to `drivetwin run
--device nanotec-smci47s --node 34` and answered byte for byte as printed. The requests are the
manual's IXXAT MiniMon frames, short ones included (DLC 4, 5, 6); every answer has DLC 8.
Vectors NT-NMT-01, NT-CW-01, NT-CW-02, NT-CW-03 and NT-CW-04, NT-PP-01, NT-PP-02 and NT-PP-03.
Frames go out PAUSE apart, as an operator types them: the drive takes a controlword in its next
cycle, so a statusword query in the same millisecond would still see the old state.
"""

import time

import can

from conftest import recv_id

NODE = 0x22  # 34
SDO_RX = 0x600 + NODE  # 622
SDO_TX = 0x580 + NODE  # 5A2
PAUSE = 0.05  # s between frames

# (request as printed, answer as printed), in the manual's order.
POWER_UP = [  # §2.4 (L490-549)
    ("2B 40 60 00 00 00", "60 40 60 00 00 00 00 00"),  # Switch On Disabled (CW := 0000h)
    ("40 41 60 00", "4B 41 60 00 60 02 00 00"),  # statusword 0260h
    ("2B 40 60 00 06 00", "60 40 60 00 00 00 00 00"),  # Ready to Switch On
    ("40 41 60 00", "4B 41 60 00 21 02 00 00"),  # 0221h
    ("2B 40 60 00 07 00", "60 40 60 00 00 00 00 00"),  # Switch On
    ("40 41 60 00", "4B 41 60 00 33 02 00 00"),  # 0233h
    ("2B 40 60 00 0F 00", "60 40 60 00 00 00 00 00"),  # Operation Enabled
    ("40 41 60 00", "4B 41 60 00 37 02 00 00"),  # 0237h
]
SELECT_PP = [("2F 60 60 00 01", "60 60 60 00 00 00 00 00")]  # §2.5 (L551-565)
START_MOVE = [  # §2.6 (L567-585)
    ("2b 40 60 00 1F 00", "60 40 60 00 00 00 00 00"),
    ("2b 40 60 00 0F 00", "60 40 60 00 00 00 00 00"),
]
NEW_TARGET = [  # §2.7 (L587-605)
    ("23 7A 60 00 45 23 01 00", "60 7A 60 00 00 00 00 00"),
    ("2b 40 60 00 1F 00", "60 40 60 00 00 00 00 00"),
    ("2b 40 60 00 0F 00", "60 40 60 00 00 00 00 00"),
]


def exchange(bus, request: str, answer: str):
    time.sleep(PAUSE)
    data = bytes.fromhex(request)
    bus.send(can.Message(arbitration_id=SDO_RX, data=data, is_extended_id=False))
    msg = recv_id(bus, SDO_TX, 2.0)
    assert msg is not None, f"no answer on 5A2 to 622: {request}"
    assert msg.dlc == 8, f"answer to {request} has DLC {msg.dlc}"
    assert bytes(msg.data) == bytes.fromhex(answer), (
        f"622: {request} -> 5A2: {bytes(msg.data).hex(' ').upper()}, manual prints {answer}")


def read_s32(bus, index: int) -> int:
    bus.send(can.Message(arbitration_id=SDO_RX, data=bytes([0x40, index & 0xFF, index >> 8, 0]),
                         is_extended_id=False))
    msg = recv_id(bus, SDO_TX, 2.0)
    assert msg is not None and msg.data[0] == 0x43, msg
    return int.from_bytes(msg.data[4:8], "little", signed=True)


def test_first_steps_frame_by_frame(launch, raw_bus):
    twin = launch("nanotec-smci47s", NODE)
    bus = raw_bus(twin)
    # §2.2 (L441-465), NT-NMT-01: MiniMon `0 1 22` = 000: 01 22; the node answers 722: 05
    # (§12.2 prints the state answer to every NMT command). A heartbeat 7F of the default
    # cell may come first.
    bus.send(can.Message(arbitration_id=0x000, data=bytes([0x01, NODE]), is_extended_id=False))
    deadline = time.monotonic() + 2.0
    states = []
    while time.monotonic() < deadline and 0x05 not in states:
        msg = recv_id(bus, 0x700 + NODE, deadline - time.monotonic())
        if msg is not None:
            assert msg.dlc == 1
            states.append(msg.data[0])
    assert 0x05 in states, f"722 carried {states}"
    for request, answer in POWER_UP + SELECT_PP + START_MOVE:
        exchange(bus, request, answer)
    # A second 1F/0F toggle does nothing: the absolute target 0 is reached (§2.6 L585).
    for request, answer in START_MOVE:
        exchange(bus, request, answer)
    assert read_s32(bus, 0x6064) == 0
    for request, answer in NEW_TARGET:
        exchange(bus, request, answer)
    # 74565 user units = 37.28 output revolutions at the default feed 2000/1: on its way.
    assert read_s32(bus, 0x607A) == 0x12345
    first = read_s32(bus, 0x6064)
    time.sleep(0.5)
    second = read_s32(bus, 0x6064)
    assert 0 <= first < second <= 0x12345, (first, second)


def test_rpdo1_remapping_with_python_canopen(launch, node_of):
    """§12.2 (L4131-4247), NT-PDO-01, NT-PDO-02, NT-PDO-03, NT-PDO-04, NT-PDO-05, NT-PDO-06, NT-PDO-07, NT-PDO-08, NT-PDO-09, NT-PDO-10, NT-PDO-11 and NT-PDO-12 through python-canopen's PdoMap and the drive's EDS:
    RPDO1 re-mapped in Pre-Operational to the controlword with the length left to the
    firmware's rules, then the power-up of §2.4 over RPDO1, each step seen in the default
    TPDO1 (the statusword, sent on change)."""
    twin = launch("nanotec-smci47s", NODE)
    node = node_of(twin)
    node.nmt.state = "PRE-OPERATIONAL"
    node.rpdo.read()
    rpdo = node.rpdo[1]
    rpdo.clear()
    controlword = rpdo.add_variable(0x6040)
    rpdo.cob_id = 0x200 + NODE
    rpdo.trans_type = 255
    rpdo.enabled = True
    node.rpdo.save()
    assert node.sdo[0x1600][1].raw == 0x60400010
    node.tpdo.read()
    node.nmt.state = "OPERATIONAL"
    tpdo = node.tpdo[1]
    for cw, sw in [(0x0006, 0x0221), (0x0007, 0x0233), (0x000F, 0x0237)]:
        controlword.raw = cw
        rpdo.transmit()
        deadline = time.monotonic() + 2.0
        while time.monotonic() < deadline:
            tpdo.wait_for_reception(deadline - time.monotonic())
            if tpdo[0].raw == sw:
                break
        assert tpdo[0].raw == sw, f"CW {cw:04X}h: TPDO1 statusword {tpdo[0].raw:04X}h"
    assert node.sdo[0x6041].raw == 0x0237


def test_rotary_switches_give_node_34_beside_a_cmmp_as(launch, connect, eds_files, tmp_path):
    """A cell with a CMMP-AS (node 1) and an SMCI47-S whose rotary switches read left = 2,
    right = 2: 16 * 2 + 2 = 34 (§1.1.1, NT-NODE-01's rule), over the file's `node`; 2009h
    reads the switch value (§11.10). Switches 1…127 fix 1 Mbit/s: the CMMP-AS's DIP6/DIP7 set
    to it."""
    from conftest import add_node, cmmp_switches

    cfg = tmp_path / "cell.toml"
    cfg.write_text('[bus]\nsocketcand = "127.0.0.1:1"\nchannel = "vcan0"\n\n'
                   '[[drive]]\ndevice = "cmmp-as"\nnode = 1\n' + "\n".join(cmmp_switches(1)) + "\n\n"
                   '[[drive]]\ndevice = "nanotec-smci47s"\nnode = 9\n'
                   '[drive.rotary_switches]\nleft = 2\nright = 2\n')
    twin = launch(config=cfg)
    assert any("nanotec-smci47s node 34" in line for line in twin.stdout_lines), twin.stdout_lines
    net = connect(twin)
    nanotec = add_node(net, NODE, eds_files["nanotec-smci47s"])
    cmmp = add_node(net, 1, eds_files["cmmp-as"])
    assert nanotec.sdo[0x2009].raw == NODE
    assert nanotec.sdo[0x1018][1].raw == 0x26C and cmmp.sdo[0x1018][1].raw == 0x1D
    assert nanotec.sdo[0x6041].raw == 0x0260


def test_nt_node_07_no_bit_rate_code_answers_but_takes_no_motion_command(launch, connect, eds_files,
                                                                         tmp_path):
    """NT-NODE-07 end to end (§1.1.3 step 7, L333): an SMCI47-S whose rotary switches read
    node + 128 (16 * 8 + 5 = 133: node 5) with no bit-rate code in 2005h "answers on CAN but
    accepts no motion commands". python-canopen reads it over SDO and writes the controlword
    steps, each acknowledged; the drive stays in Switch On Disabled, and the console's Enable
    answers 409 with that reason and the manual's rule."""
    import json
    import urllib.error
    import urllib.request

    from conftest import add_node, wait_until

    cfg = tmp_path / "cell.toml"
    cfg.write_text('[bus]\nsocketcand = "127.0.0.1:1"\nchannel = "vcan0"\n\n'
                   '[[drive]]\ndevice = "nanotec-smci47s"\nnode = 9\n'
                   '[drive.rotary_switches]\nleft = 5\nright = 8\n'
                   '[drive.objects]\n"2005:00" = 0\n')
    twin = launch(config=cfg, extra=("--http", "127.0.0.1:0"))
    net = connect(twin)
    node = add_node(net, 5, eds_files["nanotec-smci47s"])
    assert node.sdo[0x1018][1].raw == 0x26C, "NT-NODE-07: it answers on CAN as node 5"
    for cw in (0x06, 0x07, 0x0F):
        node.sdo[0x6040].raw = cw
    assert node.sdo[0x6041].raw & 0x4F == 0x40, "NT-NODE-07: no motion command: Switch On Disabled"

    line = wait_until(lambda: next((l for l in twin.stdout_lines if l.startswith("web console on ")),
                                   None), 5.0, what="the 'web console on' line")
    url = line.split("web console on ", 1)[1].strip()
    req = urllib.request.Request(url + "api/drives/0/motion/enable", method="POST")
    try:
        with urllib.request.urlopen(req, timeout=10) as r:
            status, body = r.status, json.load(r)
    except urllib.error.HTTPError as e:
        status, body = e.code, json.load(e)
    assert status == 409, body
    assert body["reason"]["kind"] == "hardware_enable_missing", body
    assert "accepts no motion commands" in body["reason"]["text"], body
    assert "§1.1.3 step 7" in body["reason"]["rule"], body
    assert node.sdo[0x6041].raw & 0x4F == 0x40, "NT-NODE-07: still Switch On Disabled"
