/*
 * libdan compile-time configuration.
 *
 * Every setting has a default here; override it with -D on the compiler
 * command line (or a header included first). Derived maxima are computed
 * from the settings, so buffers are sized statically and the library never
 * allocates.
 */
#ifndef DAN_CONFIG_H
#define DAN_CONFIG_H

/*
 * Largest payload a frame may carry, in bytes. A decoder rejects (and counts
 * as "oversize") any frame that declares a longer payload; encoders refuse to
 * build one. The default fits a 120-byte serial-tunnel chunk plus its header,
 * or twelve raw CAN frames. Must be at least 64 and at most 16383 (so the
 * length field stays within two uvarint bytes).
 */
#ifndef DAN_MAX_PAYLOAD
#define DAN_MAX_PAYLOAD 160u
#endif

/* Longest string the common payload decoders keep (identity fields, error
 * text), including the terminating NUL. Longer strings on the wire are
 * accepted and truncated (the *_truncated flag is set). */
#ifndef DAN_MAX_STRING
#define DAN_MAX_STRING 32u
#endif

#if DAN_MAX_PAYLOAD < 64u || DAN_MAX_PAYLOAD > 16383u
#error "DAN_MAX_PAYLOAD must be within 64..16383"
#endif
#if DAN_MAX_STRING < 2u || DAN_MAX_STRING > 255u
#error "DAN_MAX_STRING must be within 2..255"
#endif

/* Bytes a uvarint needs for a constant (for static sizing). */
#define DAN_UVARINT_SIZE(v)                                            \
    ((v) < 0x80u ? 1u : (v) < 0x4000u ? 2u : (v) < 0x200000u ? 3u :    \
     (v) < 0x10000000u ? 4u : 5u)

/* Longest uvarint accepted on the wire: 32-bit values. */
#define DAN_UVARINT_MAX_BYTES 5u

/* Largest frame on the wire: sync, code (up to 5 bytes), length, payload, CRC. */
#define DAN_MAX_FRAME                                                  \
    (1u + DAN_UVARINT_MAX_BYTES + DAN_UVARINT_SIZE(DAN_MAX_PAYLOAD) +  \
     DAN_MAX_PAYLOAD + 1u)

#endif /* DAN_CONFIG_H */
