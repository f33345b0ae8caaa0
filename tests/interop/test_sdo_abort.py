"""4. Every SDO abort cause, with the exact abort code: through python-canopen where it can provoke
the cause, and with raw frames from python-can where only a misbehaving client can."""

import time

import canopen
import pytest

from conftest import abort_frame, recv_id, sdo_request


def _abort_code(call) -> int:
    with pytest.raises(canopen.SdoAbortedError) as info:
        call()
    return info.value.code


def test_abort_object_does_not_exist(bench, node_of):
    node = node_of(bench)
    assert _abort_code(lambda: node.sdo.upload(0x3000, 0)) == 0x06020000
    assert _abort_code(lambda: node.sdo.download(0x3000, 0, b"\x01")) == 0x06020000


def test_abort_sub_index_does_not_exist(bench, node_of):
    node = node_of(bench)
    assert _abort_code(lambda: node.sdo.upload(0x1018, 0x10)) == 0x06090011
    assert _abort_code(lambda: node.sdo.download(0x1018, 0x10, b"\x01\x00\x00\x00")) == 0x06090011
    # a sub-index of a plain variable
    assert _abort_code(lambda: node.sdo.upload(0x2005, 1)) == 0x06090011


def test_abort_write_read_only_testbench(bench, node_of):
    node = node_of(bench)
    assert _abort_code(lambda: node.sdo.download(0x2005, 0, b"\x07")) == 0x06010002
    assert node.sdo[0x2005].raw == 42, "a refused write must not change the value"


def test_abort_write_read_only_cmmp_as_statusword(cmmp, node_of):
    node = node_of(cmmp)
    before = node.sdo[0x6041].raw
    assert _abort_code(lambda: node.sdo.download(0x6041, 0, b"\x37\x06")) == 0x06010002
    assert node.sdo[0x6041].raw == before


def test_abort_read_write_only(bench, node_of):
    node = node_of(bench)
    node.sdo.download(0x2002, 0, b"\x01\x02\x03\x04")  # writing is allowed
    assert _abort_code(lambda: node.sdo.upload(0x2002, 0)) == 0x06010001


def test_abort_length_too_high(bench, node_of):
    node = node_of(bench)
    assert _abort_code(lambda: node.sdo.download(0x2003, 0, b"\x01\x00\x00\x00")) == 0x06070012
    assert node.sdo[0x2003].raw == 0


def test_abort_length_too_low(bench, node_of):
    node = node_of(bench)
    assert _abort_code(lambda: node.sdo.download(0x2003, 0, b"\x01")) == 0x06070013
    assert node.sdo[0x2003].raw == 0


def test_abort_value_too_high_and_too_low(bench, node_of):
    node = node_of(bench)
    node.sdo[0x2003].raw = 100
    node.sdo[0x2003].raw = -100
    assert _abort_code(lambda: setattr(node.sdo[0x2003], "raw", 101)) == 0x06090031
    assert _abort_code(lambda: setattr(node.sdo[0x2003], "raw", -101)) == 0x06090032
    assert node.sdo[0x2003].raw == -100, "a refused write must not change the value"


@pytest.mark.parametrize("index", [0x1010, 0x1011], ids=["1010h", "1011h"])
def test_abort_wrong_store_restore_signature(bench, node_of, index):
    node = node_of(bench)
    assert node.sdo[index][1].raw == 1, "reads 1: saves/restores on command"
    assert _abort_code(lambda: node.sdo.download(index, 1, b"\x00\x00\x00\x00")) == 0x08000020
    assert _abort_code(lambda: node.sdo.download(index, 1, b"SAVE")) == 0x08000020


def test_abort_unknown_command_specifier(bench, raw_bus):
    bus = raw_bus(bench)
    assert sdo_request(bus, 1, bytes.fromhex("E0 00 10 00 00 00 00 00")) == bytes.fromhex(
        "80 00 10 00 01 00 04 05")
    # the server is idle again afterwards
    assert sdo_request(bus, 1, bytes.fromhex("40 05 20 00 00 00 00 00")) == bytes.fromhex(
        "4F 05 20 00 2A 00 00 00")


def test_abort_toggle_bit_not_alternated(bench, raw_bus):
    bus = raw_bus(bench)
    # upload initiate of 1008h ("drivetwin test bench", 20 bytes): segmented, size indicated
    resp = sdo_request(bus, 1, bytes.fromhex("40 08 10 00 00 00 00 00"))
    assert resp == bytes.fromhex("41 08 10 00 14 00 00 00")
    # the first segment request must have toggle 0; 0x70 has toggle 1
    assert sdo_request(bus, 1, bytes.fromhex("70 00 00 00 00 00 00 00")) == abort_frame(
        0x1008, 0, 0x05030000)


def test_toggle_bit_correct_segmented_upload_by_hand(bench, raw_bus):
    """The positive twin of the toggle test: the same upload with correct toggles works."""
    bus = raw_bus(bench)
    assert sdo_request(bus, 1, bytes.fromhex("40 08 10 00 00 00 00 00"))[0] == 0x41
    text = b""
    toggle = 0
    while True:
        resp = sdo_request(bus, 1, bytes([0x60 | toggle]) + bytes(7))
        assert resp[0] & 0xE0 == 0x00 and resp[0] & 0x10 == toggle, resp.hex(" ")
        unused = (resp[0] >> 1) & 7
        text += resp[1:8 - unused]
        if resp[0] & 1:
            break
        toggle ^= 0x10
    assert text == b"drivetwin test bench"


@pytest.mark.parametrize("blksize", [0x80, 0x00])
def test_abort_invalid_block_size(bench, raw_bus, blksize):
    bus = raw_bus(bench)
    # block upload initiate of 2001h, CRC supported, blksize out of 1..127
    req = bytes([0xA4, 0x01, 0x20, 0x00, blksize, 0x00, 0x00, 0x00])
    assert sdo_request(bus, 1, req) == abort_frame(0x2001, 0, 0x05040002)


def crc16_ccitt(data: bytes) -> int:
    """CRC of SDO block transfers: CRC-16/XMODEM, polynomial 0x1021, initial value 0."""
    crc = 0
    for byte in data:
        crc ^= byte << 8
        for _ in range(8):
            crc = ((crc << 1) ^ 0x1021) if crc & 0x8000 else (crc << 1)
            crc &= 0xFFFF
    return crc


def _block_download_by_hand(bus, data: bytes, crc: int) -> bytes:
    """Block download of `data` to 2000h; returns the server's answer to the end frame."""
    size = len(data).to_bytes(4, "little")
    resp = sdo_request(bus, 1, bytes([0xC6, 0x00, 0x20, 0x00]) + size)
    assert resp[0] & 0xFB == 0xA0 and resp[1:4] == bytes([0x00, 0x20, 0x00]), resp.hex(" ")
    assert resp[0] & 0x04, "server announces CRC support"
    blksize = resp[4]
    assert 1 <= blksize <= 127
    segments = [data[i:i + 7] for i in range(0, len(data), 7)]
    assert len(segments) <= blksize
    import can
    for seq, seg in enumerate(segments, start=1):
        last = 0x80 if seq == len(segments) else 0
        bus.send(can.Message(arbitration_id=0x601, is_extended_id=False,
                             data=bytes([last | seq]) + seg.ljust(7, b"\x00")))
    ack = recv_id(bus, 0x581, 1.0)
    assert ack is not None, "no block acknowledgement"
    assert bytes(ack.data[:2]) == bytes([0xA2, len(segments)]), bytes(ack.data).hex(" ")
    unused = 7 - len(segments[-1])
    end = bytes([0xC1 | (unused << 2)]) + crc.to_bytes(2, "little") + bytes(5)
    return sdo_request(bus, 1, end)


def test_block_download_by_hand_with_right_crc(bench, raw_bus, node_of):
    bus = raw_bus(bench)
    data = bytes(range(1, 31))
    assert _block_download_by_hand(bus, data, crc16_ccitt(data)) == bytes.fromhex(
        "A1 00 00 00 00 00 00 00")
    node = node_of(bench)
    assert node.sdo.upload(0x2000, 0) == data


def test_abort_block_download_crc_error(bench, raw_bus, node_of):
    bus = raw_bus(bench)
    # expedited download of 4 bytes "befo" to 2000h first
    assert sdo_request(bus, 1, b"\x23\x00\x20\x00befo") == bytes.fromhex("60 00 20 00 00 00 00 00")
    data = bytes(range(1, 31))
    wrong = crc16_ccitt(data) ^ 0x5A5A
    assert _block_download_by_hand(bus, data, wrong) == abort_frame(0x2000, 0, 0x05040004)
    # python-canopen joins only now: a client on the bus during the raw exchange would have
    # the raw responses in its SDO queue
    node = node_of(bench)
    assert node.sdo.upload(0x2000, 0) == b"befo", "a transfer with a CRC error is not stored"


def test_abort_sdo_protocol_timeout(bench, raw_bus, node_of):
    bus = raw_bus(bench)
    resp = sdo_request(bus, 1, bytes.fromhex("40 08 10 00 00 00 00 00"))
    assert resp[0] == 0x41, resp.hex(" ")
    t0 = time.monotonic()
    # stay silent: the server aborts the transfer with 0504 0000h after its SDO timeout (1 s)
    msg = recv_id(bus, 0x581, 3.0)
    elapsed = time.monotonic() - t0
    assert msg is not None, "no timeout abort within 3 s"
    assert bytes(msg.data) == abort_frame(0x1008, 0, 0x05040000)
    assert 0.8 <= elapsed <= 2.5, f"abort after {elapsed:.2f} s"
    # and then the server takes new requests
    node = node_of(bench)
    assert node.sdo[0x1008].raw == "drivetwin test bench"
