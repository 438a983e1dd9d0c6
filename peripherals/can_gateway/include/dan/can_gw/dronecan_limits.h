/*
 * DroneCAN facts that the gateway's DAN messages mirror, defined once for
 * both sides (the FC's message codec and the node's DSDL codecs). Source:
 * the DSDL definitions shipped with pydronecan (dronecan/dsdl_specs):
 * uavcan/equipment/esc/1030.RawCommand (int14[<=20] cmd),
 * uavcan/equipment/esc/1034.Status (uint5 esc_index),
 * uavcan/protocol/1.GetNodeInfo (uint8[<=80] name).
 */
#ifndef DAN_CAN_GW_DRONECAN_LIMITS_H
#define DAN_CAN_GW_DRONECAN_LIMITS_H

#define DAN_DC_NODE_ID_MAX              127u    /* node IDs 1..127 */
#define DAN_DC_ESC_RAW_COMMAND_MAX_CMDS 20u     /* RawCommand.cmd entries */
#define DAN_DC_ESC_RAW_CMD_MIN          (-8192) /* int14 */
#define DAN_DC_ESC_RAW_CMD_MAX          8191
#define DAN_DC_ESC_INDEX_MAX            31u /* esc.Status.esc_index: uint5 */
#define DAN_DC_GET_NODE_INFO_NAME_MAX   80u /* GetNodeInfo.name bytes */
#define DAN_DC_UNIQUE_ID_SIZE           16u /* HardwareVersion.unique_id bytes */

#endif /* DAN_CAN_GW_DRONECAN_LIMITS_H */
