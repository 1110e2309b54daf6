"""Decodes frames with drivers/imu/imu.dbc through canmatrix (Debian python3-canmatrix), a DBC
reader nobody here wrote, for tests/drivers/imu_dbc_test.cpp.

  dbc_decode.py DBC FRAMES
      FRAMES has one frame per line: "<id hex> <8 data bytes hex>". Prints, per frame and signal,
      "<line index> <signal name> <raw integer>", and first one line per message of the DBC:
      "message <id hex> <name> <dlc>".
"""
import sys

import canmatrix
import canmatrix.formats


def main(dbc_path, frames_path):
    db = canmatrix.formats.loadp_flat(dbc_path)
    for frame in db.frames:
        print("message %X %s %d" % (frame.arbitration_id.id, frame.name, frame.size))
    with open(frames_path) as f:
        for index, line in enumerate(f):
            can_id, data = line.split()
            frame = db.frame_by_id(canmatrix.ArbitrationId(int(can_id, 16)))
            if frame is None:
                sys.exit("no message with id %s in %s" % (can_id, dbc_path))
            for name, value in frame.decode(bytes.fromhex(data)).items():
                print("%d %s %d" % (index, name, int(value.raw_value)))


if __name__ == "__main__":
    if len(sys.argv) != 3:
        sys.exit("usage: dbc_decode.py DBC FRAMES")
    main(sys.argv[1], sys.argv[2])
