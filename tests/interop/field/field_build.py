"""Building the field programs written in C: `cc` from the machine (scripts/test installs it
with libmodbus-dev), and the SOEM sources that pysoem's source distribution carries, fetched
with pip at test time (they are not part of this repository)."""

from __future__ import annotations

import shutil
import subprocess
import sys
import tarfile
from pathlib import Path

import pytest

HERE = Path(__file__).resolve().parent
C_DIR = HERE / "c"
REQUIREMENTS = HERE.parent / "requirements.txt"


def cc(output: Path, sources: list[Path], *flags: str) -> Path:
    """Compiles and links `sources` into `output`; fails the test with the compiler's words."""
    compiler = shutil.which("cc")
    if compiler is None:
        pytest.skip("no C compiler (`cc`): scripts/test installs gcc")
    r = subprocess.run([compiler, "-std=gnu99", "-O2", "-Wall", "-o", str(output),
                        *map(str, sources), *flags], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, f"cc {output.name}: {r.stderr}"
    return output


def pysoem_version() -> str:
    """The pysoem version the interop tests pin."""
    for line in REQUIREMENTS.read_text().splitlines():
        if line.startswith("pysoem=="):
            return line.split("==", 1)[1].strip()
    raise AssertionError(f"no pysoem pin in {REQUIREMENTS}")


def soem_sources(into: Path) -> Path:
    """Downloads pysoem's source distribution (pip, no wheel; its build dependencies as
    wheels) and unpacks it under `into`; returns its `soem` directory."""
    version = pysoem_version()
    r = subprocess.run([sys.executable, "-m", "pip", "download", "--quiet",
                        "--disable-pip-version-check", "--no-deps", "--no-binary", "pysoem",
                        f"pysoem=={version}", "-d", str(into)],
                       capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, f"pip download pysoem=={version}: {r.stderr[-2000:]}"
    archive = into / f"pysoem-{version}.tar.gz"
    with tarfile.open(archive) as tar:
        if hasattr(tarfile, "data_filter"):
            tar.extractall(into, filter="data")
        else:
            tar.extractall(into)
    soem = into / f"pysoem-{version}" / "soem"
    assert (soem / "soem" / "ethercatmain.c").is_file(), f"no SOEM sources in {archive}"
    return soem


def soem_master(build: Path, name: str) -> Path:
    """Builds the C master `c/<name>.c` with the context it shares with the other masters
    (`c/soem_context.c`) and SOEM (EC_VER2) from pysoem's sources, into `build/<name>`."""
    soem = soem_sources(build)
    sources = [C_DIR / f"{name}.c", C_DIR / "soem_context.c",
               *sorted((soem / "soem").glob("*.c")), soem / "osal" / "linux" / "osal.c",
               *sorted((soem / "oshw" / "linux").glob("*.c"))]
    includes = [f"-I{soem / d}" for d in ("soem", "osal", "osal/linux", "oshw/linux")]
    return cc(build / name, sources, "-DEC_VER2", *includes, "-lpthread", "-lrt")
