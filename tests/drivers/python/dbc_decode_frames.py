"""Decodes frames of any DBC through canmatrix (Debian python3-canmatrix), a DBC reader nobody
here wrote, for tests/drivers/dbc_reader_test.cpp.

  dbc_decode_frames.py DBC FRAMES
      FRAMES has one frame per line: "<id hex> <data hex>", an identifier of 8 hex digits being a
      29-bit (extended) one, as candump writes them. Prints per frame and decoded signal
      "<line index> <signal name> <raw>": the raw integer, or for a float signal its value
      ("%.17g"). A multiplexed message decodes to its multiplexor, the signals of the multiplexor's
      value and the ones that are not multiplexed.
"""
import sys

import canmatrix
import canmatrix.formats


def main(dbc_path, frames_path):
    db = canmatrix.formats.loadp_flat(dbc_path)
    with open(frames_path) as f:
        for index, line in enumerate(f):
            can_id, data = line.split()
            arb = canmatrix.ArbitrationId(int(can_id, 16), extended=len(can_id) == 8)
            frame = db.frame_by_id(arb)
            if frame is None:
                sys.exit("no message with id %s in %s" % (can_id, dbc_path))
            for name, value in frame.decode(bytes.fromhex(data)).items():
                signal = value.signal
                if signal.is_float:
                    print("%d %s %.17g" % (index, name, float(value.raw_value)))
                else:
                    print("%d %s %d" % (index, name, int(value.raw_value)))


if __name__ == "__main__":
    if len(sys.argv) != 3:
        sys.exit("usage: dbc_decode_frames.py DBC FRAMES")
    main(sys.argv[1], sys.argv[2])
