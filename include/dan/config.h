/*
 * Every compile-time setting of libdan and of the peripheral types, in one
 * place (as nanopb's pb.h and libcanard's canard.h do).
 *
 * Change a setting with -D on the compiler command line, or put the
 * settings of a project in one header and name it with
 * -DDAN_USER_CONFIG='"my_dan_config.h"': it is included first, so every
 * #define there wins. Each setting says its unit and what it costs; derived
 * maxima are computed from them, so buffers are sized statically and
 * nothing ever allocates.
 *
 * Fixed protocol constants (the draft's bauds, DroneCAN's timeouts, DSDL
 * limits) are not settings: they live beside the code that implements them.
 */
#ifndef DAN_CONFIG_H
#define DAN_CONFIG_H

#ifdef DAN_USER_CONFIG
#include DAN_USER_CONFIG
#endif

/* ==== libdan core: frames and payloads ==== */

/* Largest payload a frame may carry, bytes (64..16383). A decoder rejects
 * (counted "oversize") a frame declaring a longer one; encoders refuse to
 * build one. 160 fits a 120-byte tunnel chunk plus its header, or twelve
 * raw CAN frames. RAM: ~2 x this per master (decoder, TX frame; the last
 * response is kept in the TX frame) and 3 x per peripheral engine. */
#ifndef DAN_MAX_PAYLOAD
#define DAN_MAX_PAYLOAD 160u
#endif

/* Longest string kept by the common payload decoders (identity fields,
 * error text), bytes including the NUL (2..255). Longer strings on the wire
 * are accepted and truncated (flagged). RAM: 4 x this per dan_identity_t
 * (the caller's, dan_master_set_identities(); the master keeps none). */
#ifndef DAN_MAX_STRING
#define DAN_MAX_STRING 32u
#endif

/* The crc8 (every received byte) by a 256-byte table (1: about 6 x86
 * instructions a byte, the parser's 17 instr/B in `make bench`) or a
 * 16-byte nibble table (0: ~240 bytes less flash, about 10 instructions a
 * byte more). `make size` reports both. */
#ifndef DAN_CRC8_TABLE
#define DAN_CRC8_TABLE 1
#endif

/* ==== bus engines: timing defaults (docs/PROTOCOL.md section 6) ====
 * Each is only a default: the engines' config structs change them at run
 * time. No RAM cost. */

/* Idle character times before talking (listen before talk; >= 2). */
#ifndef DAN_LBT_CHARS
#define DAN_LBT_CHARS 3u
#endif
/* Idle character times that end a partial frame (the inter-byte gap) ... */
#ifndef DAN_GAP_CHARS
#define DAN_GAP_CHARS 10u
#endif
/* ... but never shorter than this, microseconds. */
#ifndef DAN_GAP_MIN_US
#define DAN_GAP_MIN_US 2000u
#endif
/* Character times a peripheral waits after a request before replying. */
#ifndef DAN_TURNAROUND_CHARS
#define DAN_TURNAROUND_CHARS 2u
#endif
/* A reply must start this soon after the turnaround, microseconds (the
 * master's response deadline, the peripheral's reply window). */
#ifndef DAN_RESP_LATENCY_US
#define DAN_RESP_LATENCY_US 10000u
#endif
/* How long after an echo timeout or a collision a copy of our own frame
 * is taken for our own late echo, microseconds. */
#ifndef DAN_ECHO_LATE_HOLD_US
#define DAN_ECHO_LATE_HOLD_US 1000000u
#endif

/* ==== master engine ==== */

/* Peripheral types one master probes (= peers per UART), 1..8. RAM: one
 * dan_peer_t each and its configure state (16 bytes). */
#ifndef DAN_MASTER_MAX_TYPES
#define DAN_MASTER_MAX_TYPES 4u
#endif

/* ==== receive ring for interrupt-fed bytes (dan/rxring.h) ==== */

/* Ring size, bytes: a power of two, 2..32768. RAM: this per ring. It must
 * hold the bytes that arrive between two main-loop passes (115200 baud:
 * 11.5 bytes/ms). */
#ifndef DAN_RXRING_SIZE
#define DAN_RXRING_SIZE 256u
#endif
/* Type of the free-running indices: read and written by the CPU in one
 * access (uint32_t on 32-bit MCUs; on 8/16-bit MCUs use uint8_t with a
 * size <= 128, or mask interrupts around the consumer's reads instead). */
#ifndef DAN_RXRING_INDEX_T
#define DAN_RXRING_INDEX_T uint32_t
#endif
/* DAN_RXRING_BARRIER(): the memory barrier between storing a byte and
 * publishing it; its default per compiler is in dan/rxring.h. */

/* ==== CAN gateway type, FC side: the client (dan/can_gw/client.h) ==== */

/* Telemetry slots the client keeps (ESC indexes 0..DAN_GW_MAX_ESC-1;
 * records of higher indexes are counted in telem_ignored). 4: a quad;
 * raise it for more motors. RAM: 44 bytes each in dan_gw_t (Cortex-M4;
 * `make size` states it). */
#ifndef DAN_GW_MAX_ESC
#define DAN_GW_MAX_ESC 4u
#endif
/* Tunnel ports the client tracks (port numbers 0..DAN_GW_TUNNELS-1). RAM:
 * 24 bytes each in dan_gw_t. */
#ifndef DAN_GW_TUNNELS
#define DAN_GW_TUNNELS 2u
#endif
/* A CAN_RECV sequence this far ahead of (or behind) the client's means the
 * gateway restarted: the client follows it instead of counting losses.
 * Frames; no RAM cost. */
#ifndef DAN_GW_CAN_RESYNC
#define DAN_GW_CAN_RESYNC 4096u
#endif

/* ==== CAN gateway type, node side (dan/can_gw/node.h) ==== */

/* Node table entries. RAM: ~130 bytes each (the GetNodeInfo data). */
#ifndef DAN_GW_NODE_MAX_NODES
#define DAN_GW_NODE_MAX_NODES 32u
#endif
/* Tunnel ports. RAM: TUN_TX_BUF + TUN_RX_BUF + 40 bytes each. */
#ifndef DAN_GW_NODE_TUNNELS
#define DAN_GW_NODE_TUNNELS 4u
#endif
/* DAN -> CAN tunnel bytes buffered per port (a power of two). */
#ifndef DAN_GW_NODE_TUN_TX_BUF
#define DAN_GW_NODE_TUN_TX_BUF 1024u
#endif
/* CAN -> DAN tunnel bytes buffered per port (a power of two). */
#ifndef DAN_GW_NODE_TUN_RX_BUF
#define DAN_GW_NODE_TUN_RX_BUF 4096u
#endif
/* Frames per CAN output queue (two queues). RAM: 16 bytes a frame. At
 * least 19: one whole Targetted tunnel transfer. */
#ifndef DAN_GW_NODE_TXQ
#define DAN_GW_NODE_TXQ 128u
#endif
/* Raw frames waiting for CAN_RECV. RAM: 16 bytes each. */
#ifndef DAN_GW_NODE_RAW_RX
#define DAN_GW_NODE_RAW_RX 64u
#endif

/* Dynamic node ID allocation table entries. RAM: 17 bytes each, and the
 * same again on the stack while the table is stored. 1..125. */
#ifndef DAN_GW_NODE_DNA_MAX
#define DAN_GW_NODE_DNA_MAX 64u
#endif
/* Servo actuators the node remembers (their last command and failsafe).
 * RAM: 10 bytes each. */
#ifndef DAN_GW_NODE_SERVOS
#define DAN_GW_NODE_SERVOS 32u
#endif
/* DroneCAN service calls (parameters, restart) in flight or holding a
 * result at once. RAM: ~620 bytes each (the request and the result). */
#ifndef DAN_GW_NODE_CALLS
#define DAN_GW_NODE_CALLS 8u
#endif
/* File requests (file.Read, GetInfo) waiting for room in the bulk CAN
 * queue: a Read's answer is 38 frames, so the queue holds three, and
 * ArduPilot's CAN bootloader keeps four reads in flight per node. RAM:
 * ~56 bytes each. 1..64. */
#ifndef DAN_GW_NODE_FILE_WAIT
#define DAN_GW_NODE_FILE_WAIT 8u
#endif

/* DroneCAN reception (dan/can_gw/dronecan.h): concurrent multi-frame RX
 * sessions, one per (data type, transfer type, source node); a slot stays
 * in use for the transfer timeout after its transfer completes (duplicate
 * detection; a multi-frame start may take such a slot, never one with a
 * transfer in progress). 20 ESCs sending esc.Status and StatusExtended
 * need 40, plus GetNodeInfo and tunnels: 64. RAM: DAN_DC_MAX_TRANSFER + ~24 bytes each
 * (25 KiB by default on a Linux gateway; an MCU gateway with fewer ESCs
 * lowers it). 1..255. */
#ifndef DAN_DC_RX_SESSIONS
#define DAN_DC_RX_SESSIONS 64u
#endif
/* Largest transfer payload received, bytes, excluding the transfer CRC.
 * 384 fits the largest uavcan.protocol.GetNodeInfo response (376 bytes: an
 * 80-char name and a 255-byte certificate) and tunnel.Targetted (126). */
#ifndef DAN_DC_MAX_TRANSFER
#define DAN_DC_MAX_TRANSFER 384u
#endif
/* Distinct TX flows whose transfer IDs are tracked. RAM: 4 bytes each. */
#ifndef DAN_DC_TX_TIDS
#define DAN_DC_TX_TIDS 16u
#endif

/* ==== checks and derived values ==== */

#if DAN_MAX_PAYLOAD < 64u || DAN_MAX_PAYLOAD > 16383u
#error "DAN_MAX_PAYLOAD must be within 64..16383"
#endif
#if DAN_MASTER_MAX_TYPES < 1u || DAN_MASTER_MAX_TYPES > 8u
#error "DAN_MASTER_MAX_TYPES must be within 1..8 (a bitmask of peers)"
#endif
#if DAN_MAX_STRING < 2u || DAN_MAX_STRING > 255u
#error "DAN_MAX_STRING must be within 2..255"
#endif
#if DAN_RXRING_SIZE < 2u || DAN_RXRING_SIZE > 32768u || \
    (DAN_RXRING_SIZE & (DAN_RXRING_SIZE - 1u)) != 0u
#error "DAN_RXRING_SIZE must be a power of two within 2..32768"
#endif
#if (DAN_GW_NODE_TUN_TX_BUF & (DAN_GW_NODE_TUN_TX_BUF - 1u)) != 0u || \
    (DAN_GW_NODE_TUN_RX_BUF & (DAN_GW_NODE_TUN_RX_BUF - 1u)) != 0u
#error "tunnel buffer sizes must be powers of two (offsets wrap at 2^32)"
#endif
#if DAN_GW_NODE_TXQ < 19u
#error "DAN_GW_NODE_TXQ must hold one Targetted tunnel transfer (19 frames)"
#endif
#if DAN_GW_NODE_DNA_MAX < 1u || DAN_GW_NODE_DNA_MAX > 125u
#error "DAN_GW_NODE_DNA_MAX must be within 1..125"
#endif
#if DAN_GW_NODE_CALLS < 1u || DAN_GW_NODE_CALLS > 64u
#error "DAN_GW_NODE_CALLS must be within 1..64"
#endif
#if DAN_GW_NODE_FILE_WAIT < 1u || DAN_GW_NODE_FILE_WAIT > 64u
#error "DAN_GW_NODE_FILE_WAIT must be within 1..64"
#endif
#if DAN_DC_RX_SESSIONS < 1u || DAN_DC_RX_SESSIONS > 255u
#error "DAN_DC_RX_SESSIONS must be within 1..255"
#endif

/* Bytes a uvarint needs for a constant (for static sizing). */
#define DAN_UVARINT_SIZE(v) \
    ((v) < 0x80u ? 1u : (v) < 0x4000u ? 2u : (v) < 0x200000u ? 3u : (v) < 0x10000000u ? 4u : 5u)

/* Longest uvarint accepted on the wire: 32-bit values. */
#define DAN_UVARINT_MAX_BYTES 5u

/* Largest frame on the wire: sync, code (up to 5 bytes), length, payload, CRC. */
#define DAN_MAX_FRAME \
    (1u + DAN_UVARINT_MAX_BYTES + DAN_UVARINT_SIZE(DAN_MAX_PAYLOAD) + DAN_MAX_PAYLOAD + 1u)

#endif /* DAN_CONFIG_H */
