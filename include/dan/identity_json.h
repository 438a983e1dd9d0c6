/*
 * A discovered peer as one JSON object, written into a caller's buffer: the
 * FC firmware (semihosting, no stdio) and dan-master (stdio) print the same
 * object with the same escaping from this one formatter. Portable C99, no
 * stdio, no allocation.
 */
#ifndef DAN_IDENTITY_JSON_H
#define DAN_IDENTITY_JSON_H

#include <stddef.h>

#include "dan/master.h"

#ifdef __cplusplus
extern "C" {
#endif

/* dan_peer_json() flag: also "first_code", "hw_version" and "capabilities"
 * (dan-master prints them; the firmware keeps its lines short). */
#define DAN_PEER_JSON_FULL 1u

/* A buffer this large always holds a whole object: four strings of at most
 * DAN_MAX_STRING - 1 bytes, each escaped to at most 6 bytes a byte, plus
 * the keys, numbers and the NUL. */
#define DAN_PEER_JSON_MAX (4u * 6u * DAN_MAX_STRING + 256u)

/* s as a JSON string: quoted, '"' and '\' escaped with a backslash, bytes
 * below 0x20 and from 0x7F up as \u00xx. Writes at most cap - 1 bytes and
 * a NUL (nothing when cap is 0); an escape that would not fit whole is
 * left out. Returns the bytes written without the NUL. */
size_t dan_json_str(char *out, size_t cap, const char *s);

/* The peer with its identity id (as reported by discovery, see
 * dan_master_set_identities()) as {"type":NAME,"baud":N,"dan_version":N,"manufacturer":S,
 * "model":S,"sw_version":S,"baud_mask":N}, with DAN_PEER_JSON_FULL also
 * "first_code" after "type", "hw_version" after "model" and "capabilities"
 * last. NAME is the registry's name of p->first_code, or "?". Output and
 * return value as dan_json_str(). */
size_t dan_peer_json(char *out, size_t cap, const dan_peer_t *p, const dan_identity_t *id,
                     unsigned flags);

#ifdef __cplusplus
}
#endif

#endif /* DAN_IDENTITY_JSON_H */
