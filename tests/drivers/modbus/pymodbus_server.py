#!/usr/bin/python3
"""An independent Modbus TCP server (pymodbus) laid out like drivers/configs/*_map.yaml.

Input registers 0..5 hold a drive (status, actual_position int32 big-endian, velocity, fault
code); holding 0..2 its control and target. A write to control copies the enable bit into
status; a write to the target moves actual_position there at once (a perfect drive).
Input registers 10..12 hold a transducer: pressure float32 MPa big-endian and a status word.
Usage: pymodbus_server.py PORT PRESSURE_MPA
"""
import struct
import sys
import types

# pymodbus.server imports pyserial and serial_asyncio even for TCP. Where python3-serial or
# python3-serial-asyncio is missing, stand-ins let the TCP server load (it uses neither).
for name in ("serial", "serial_asyncio"):
    try:
        __import__(name)
    except ImportError:
        stub = types.ModuleType(name)
        stub.create_serial_connection = None
        sys.modules[name] = stub

from pymodbus.datastore import ModbusSequentialDataBlock, ModbusServerContext, ModbusSlaveContext
from pymodbus.server import StartTcpServer


class Drive(ModbusSlaveContext):
    def setValues(self, fc_as_hex, address, values):
        super().setValues(fc_as_hex, address, values)
        if fc_as_hex in (6, 16):
            hr = super().getValues(3, 0, 3)
            status = super().getValues(4, 0, 1)[0]
            status = (status & ~1) | (hr[0] & 1)
            super().setValues(4, 0, [status])
            if hr[0] & 1:
                super().setValues(4, 1, hr[1:3])


def main():
    port = int(sys.argv[1])
    hi, lo = struct.unpack(">HH", struct.pack(">f", float(sys.argv[2])))
    ir = [0] * 16
    ir[1], ir[2] = 0x0000, 0xC350  # actual position 50000 counts = 0.5 rad
    ir[10], ir[11], ir[12] = hi, lo, 0
    store = Drive(ir=ModbusSequentialDataBlock(0, ir), hr=ModbusSequentialDataBlock(0, [0] * 16),
                  co=ModbusSequentialDataBlock(0, [0] * 16), di=ModbusSequentialDataBlock(0, [0] * 16),
                  zero_mode=True)
    print("pymodbus server on", port, flush=True)
    StartTcpServer(context=ModbusServerContext(slaves=store, single=True), address=("127.0.0.1", port))


if __name__ == "__main__":
    main()
