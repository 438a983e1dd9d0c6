/* Gateway node: servos (uavcan.equipment.actuator.ArrayCommand) with a
 * failsafe per actuator, lights (LightsCommand) and the buzzer
 * (BeepCommand). Servo positions and lights are states: latest wins on
 * CAN, as throttle does. */
#include <string.h>

#include "dan/can_gw/f16.h"
#include "gw_node_internal.h"

/* The slot of an actuator, taken if new; NULL when the table is full. The
 * table is kept in actuator ID order, so ArrayCommands list the actuators
 * in that order whatever the history. */
static dan_gw_node_servo_t *servo_slot(dan_gw_node_t *g, uint8_t id, bool take)
{
    dan_gw_node_servos_t *s = &g->servos;
    size_t i = 0, j;
    while (i < s->n && s->servo[i].last.actuator_id < id) {
        i++;
    }
    if (i < s->n && s->servo[i].last.actuator_id == id) {
        return &s->servo[i];
    }
    if (!take || s->n >= DAN_GW_NODE_SERVOS) {
        return NULL;
    }
    for (j = s->n; j > i; j--) {
        s->servo[j] = s->servo[j - 1];
    }
    memset(&s->servo[i], 0, sizeof s->servo[0]);
    s->servo[i].last.actuator_id = id;
    s->n++;
    return &s->servo[i];
}

/* One ArrayCommand: the commanded actuators group * 15 to group * 15 + 14
 * (in actuator order), what each should get now (its last command, or in
 * the failsafe its failsafe value). */
static void send_servo_group(dan_gw_node_t *g, size_t group)
{
    const dan_gw_node_servos_t *s = &g->servos;
    dan_dc_array_command_t m;
    uint8_t buf[DAN_DC_ARRAY_COMMAND_MAX_SIZE];
    size_t i, k = 0;
    m.count = 0;
    for (i = 0; i < s->n && m.count < DAN_DC_ARRAY_COMMAND_MAX; i++) {
        const dan_gw_node_servo_t *v = &s->servo[i];
        const dan_gw_servo_t *c =
            s->failsafe && v->fs_mode == DAN_GW_SERVO_VALUE ? &v->fs : &v->last;
        if (!v->commanded || k++ < group * DAN_DC_ARRAY_COMMAND_MAX) {
            continue;
        }
        m.cmd[m.count].actuator_id = v->last.actuator_id;
        m.cmd[m.count].command_type = c->command_type;
        m.cmd[m.count].value_f16 = c->value_f16;
        m.count++;
    }
    (void)dan_gwn_broadcast(g, &g->q_urgent, DAN_DC_ARRAY_COMMAND_ID,
                            DAN_DC_ARRAY_COMMAND_SIGNATURE, DAN_DC_PRIORITY_HIGH, buf,
                            dan_dc_array_command_encode(&m, buf, sizeof buf));
}

/* Sends every commanded actuator's value, 15 to an ArrayCommand; every
 * older ArrayCommand of ours still queued is dropped first (latest wins).
 * After such a drop the next message leads: requests faster than the bus
 * takes all of them otherwise starve the last ones (32 actuators at
 * 400 Hz: actuators 30 and 31 were never commanded; review finding). */
static void send_servos(dan_gw_node_t *g)
{
    dan_gw_node_servos_t *s = &g->servos;
    size_t i, ncmd = 0, groups;
    bool dropped = dan_gwn_drop_own(g, &g->q_urgent, DAN_DC_ARRAY_COMMAND_ID) > 0u;
    for (i = 0; i < s->n; i++) {
        ncmd += s->servo[i].commanded ? 1u : 0u;
    }
    if (ncmd == 0u) {
        return;
    }
    groups = (ncmd + DAN_DC_ARRAY_COMMAND_MAX - 1u) / DAN_DC_ARRAY_COMMAND_MAX;
    s->first_group = (uint8_t)((s->first_group + (dropped ? 1u : 0u)) % groups);
    for (i = 0; i < groups; i++) {
        send_servo_group(g, (s->first_group + i) % groups);
    }
}

void dan_gwn_servos_command(dan_gw_node_t *g, const dan_gw_servo_t *c, size_t n, uint64_t now_us)
{
    size_t i;
    for (i = 0; i < n; i++) {
        dan_gw_node_servo_t *v = servo_slot(g, c[i].actuator_id, true);
        if (v == NULL) {
            g->stats.servo_dropped++;
            continue;
        }
        v->last = c[i];
        v->commanded = true;
    }
    g->stats.servo_cmds++;
    g->servos.active = true;
    g->servos.failsafe = false;
    g->servos.last_cmd_us = now_us;
    send_servos(g);
}

/* Frees the slots of actuators never commanded and no longer in the
 * failsafe table (a table entry alone must not hold a slot for ever). */
static void servos_compact(dan_gw_node_servos_t *s)
{
    size_t i, k = 0;
    for (i = 0; i < s->n; i++) {
        if (s->servo[i].commanded || s->servo[i].fs_mode != DAN_GW_SERVO_HOLD) {
            s->servo[k++] = s->servo[i];
        }
    }
    s->n = (uint8_t)k;
}

size_t dan_gwn_servos_set_failsafe(dan_gw_node_t *g, const dan_gw_servo_fs_t *f, size_t n)
{
    size_t i, kept = 0;
    for (i = 0; i < g->servos.n; i++) {
        g->servos.servo[i].fs_mode = DAN_GW_SERVO_HOLD;
    }
    servos_compact(&g->servos);
    for (i = 0; i < n; i++) {
        /* HOLD is every actuator's default: it needs a slot only if the
         * actuator has one already */
        bool hold = f[i].mode == DAN_GW_SERVO_HOLD;
        dan_gw_node_servo_t *v = servo_slot(g, f[i].value.actuator_id, !hold);
        if (v != NULL) {
            v->fs_mode = f[i].mode;
            v->fs = f[i].value;
        }
        kept += (v != NULL || hold) ? 1u : 0u;
    }
    return kept;
}

void dan_gwn_servos_failsafe(dan_gw_node_t *g, uint64_t now_us)
{
    (void)now_us;
    if (g->servos.active) {
        g->servos.failsafe = true;
        send_servos(g);
    }
}

/* Servo commands stopped for esc_timeout_ms: the failsafe values go out,
 * then again with every ArmingStatus until the next SERVO. */
void dan_gwn_servos_poll(dan_gw_node_t *g, uint64_t now_us)
{
    dan_gw_node_servos_t *s = &g->servos;
    if (s->active && !s->failsafe &&
        now_us - s->last_cmd_us > (uint64_t)g->cfg.esc_timeout_ms * 1000u) {
        dan_gwn_servos_failsafe(g, now_us);
    } else if (s->failsafe && now_us >= g->arming.due_us) {
        send_servos(g);
    }
}

uint64_t dan_gwn_servos_next_us(const dan_gw_node_t *g, uint64_t t)
{
    const dan_gw_node_servos_t *s = &g->servos;
    if (s->active && !s->failsafe) {
        uint64_t fs = s->last_cmd_us + (uint64_t)g->cfg.esc_timeout_ms * 1000u + 1u;
        if (fs < t) {
            t = fs;
        }
    }
    return t;
}

void dan_gwn_lights(dan_gw_node_t *g, const dan_gw_light_t *l, size_t n)
{
    dan_dc_lights_command_t m;
    uint8_t buf[DAN_DC_LIGHTS_COMMAND_MAX_SIZE];
    size_t i;
    m.count = (uint8_t)n;
    for (i = 0; i < n; i++) {
        m.light[i].light_id = l[i].light_id;
        m.light[i].rgb565 = l[i].rgb565;
    }
    /* bulk: up to 9 frames of low priority never wait in front of throttle */
    dan_gwn_drop_own(g, &g->q_bulk, DAN_DC_LIGHTS_COMMAND_ID);
    (void)dan_gwn_broadcast(g, &g->q_bulk, DAN_DC_LIGHTS_COMMAND_ID,
                            DAN_DC_LIGHTS_COMMAND_SIGNATURE, DAN_DC_PRIORITY_LOW, buf,
                            dan_dc_lights_command_encode(&m, buf, sizeof buf));
}

void dan_gwn_beep(dan_gw_node_t *g, const dan_gw_beep_t *b)
{
    dan_dc_beep_command_t m;
    uint8_t buf[DAN_DC_BEEP_COMMAND_MAX_SIZE];
    m.frequency_f16 = dan_f16_from_f32((float)b->frequency_hz);
    m.duration_f16 = dan_f16_from_f32((float)b->duration_ms / 1000.0f);
    (void)dan_gwn_broadcast(g, &g->q_bulk, DAN_DC_BEEP_COMMAND_ID, DAN_DC_BEEP_COMMAND_SIGNATURE,
                            DAN_DC_PRIORITY_LOW, buf,
                            dan_dc_beep_command_encode(&m, buf, sizeof buf));
}
