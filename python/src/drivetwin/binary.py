"""Where the `drivetwin` binary is: the one the wheel installed beside this interpreter's
scripts, unless told otherwise."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import sysconfig
from pathlib import Path
from typing import Optional, Union

from .errors import BinaryNotFound

ENV = "DRIVETWIN_BIN"


def find_binary(explicit: Optional[Union[str, os.PathLike]] = None) -> Path:
    """The binary to run, in this order: `explicit`, `$DRIVETWIN_BIN`, the scripts folder of
    this interpreter (where the wheel puts it, also when the venv is not activated), `PATH`."""
    candidates = []
    if explicit is not None:
        candidates.append(Path(explicit))
    elif os.environ.get(ENV):
        candidates.append(Path(os.environ[ENV]))
    else:
        for scheme_dir in (sysconfig.get_path("scripts"), str(Path(sys.executable).parent)):
            if scheme_dir:
                candidates.append(Path(scheme_dir) / "drivetwin")
        found = shutil.which("drivetwin")
        if found:
            candidates.append(Path(found))
    for path in candidates:
        if path.is_file() and os.access(path, os.X_OK):
            return path
    tried = ", ".join(str(p) for p in candidates) or "nothing"
    raise BinaryNotFound(
        f"no drivetwin binary (tried {tried}): install the wheel (`pip install drivetwin`), "
        f"or set {ENV} to a built binary (`cargo build --release -p drivetwin`)"
    )


def binary_version(binary: Optional[Union[str, os.PathLike]] = None) -> str:
    """What `drivetwin --version` says: the version and the device files the binary carries."""
    result = subprocess.run([str(find_binary(binary)), "--version"], capture_output=True,
                            text=True, timeout=30, check=True)
    return result.stdout.strip()
