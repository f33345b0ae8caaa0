"""Modbus from a shell, as commissioning engineers and small controllers do it: Debian's
`mbpoll` in a bash script (sh/) and a small C program on libmodbus (c/, compiled by the test
with cc), against the CMMO-ST's Modbus TCP (FHPP: enable, home, direct move, read the status)
and against the Kinco FD3's Modbus RTU on its RS485 pty (mbpoll and libmodbus open it as a
serial device: mode, profile, controlword 06h, 07h, 0Fh each after its answer, 2Fh → 3Fh, read
the statusword and Pos_Actual). Each program judges itself by what it set out to do (enabled,
moved, reached; exit 0) and the test reads the position back through another client.

The Kinco is commissioned first as its owner would with the vendor's tool on RS232: the
controlword and the mode freed of the factory inputs (Din1_Function 2010h:03 and Din3_Function
2010h:05 = 0, manual L1287); the RTU register map has no register for Din3_Function."""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import pytest

from conftest import HOST
from field_build import C_DIR, HERE, cc
from field_program import PERSONALITIES
from test_fhpp_modbus import cmmo, decode  # noqa: F401 (cmmo is a fixture)
from test_field_kinco_rs232 import AgvKincoDriver, serial_line

FHPP_TARGET = 27_000  # SINC (0.01°): 270°
KINCO_TARGET = 50_000  # increments
LIBMODBUS = ("-I/usr/include/modbus", "-lmodbus")


def run(args: list[str], timeout: float = 60.0) -> str:
    r = subprocess.run(args, capture_output=True, text=True, timeout=timeout)
    assert r.returncode == 0, f"{' '.join(args)}: exit {r.returncode}\n{r.stdout}\n{r.stderr}"
    return r.stdout


@pytest.fixture(scope="module")
def mbpoll() -> str:
    path = shutil.which("mbpoll")
    if path is None:
        pytest.skip("mbpoll is not installed (scripts/test installs it: apt-get install mbpoll)")
    return path


@pytest.fixture(scope="module")
def libmodbus_programs(tmp_path_factory) -> dict[str, str]:
    if not Path("/usr/include/modbus/modbus.h").is_file():
        pytest.skip("libmodbus-dev is not installed (scripts/test installs it)")
    build = tmp_path_factory.mktemp("libmodbus")
    return {name: str(cc(build / name, [C_DIR / f"{name}.c"], *LIBMODBUS))
            for name in ("fhpp_libmodbus", "kinco_rtu_libmodbus")}


def fhpp_actual(twin) -> dict:
    c = twin.client()
    try:
        rr = c.read_holding_registers(0, count=4)
        assert not rr.isError(), rr
        return decode(rr.registers)
    finally:
        c.close()


@pytest.fixture
def kinco_rtu(launch, tmp_path):
    """A Kinco FD3 with its RS232 and RS485 ports, commissioned over RS232: (RS485 path, the
    RS232 driver to read it back)."""
    rs232, rs485 = tmp_path / "ttyKINCO", tmp_path / "ttyRS485"
    p = PERSONALITIES["kinco-fd3"]
    twin = launch(p.device, p.node, extra=("--rs232", str(rs232), "--rs485", str(rs485)))
    serial_line(twin, "RS232", rs232)
    serial_line(twin, "RS485", rs485)
    driver = AgvKincoDriver(rs232, p.node)
    driver.write(0x2010, 3, 0, 2)
    driver.write(0x2010, 5, 0, 2)
    yield rs485, driver
    driver.close()


def test_mbpoll_script_enables_homes_and_moves_the_cmmo_st(cmmo, mbpoll):  # noqa: F811
    twin = cmmo()
    out = run(["bash", str(HERE / "sh" / "fhpp_mbpoll.sh"), HOST, str(twin.port), str(FHPP_TARGET)])
    assert "enabled" in out and "homed" in out and "reached" in out, out
    assert abs(fhpp_actual(twin)["actual"] - FHPP_TARGET) <= 180


def test_libmodbus_program_enables_homes_and_moves_the_cmmo_st(cmmo, libmodbus_programs):  # noqa: F811
    twin = cmmo()
    out = run([libmodbus_programs["fhpp_libmodbus"], HOST, str(twin.port), str(FHPP_TARGET)])
    assert "reached" in out, out
    assert abs(fhpp_actual(twin)["actual"] - FHPP_TARGET) <= 180


def test_mbpoll_script_enables_and_moves_the_kinco_over_rtu(kinco_rtu, mbpoll):
    rs485, driver = kinco_rtu
    out = run(["bash", str(HERE / "sh" / "kinco_rtu_mbpoll.sh"), str(rs485), str(KINCO_TARGET)])
    assert "enabled" in out and "reached" in out, out
    assert abs(driver.read(0x6063) - KINCO_TARGET) <= driver.read(0x6067)


def test_libmodbus_program_enables_every_run_and_moves_the_kinco_over_rtu(kinco_rtu,
                                                                         libmodbus_programs):
    rs485, driver = kinco_rtu
    out = run([libmodbus_programs["kinco_rtu_libmodbus"], str(rs485), str(KINCO_TARGET)])
    assert "enabled in 20 of 20 runs" in out and "reached" in out, out
    assert abs(driver.read(0x6063) - KINCO_TARGET) <= driver.read(0x6067)
