"""Compact ESC exchange vectors of tests/vectors/gateway.txt
(docs/PROTOCOL.md section 7, "Fast ESC exchanges": ESC_FAST 0x59,
ESC_FAST_T 0x5A), written from the document like gen_gateway.py, which
prints them after its own.

Field texts:
  esc_fast req     values=v1,v2,...     (both codes: the same request)
  esc_fast rsp     flags= then, with a record, rec=<index>/<fresh>/<age_4ms>/
                   <voltage f16>/<current f16>/<temperature f16, 4 hex each>/<rpm>
  esc_fast bad     a request payload every decoder must refuse (length or padding)
  esc_fast_rsp bad a response payload every decoder must refuse (length)
"""

from _wire import u8, u16, u24


def pack14(values):
    """The ESC_CMD bit stream without its count: value i at bits 14i.., LSB
    first, the last byte zero-padded."""
    acc = 0
    for i, v in enumerate(values):
        acc |= (v & 0x3FFF) << (14 * i)
    return acc.to_bytes((14 * len(values) + 7) // 8, "little")


def rec_bytes(index, fresh, age4, volt, cur, temp, rpm):
    """voltage, current, temperature (binary16 bits), u24 rpm int18 | index
    << 18 | fresh << 23, u8 age in 4 ms units."""
    packed = (rpm & 0x3FFFF) | (index << 18) | (int(fresh) << 23)
    return u16(volt) + u16(cur) + u16(temp) + u24(packed) + u8(age4)


def fast_vectors(emit):
    for values in (
        [0, 100, 200, 300],
        [-1],
        [-8192, 8191, 0, 1, -1, 1234, -4321, 5000],
        [i * 811 - 8000 for i in range(20)],
        [8191] * 3,
    ):
        emit("esc_fast", "req", ["values=" + ",".join(map(str, values))], pack14(values))
    emit("esc_fast", "rsp", ["flags=5"], u8(5))
    # 16.8 V = 0x4C33, 3.5 A = 0x4300, 310 K = 0x5CD8
    recs = [
        (flags, r)
        for flags, r in (
            (5, (2, 1, 3, 0x4C33, 0x4300, 0x5CD8, 5002)),
            (4, (31, 0, 255, 0x7BFF, 0xBD00, 0x0001, -131072)),
            (0, (0, 1, 0, 0, 0, 0, 131071)),
            (7, (17, 0, 9, 0x4A40, 0x8000, 0x5CB0, -1)),
        )
    ]
    for flags, r in recs:
        text = "rec=%d/%d/%d/%04x/%04x/%04x/%d" % r
        emit("esc_fast", "rsp", ["flags=%d" % flags, text], u8(flags) + rec_bytes(*r))
    # every length no count of values has (and counts above 20), and a set
    # padding bit (1 value: 2 padding bits; 3 values: 6)
    good = {(14 * n + 7) // 8 for n in range(1, 21)}
    for length in range(0, 37):
        if length not in good:
            emit("esc_fast", "bad", [], bytes(range(length)))
    emit("esc_fast", "bad", [], bytes.fromhex("0040"))
    emit("esc_fast", "bad", [], pack14([1, 2, 3])[:-1] + b"\x80")
    for length in (0, 2, 10, 12, 20):
        emit("esc_fast_rsp", "bad", [], bytes(length))
