"""2-3. SDO expedited, segmented and block transfers with python-canopen's SDO client."""

import random

import pytest


def test_expedited_read_identity_cmmp_as(cmmp, node_of):
    node = node_of(cmmp)
    assert node.sdo[0x1018][1].raw == 0x1D
    assert node.sdo[0x1018][2].raw == 0x0018C375
    assert node.sdo[0x1018][3].raw == 0x00040000
    assert node.sdo[0x1018][0].raw >= 4
    assert node.sdo[0x1000].raw == 0x00020192
    # the commissioned heartbeat of a single drive without --config
    assert node.sdo[0x1017].raw == 1000


def test_expedited_write_then_read_back(cmmp, node_of):
    node = node_of(cmmp)
    node.sdo[0x1017].raw = 1234
    assert node.sdo[0x1017].raw == 1234
    node.sdo[0x1017].raw = 0
    assert node.sdo[0x1017].raw == 0
    node.sdo[0x1017].raw = 65535
    assert node.sdo[0x1017].raw == 65535
    # the raw bytes on the wire are little endian
    assert node.sdo.upload(0x1017, 0) == b"\xff\xff"


def test_expedited_every_data_type_on_testbench(bench, node_of):
    node = node_of(bench)
    rec = node.sdo[0x2004]
    defaults = {2: -8, 3: -16, 4: -32, 5: -64, 6: 8, 7: 16, 8: 32, 9: 64}
    for sub, value in defaults.items():
        assert rec[sub].raw == value, f"2004:{sub:02X}"
    assert rec[10].raw == pytest.approx(1.5)
    assert rec[11].raw == pytest.approx(-2.25)
    new = {1: True, 2: -128, 3: -32768, 4: -(2**31), 5: -(2**63), 6: 255, 7: 65535,
           8: 2**32 - 1, 9: 2**64 - 1}
    for sub, value in new.items():
        rec[sub].raw = value
    for sub, value in new.items():
        assert rec[sub].raw == value, f"2004:{sub:02X}"
    rec[10].raw = -0.125
    rec[11].raw = 1e300
    assert rec[10].raw == -0.125
    assert rec[11].raw == 1e300
    assert node.sdo[0x2005].raw == 42
    assert node.sdo[0x1008].raw == "drivetwin test bench"


def _random_bytes(n, seed):
    return random.Random(seed).randbytes(n)


def _random_text(n, seed):
    rng = random.Random(seed)
    alphabet = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789 .,;:-_/"
    return "".join(rng.choice(alphabet) for _ in range(n))


def _write_block(node, index, data: bytes):
    with node.sdo[index].open("wb", size=len(data), block_transfer=True,
                              request_crc_support=True) as f:
        f.write(data)


def _read_block(node, index) -> bytes:
    with node.sdo[index].open("rb", block_transfer=True, request_crc_support=True) as f:
        return f.read()


def _write_segmented(node, index, data: bytes):
    node.sdo[index].raw = data


def _read_segmented(node, index) -> bytes:
    return node.sdo.upload(index, 0)


WRITERS = {"segmented": _write_segmented, "block": _write_block}
READERS = {"segmented": _read_segmented, "block": _read_block}


@pytest.mark.parametrize("reader", sorted(READERS))
@pytest.mark.parametrize("writer", sorted(WRITERS))
def test_large_domain_round_trip(bench, node_of, writer, reader):
    node = node_of(bench)
    data = _random_bytes(5000 + 77, seed=f"{writer}-{reader}")
    WRITERS[writer](node, 0x2000, data)
    assert READERS[reader](node, 0x2000) == data
    # a second, shorter write replaces the whole value
    data2 = _random_bytes(6001, seed=7)
    WRITERS[writer](node, 0x2000, data2)
    assert READERS[reader](node, 0x2000) == data2


@pytest.mark.parametrize("reader", sorted(READERS))
@pytest.mark.parametrize("writer", sorted(WRITERS))
def test_long_visible_string_round_trip(bench, node_of, writer, reader):
    node = node_of(bench)
    assert node.sdo[0x2001].raw == "drivetwin"
    text = _random_text(3000, seed=len(writer) * 31 + len(reader))
    WRITERS[writer](node, 0x2001, text.encode("ascii"))
    assert READERS[reader](node, 0x2001).decode("ascii") == text
    assert node.sdo[0x2001].raw == text
    # a shorter string afterwards is not padded with the tail of the longer one
    node.sdo[0x2001].raw = "short"
    assert node.sdo[0x2001].raw == "short"


def test_domain_full_size_8192_block_both_ways(bench, node_of):
    node = node_of(bench)
    data = _random_bytes(8192, seed=8192)
    _write_block(node, 0x2000, data)
    assert _read_block(node, 0x2000) == data
    assert _read_segmented(node, 0x2000) == data
