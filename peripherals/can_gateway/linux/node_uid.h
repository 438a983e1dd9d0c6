/*
 * The gateway's DroneCAN unique ID (GetNodeInfo hardware_version.unique_id,
 * 16 bytes) for dan-gatewayd: from --uid, or derived from the machine ID.
 *
 * Derived: byte 4k..4k+3 (k = 0..3) is the 32-bit FNV-1a hash, little
 * endian, of the text "dan-gatewayd:K:" (K the digit k) followed by the
 * 32 hex digits of /etc/machine-id. A hash, not the machine ID itself:
 * systemd asks programs not to publish it (machine-id(5)), and a bus
 * sniffer must not learn it. Stable across reboots, different per machine.
 * Without a machine ID (file missing, unreadable, not 32 hex digits) the
 * same hash is taken of "host:" and the host name instead: stable while
 * the host name is, but two gateways with one host name share it, so the
 * daemon warns and --uid should be given. All zeros, which DroneCAN
 * reserves for "undefined", is never the result (the last byte becomes 1).
 */
#ifndef DAN_GWD_NODE_UID_H
#define DAN_GWD_NODE_UID_H

#include <stddef.h>
#include <stdint.h>

#define DAN_UID_SIZE     16u
#define DAN_MACHINE_ID   "/etc/machine-id"
#define DAN_UID_HEX_SIZE 32u

/* 32 hex digits (either case) into uid; 0, or -1 (not 32 hex digits, or
 * all zeros: DroneCAN's "undefined"). */
int dan_uid_parse(const char *hex, uint8_t uid[DAN_UID_SIZE]);

/* The ID derived from the machine ID file at path (DAN_MACHINE_ID): 0; or
 * 1 when there was none and the host name was used. */
int dan_uid_derive(const char *machine_id_path, uint8_t uid[DAN_UID_SIZE]);

/* The hash itself: uid from the text key (the machine ID, or "host:NAME"). */
void dan_uid_hash(const char *key, uint8_t uid[DAN_UID_SIZE]);

#endif /* DAN_GWD_NODE_UID_H */
