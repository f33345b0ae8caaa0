"""A plain pymodbus Modbus TCP server for the loopback benchmark
(`cargo bench -p drivetwin --bench modbus_loopback`): 16 holding registers from address 0,
answering FC 0x03, 0x10 and 0x17 with pymodbus's own request handling.

Usage: python3 tests/bench/pymodbus_server.py PORT
"""

from __future__ import annotations

import asyncio
import logging
import sys

from pymodbus.datastore import (
    ModbusDeviceContext,
    ModbusSequentialDataBlock,
    ModbusServerContext,
)
from pymodbus.server import StartAsyncTcpServer


async def main(port: int) -> None:
    logging.getLogger("pymodbus").setLevel(logging.ERROR)
    # pymodbus numbers the data block from 1: block address 1 is protocol address 0.
    device = ModbusDeviceContext(hr=ModbusSequentialDataBlock(1, [0] * 16))
    context = ModbusServerContext(devices=device, single=True)
    await StartAsyncTcpServer(context=context, address=("127.0.0.1", port))


if __name__ == "__main__":
    if len(sys.argv) != 2 or not sys.argv[1].isdigit():
        sys.exit(f"usage: {sys.argv[0]} PORT")
    try:
        asyncio.run(main(int(sys.argv[1])))
    except KeyboardInterrupt:
        pass
