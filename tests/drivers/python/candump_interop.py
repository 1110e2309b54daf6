"""Interop helper for tests/drivers/can_candump_test.cpp: python-can (Debian python3-can) as the
independent reader and writer of candump logs.

  candump_interop.py read LOG
      Reads LOG with can.CanutilsLogReader and prints one line per message:
      "<timestamp %.6f> <arbitration id hex> <ext 0|1> <rtr 0|1> <err 0|1> <dlc> <data hex or ->"
      then "count <n>".
  candump_interop.py write SPEC LOG
      SPEC has one frame per line: "<timestamp_us> <id hex> <ext 0|1> <rtr 0|1> <dlc> <data hex or ->";
      writes them to LOG with can.CanutilsLogWriter (channel "can0").
"""
import sys

import can


def read(path):
    n = 0
    with can.CanutilsLogReader(path) as reader:
        for msg in reader:
            data = bytes(msg.data).hex().upper() if msg.data else "-"
            print("%.6f %X %d %d %d %d %s" % (msg.timestamp, msg.arbitration_id, int(msg.is_extended_id),
                                              int(msg.is_remote_frame), int(msg.is_error_frame), msg.dlc, data))
            n += 1
    print("count %d" % n)


def write(spec, path):
    writer = can.CanutilsLogWriter(path, channel="can0")
    with open(spec) as f:
        for line in f:
            ts_us, can_id, ext, rtr, dlc, data = line.split()
            msg = can.Message(timestamp=int(ts_us) / 1e6, arbitration_id=int(can_id, 16),
                              is_extended_id=ext == "1", is_remote_frame=rtr == "1", dlc=int(dlc),
                              data=None if data == "-" else bytes.fromhex(data), channel="can0")
            writer.on_message_received(msg)
    writer.stop()


if __name__ == "__main__":
    if len(sys.argv) == 3 and sys.argv[1] == "read":
        read(sys.argv[2])
    elif len(sys.argv) == 4 and sys.argv[1] == "write":
        write(sys.argv[2], sys.argv[3])
    else:
        sys.exit("usage: candump_interop.py read LOG | write SPEC LOG")
