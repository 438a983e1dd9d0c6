/* FC side: ArduPilot's ESC output rules (see esc_map.h). */
#include "dan/can_gw/esc_map.h"

#include "dan/can_gw/dronecan_limits.h"
#include "dan/common.h"

void dan_esc_map_init(dan_esc_map_t *m)
{
    m->esc_mask = 0u;
    m->reversible_mask = 0u;
    m->offset = 0u;
    m->pwm_min = DAN_ESC_MAP_PWM_MIN;
    m->pwm_max = DAN_ESC_MAP_PWM_MAX;
}

static int32_t clamp32(int32_t v, int32_t lo, int32_t hi)
{
    return v < lo ? lo : (v > hi ? hi : v);
}

/* One output's value when it may spin. */
static int16_t scale(const dan_esc_map_t *m, uint16_t pwm, bool reversible)
{
    const int32_t span = (int32_t)m->pwm_max - (int32_t)m->pwm_min;
    const int32_t top = DAN_DC_ESC_RAW_CMD_MAX;
    int32_t v;
    if (reversible) {
        /* twice the distance from the centre over the span: no half-units */
        v = top * (2 * (int32_t)pwm - (int32_t)m->pwm_min - (int32_t)m->pwm_max) / span;
        return (int16_t)clamp32(v, -top, top);
    }
    v = top * ((int32_t)pwm - (int32_t)m->pwm_min) / span;
    return (int16_t)clamp32(v, 0, top);
}

/* Outputs up to the highest one in esc_mask. */
static unsigned mask_top(uint32_t mask)
{
    unsigned n = 0u;
    while (mask != 0u) {
        mask >>= 1;
        n++;
    }
    return n;
}

int dan_esc_map(const dan_esc_map_t *m, const uint16_t *pwm, size_t n_out, bool armed,
                uint32_t armed_mask, int16_t *values, size_t cap)
{
    unsigned top, k, count;
    if (m == NULL || (values == NULL && cap > 0u) || (pwm == NULL && n_out > 0u) ||
        m->offset > DAN_ESC_MAP_OFFSET_MAX || m->pwm_max <= m->pwm_min + 1u) {
        return DAN_ERR_ARG;
    }
    top = mask_top(m->esc_mask);
    count = top > m->offset ? top - m->offset : 0u;
    if (count > DAN_DC_ESC_RAW_COMMAND_MAX_CMDS) {
        count = DAN_DC_ESC_RAW_COMMAND_MAX_CMDS;
    }
    if (count > cap) {
        return DAN_ERR_OVERFLOW;
    }
    for (k = 0u; k < count; k++) {
        const unsigned i = m->offset + k;
        const uint32_t bit = (uint32_t)1u << i;
        values[k] = 0;
        if (armed && (m->esc_mask & armed_mask & bit) != 0u && i < n_out) {
            values[k] = scale(m, pwm[i], (m->reversible_mask & bit) != 0u);
        }
    }
    return (int)count;
}
