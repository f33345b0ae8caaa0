"""A C master linked against SOEM (the sources pysoem's source distribution carries, fetched
with pip at test time) against the twin's EtherCAT slave on a veth pair, doing what SOEM's
samples do: find the slave, read its SII identity and compare it with CoE 1018h, map the
process data, Safe-Op, Op, 2000 cycles of 1 ms with the working counter checked on every one
while the controlword in the outputs enables the CiA 402 drive, back to Init
(c/soem_master.c). Judged by what it set out to do: found, read, reached Op, every working
counter right, enabled. Needs root and iproute2 (the veth fixture skips otherwise)."""

from __future__ import annotations

import subprocess

import pytest

from conftest import ecat_twin_run
from field_build import soem_master as build_soem_master

FESTO = 0x1D


@pytest.fixture(scope="module")
def soem_master(tmp_path_factory) -> str:
    build = tmp_path_factory.mktemp("soem")
    return str(build_soem_master(build, "soem_master"))


def test_soem_master_finds_reads_and_runs_the_slave(veth, tmp_path, soem_master):
    with ecat_twin_run(veth, tmp_path) as (master_if, _):
        r = subprocess.run([soem_master, master_if, "2000"], capture_output=True, text=True,
                           timeout=60)
    out = r.stdout
    print(out)
    assert r.returncode == 0, f"exit {r.returncode}:\n{out}\n{r.stderr}"
    assert "1 slaves found" in out, out
    assert f"man {FESTO:08X}" in out, out
    assert "Op\n" in out and ", 0 with a wrong working counter" in out, out
    assert "End, ok" in out, out
