"""The SLCAN (Lawicel) frame lines, shared by slcan_hub.py and danprobe's
slcan command (docs/SLCAN.md):

  tIIIL<data>   11-bit data frame      TIIIIIIIIL<data>  29-bit
  rIIIL         11-bit remote frame    RIIIIIIIIL        29-bit

I: the identifier in hex, L: the data length 0..8, data: 2L hex digits
(either case in, upper case out), then CR. Received frames may end with 4
hex digits of milliseconds (timestamps on, Z1).

Standard library only: slcan_hub.py runs with the system python3, outside
the venv.
"""

from typing import NamedTuple, Optional

ACK, BEL = b"\r", b"\x07"
LINE_MAX = 64  # longer command lines are refused (BEL)
HEX = frozenset(b"0123456789abcdefABCDEF")
SFF_MASK, EFF_MASK = 0x7FF, 0x1FFFFFFF
FRAME_KINDS = (b"t", b"T", b"r", b"R")


class Frame(NamedTuple):
    """One classic CAN frame; a remote frame has a dlc and no data."""

    id: int
    ext: bool
    rtr: bool
    dlc: int
    data: bytes


def is_hex(b: bytes) -> bool:
    return bool(b) and set(b) <= HEX


def parse_frame(line: bytes) -> Optional[Frame]:
    """A t/T/r/R line (no CR, no timestamp) as a Frame, or None if it is
    malformed: not a frame letter, identifier or length not hex, an
    identifier out of range, data of another length."""
    kind = line[:1]
    if kind not in FRAME_KINDS:
        return None
    ext, rtr = kind in (b"T", b"R"), kind in (b"r", b"R")
    idlen = 8 if ext else 3
    ident, dlc = line[1 : 1 + idlen], line[1 + idlen : 2 + idlen]
    if len(ident) != idlen or not is_hex(ident) or len(dlc) != 1 or dlc not in b"012345678":
        return None
    fid, n = int(ident, 16), int(dlc)
    if fid > (EFF_MASK if ext else SFF_MASK):
        return None
    body = line[2 + idlen :]
    if rtr:
        return None if body else Frame(fid, ext, True, n, b"")
    if len(body) != 2 * n or (n and not is_hex(body)):
        return None
    return Frame(fid, ext, False, n, bytes.fromhex(body.decode()))


def format_frame(f, stamp_ms: Optional[int] = None) -> bytes:
    """The line (with its CR) of a frame: anything with id, ext, rtr, dlc
    and data (a Frame, gateway_can.CanFrame). stamp_ms is taken modulo
    60000, as adapters count."""
    kind = ("R" if f.ext else "r") if f.rtr else ("T" if f.ext else "t")
    text = kind + (f"{f.id:08X}" if f.ext else f"{f.id:03X}") + str(f.dlc)
    if not f.rtr:
        text += f.data.hex().upper()
    if stamp_ms is not None:
        text += f"{stamp_ms % 60000:04X}"
    return text.encode() + ACK


def tx_ack(ext: bool) -> bytes:
    """An adapter's answer to a frame it sent: Z for a 29-bit one, z else."""
    return b"Z\r" if ext else b"z\r"
