"""Decodes a candump log with a DBC through python-can's candump reader and canmatrix (Debian
python3-can, python3-canmatrix): peer tools nobody here wrote, for
tests/drivers/dbc_candump_test.cpp.

  dbc_decode_candump.py DBC LOG
      Prints per frame of the log and decoded signal "<frame index> <signal name> <physical>"
      ("%.17g"); a multiplexed message decodes to its multiplexor, the signals of the
      multiplexor's value and the ones that are not multiplexed. Frames of no message of the DBC
      are skipped (their index still counts).
"""
import sys

import can
import canmatrix
import canmatrix.formats


def main(dbc_path, log_path):
    db = canmatrix.formats.loadp_flat(dbc_path)
    for index, msg in enumerate(can.CanutilsLogReader(log_path)):
        arb = canmatrix.ArbitrationId(msg.arbitration_id, extended=msg.is_extended_id)
        frame = db.frame_by_id(arb)
        if frame is None:
            continue
        for name, value in frame.decode(bytes(msg.data)).items():
            print("%d %s %.17g" % (index, name, float(value.phys_value)))


if __name__ == "__main__":
    if len(sys.argv) != 3:
        sys.exit("usage: dbc_decode_candump.py DBC LOG")
    main(sys.argv[1], sys.argv[2])
