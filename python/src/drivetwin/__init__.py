"""drivetwin: software twins of fieldbus motor controllers, from Python.

- :class:`Cell`: `drivetwin run` on free loopback ports as a context manager, with its
  socketcand, Modbus TCP, serial and web console addresses;
- :class:`Client` (`Cell.api`): the console's REST API, typed;
- the pytest plugin (:mod:`drivetwin.pytest_plugin`, loaded by pytest when the package is
  installed): the fixtures `drivetwin_cell`, `drivetwin_network`, `drivetwin_node` and
  `drivetwin_cells`.

The wheel carries the `drivetwin` binary itself (installed beside the interpreter's scripts).
"""

from __future__ import annotations

from importlib.metadata import PackageNotFoundError, version as _version

from .binary import binary_version, find_binary
from .cell import Cell, Endpoint, SerialLine, SocketcandBus
from .client import Client
from .errors import (ApiError, ApiTimeout, BinaryNotFound, CellDied, CellStartError, Conflict,
                     DrivetwinError, NotFound)

try:
    __version__ = _version("drivetwin")
except PackageNotFoundError:  # run from a source tree
    __version__ = "0+unknown"

__all__ = ["ApiError", "ApiTimeout", "BinaryNotFound", "Cell", "CellDied", "CellStartError",
           "Client", "Conflict", "DrivetwinError", "Endpoint", "NotFound", "SerialLine",
           "SocketcandBus", "binary_version", "find_binary", "__version__"]
