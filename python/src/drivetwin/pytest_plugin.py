"""pytest fixtures for tests against drivetwin cells (loaded through the `pytest11` entry
point when the package is installed).

- ``drivetwin_cell``: a :class:`~drivetwin.Cell` running for one test; one CMMP-AS at node 1
  unless the test says otherwise, by indirect parametrization::

      @pytest.mark.parametrize("drivetwin_cell", ["cmmp-as", "nanotec-pd4n"], indirect=True)

  (a device name, a list of devices, or a dict of :class:`~drivetwin.Cell` arguments), or by a
  marker: ``@pytest.mark.drivetwin(devices=["cmmp-as", "cmmo-st"])``,
  ``@pytest.mark.drivetwin(config="cell.toml")``;
- ``drivetwin_network``: a python-canopen ``Network`` joined to the cell's first bus;
- ``drivetwin_node``: the cell's first CANopen drive on that network, with its EDS, after its
  first heartbeat: a ``BaseNode402`` with its state machine set up to use SDOs (a CiA 402
  drive) or a ``RemoteNode``;
- ``drivetwin_cells``: a factory, ``drivetwin_cells(devices=[...])``, for several cells.

Every cell is stopped after the test; one that died or did not stop cleanly fails the test
with its standard error. ``--drivetwin-binary PATH`` runs another binary than the wheel's.
"""

from __future__ import annotations

from typing import Any, Callable, Dict, Iterator, List, Mapping, Optional, Sequence

import pytest

from .cell import Cell
from .cellfile import MODBUS_DEVICES

#: The personalities without CiA 402 (python-canopen's RemoteNode, not BaseNode402).
PLAIN_DEVICES = frozenset({"testbench"})


def pytest_addoption(parser: pytest.Parser) -> None:
    group = parser.getgroup("drivetwin")
    group.addoption("--drivetwin-binary", default=None, metavar="PATH",
                    help="the drivetwin binary the fixtures run (default: the wheel's, "
                         "or $DRIVETWIN_BIN)")


def pytest_configure(config: pytest.Config) -> None:
    config.addinivalue_line(
        "markers",
        "drivetwin(devices=None, config=None, **cell_args): the cell `drivetwin_cell` starts "
        "(arguments of drivetwin.Cell)")


def _cell_args(request: pytest.FixtureRequest) -> Dict[str, Any]:
    """The Cell arguments of this test: its indirect parameter, else its marker, else none."""
    param = getattr(request, "param", None)
    if param is not None:
        if isinstance(param, str):
            return {"devices": [param]}
        if isinstance(param, Mapping):
            return dict(param)
        if isinstance(param, Sequence):
            return {"devices": list(param)}
        raise TypeError(f"drivetwin_cell parameter {param!r}: a device name, a list of "
                        "devices or a dict of drivetwin.Cell arguments")
    marker = request.node.get_closest_marker("drivetwin")
    if marker is None:
        return {}
    args = dict(marker.kwargs)
    if marker.args:
        args["devices"] = list(marker.args[0]) if not isinstance(marker.args[0], str) \
            else list(marker.args)
    return args


def _start(request: pytest.FixtureRequest, args: Dict[str, Any]) -> Cell:
    args.setdefault("binary", request.config.getoption("--drivetwin-binary"))
    cell = Cell(**args).__enter__()
    cells = getattr(request.node, "_drivetwin_cells", [])
    cells.append(cell)
    request.node._drivetwin_cells = cells
    return cell


@pytest.hookimpl(wrapper=True)
def pytest_runtest_makereport(item: pytest.Item, call: pytest.CallInfo) -> Any:
    """A failed test's report carries what each of its cells printed (its addresses on
    standard output, its log on standard error)."""
    report = yield
    if report.failed:
        for i, cell in enumerate(getattr(item, "_drivetwin_cells", [])):
            for name, text in (("stdout", "\n".join(cell.stdout_lines)), ("stderr", cell.stderr)):
                if text.strip():
                    report.sections.append((f"drivetwin cell {i} {name}", text[-8000:]))
    return report


@pytest.fixture
def drivetwin_cell(request: pytest.FixtureRequest) -> Iterator[Cell]:
    """A running cell for this test (one CMMP-AS at node 1 by default)."""
    cell = _start(request, _cell_args(request))
    yield cell
    cell.__exit__(None, None, None)


@pytest.fixture
def drivetwin_cells(request: pytest.FixtureRequest) -> Iterator[Callable[..., Cell]]:
    """Factory: ``drivetwin_cells(devices=[...])`` starts a cell; all stop after the test."""
    cells: List[Cell] = []

    def start(config: Any = None, **kwargs: Any) -> Cell:
        if config is not None:
            kwargs["config"] = config
        cell = _start(request, kwargs)
        cells.append(cell)
        return cell

    yield start
    errors = []
    for cell in cells:
        try:
            cell.__exit__(None, None, None)
        except Exception as e:  # every cell is stopped; the first failure is reported
            errors.append(e)
    if errors:
        raise errors[0]


@pytest.fixture
def drivetwin_network(drivetwin_cell: Cell) -> Iterator[Any]:
    """A python-canopen Network joined to the cell's first CAN bus over socketcand."""
    canopen = pytest.importorskip("canopen", reason="python-canopen is not installed")
    net = canopen.Network()
    # A short receive timeout: disconnect() joins the notifier thread at once.
    net.NOTIFIER_CYCLE = 0.05
    net.connect(**drivetwin_cell.bus.can_kwargs())
    yield net
    net.disconnect()


def _first_can_drive(cell: Cell) -> Optional[Dict[str, Any]]:
    """The first drive of the cell file on CANopen (not a CMMO-ST, not EtherCAT only)."""
    for d in cell.drive_specs:
        interfaces = d.get("interfaces")
        if str(d.get("device", "")) in MODBUS_DEVICES or "modbus" in d:
            continue
        if interfaces is not None and "canopen" not in interfaces:
            continue
        if interfaces is None and "ethercat" in d:
            continue
        return d
    return None


@pytest.fixture
def drivetwin_node(drivetwin_cell: Cell, drivetwin_network: Any) -> Any:
    """The cell's first CANopen drive, with its EDS, once its first heartbeat came."""
    from canopen import RemoteNode
    from canopen.profiles.p402 import BaseNode402

    spec = _first_can_drive(drivetwin_cell)
    if spec is None:
        pytest.fail("drivetwin_node: the cell has no CANopen drive", pytrace=False)
    device = str(spec.get("device", ""))
    eds = spec.get("eds") or str(drivetwin_cell.eds(device))
    node_id = int(spec.get("node", 1))
    cls = RemoteNode if device in PLAIN_DEVICES else BaseNode402
    node = cls(node_id, str(eds))
    # python-canopen waits 0.3 s for an SDO answer; a CI machine running many jobs at once
    # can take longer (the twin answers within its manual's times; the host is late).
    node.sdo.RESPONSE_TIMEOUT = max(node.sdo.RESPONSE_TIMEOUT, 2.0)
    drivetwin_network.add_node(node)
    node.nmt.wait_for_heartbeat(5)
    if isinstance(node, BaseNode402):
        # Statusword and controlword by SDO: right on every drive whatever its PDOs and NMT
        # state (a master that maps them calls setup_402_state_machine() again).
        node.setup_402_state_machine(read_pdos=False)
    return node
