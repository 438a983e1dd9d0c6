#!/usr/bin/env python3
"""A CAN frame source on an SLCAN adapter (a slcan_hub port): 29-bit frames,
16 at a time, as fast as the port takes them, for SECONDS.

    python3 tests/tools/can_flood.py PORT SECONDS

Prints READY once the channel is open, and at the end the number of frames
written. Used by the fault tests (a CAN flood while ESC commands flow) and
the raw CAN benchmark. Standard library only.
"""

import os
import sys
import time
import tty


def main(path, seconds):
    fd = os.open(path, os.O_RDWR | os.O_NOCTTY)
    tty.setraw(fd)
    os.write(fd, b"C\rS8\rO\r")
    time.sleep(0.2)
    os.set_blocking(fd, False)
    print("READY", flush=True)
    n, end = 0, time.monotonic() + seconds
    while time.monotonic() < end:
        try:
            os.write(
                fd,
                b"".join(b"T%08X8%016X\r" % (0x1ABC0000 + (k & 0xFF), k) for k in range(n, n + 16)),
            )
            n += 16
        except BlockingIOError:
            pass  # the hub has not read what we wrote yet
        try:
            while os.read(fd, 65536):  # its z acknowledgements
                pass
        except (BlockingIOError, OSError):
            pass
        time.sleep(0.002)
    print(n, flush=True)


if __name__ == "__main__":
    main(sys.argv[1], float(sys.argv[2]))
