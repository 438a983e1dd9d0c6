/* dan_esc_map: ArduPilot's ESC output rules, one table row per case. The
 * expected values are worked by hand from AP_DroneCAN's formulas (seed 000,
 * "ESC Scaling and Reversible Support"; scale_esc_to_unity):
 *   forward    8191 * (pwm - 1000) / 1000, clamped 0..8191
 *   reversible 8191 * (2 * pwm - 3000) / 1000, clamped -8191..8191
 * truncated toward zero. */
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
#include <string.h>
#include <cmocka.h>

#include "dan/can_gw/esc_map.h"
#include "dan/common.h"
#include "unit_run.h"

#define NOUT 32

typedef struct {
    const char *what;
    uint32_t esc_mask, rev_mask, armed_mask;
    uint8_t offset;
    uint16_t pwm_min, pwm_max; /* 0: defaults */
    int armed;
    size_t n_out;
    uint16_t pwm[8]; /* outputs offset..offset+7; 0 and the rest: 1500 */
    int count;       /* or an error code */
    int16_t want[20];
} map_case_t;

/* One case per row: what, esc_mask, rev_mask, armed_mask, offset, pwm_min,
 * pwm_max, armed, n_out, pwm[], count, want[]. */
/* clang-format off */
static const map_case_t cases[] = {
    {"forward scale", 0x0Fu, 0, ~0u, 0, 0, 0, 1, NOUT, {1000, 1500, 2000, 1100}, 4, {0, 4095, 8191, 819}},
    {"forward clamps", 0x0Fu, 0, ~0u, 0, 0, 0, 1, NOUT, {900, 2100, 1001, 1999}, 4, {0, 8191, 8, 8182}},
    {"disarmed sends zeros", 0x0Fu, 0, ~0u, 0, 0, 0, 0, NOUT, {2000, 2000, 2000, 2000}, 4, {0, 0, 0, 0}},
    {"armed mask", 0x0Fu, 0, 0x05u, 0, 0, 0, 1, NOUT, {2000, 2000, 2000, 2000}, 4, {8191, 0, 8191, 0}},
    {"gaps in the ESC mask", 0x09u, 0, ~0u, 0, 0, 0, 1, NOUT, {2000, 2000, 2000, 2000}, 4, {8191, 0, 0, 8191}},
    {"offset packs outputs 5..8", 0xF0u, 0, ~0u, 4, 0, 0, 1, NOUT, {1000, 1250, 1750, 2000}, 4, {0, 2047, 6143, 8191}},
    {"reversible", 0x3Fu, 0x3Fu, ~0u, 0, 0, 0, 1, NOUT, {1500, 2000, 1000, 1250, 1750, 1499}, 6, {0, 8191, -8191, -4095, 4095, -16}},
    {"reversible clamps", 0x03u, 0x03u, ~0u, 0, 0, 0, 1, NOUT, {800, 2300}, 2, {-8191, 8191}},
    {"mixed directions", 0x03u, 0x02u, ~0u, 0, 0, 0, 1, NOUT, {1250, 1250}, 2, {2047, -4095}},
    {"reversible disarmed is zero, not -8191", 0x01u, 0x01u, ~0u, 0, 0, 0, 0, NOUT, {1000}, 1, {0}},
    {"custom PWM range", 0x07u, 0x04u, ~0u, 0, 1100, 1900, 1, NOUT, {1900, 1500, 1100}, 3, {8191, 4095, -8191}},
    {"twenty slots at most", 0xFFFFFFFFu, 0, ~0u, 0, 0, 0, 1, NOUT, {2000}, 20, {8191, 4095, 4095, 4095, 4095, 4095, 4095, 4095, 4095, 4095, 4095, 4095, 4095, 4095, 4095, 4095, 4095, 4095, 4095, 4095}},
    {"top output 32 with offset 18", 0x80000000u, 0, ~0u, 18, 0, 0, 1, NOUT, {2000}, 14, {0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 4095}},
    {"ESCs only below the offset", 0x0Fu, 0, ~0u, 4, 0, 0, 1, NOUT, {2000}, 0, {0}},
    {"no ESCs", 0u, 0, ~0u, 0, 0, 0, 1, NOUT, {2000}, 0, {0}},
    {"outputs the FC does not have", 0x0Fu, 0, ~0u, 0, 0, 0, 1, 2, {2000, 2000, 2000, 2000}, 4, {8191, 8191, 0, 0}},
    {"offset above 18", 0x0Fu, 0, ~0u, 19, 0, 0, 1, NOUT, {0}, DAN_ERR_ARG, {0}},
    {"empty PWM range", 0x0Fu, 0, ~0u, 0, 1500, 1500, 1, NOUT, {0}, DAN_ERR_ARG, {0}},
};
/* clang-format on */

static void run_case(const map_case_t *c)
{
    dan_esc_map_t m;
    uint16_t pwm[NOUT];
    int16_t values[20];
    size_t i;
    int n;
    dan_esc_map_init(&m);
    m.esc_mask = c->esc_mask;
    m.reversible_mask = c->rev_mask;
    m.offset = c->offset;
    if (c->pwm_max != 0u) {
        m.pwm_min = c->pwm_min;
        m.pwm_max = c->pwm_max;
    }
    for (i = 0; i < NOUT; i++) {
        pwm[i] = 1500;
    }
    for (i = 0; i < 8 && c->offset + i < NOUT; i++) {
        if (c->pwm[i] != 0u) {
            pwm[c->offset + i] = c->pwm[i];
        }
    }
    memset(values, 0x55, sizeof values);
    n = dan_esc_map(&m, pwm, c->n_out, c->armed != 0, c->armed_mask, values, 20);
    print_message("case: %s\n", c->what);
    assert_int_equal(n, c->count);
    for (i = 0; n > 0 && i < (size_t)n; i++) {
        assert_int_equal(values[i], c->want[i]);
    }
}

static void test_table(void **state)
{
    size_t i;
    (void)state;
    for (i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        run_case(&cases[i]);
    }
}

static void test_cap_and_null(void **state)
{
    dan_esc_map_t m;
    uint16_t pwm[4] = {2000, 2000, 2000, 2000};
    int16_t values[4];
    (void)state;
    dan_esc_map_init(&m);
    m.esc_mask = 0x0Fu;
    assert_int_equal(dan_esc_map(&m, pwm, 4, true, ~0u, values, 3), DAN_ERR_OVERFLOW);
    assert_int_equal(dan_esc_map(&m, NULL, 4, true, ~0u, values, 4), DAN_ERR_ARG);
    assert_int_equal(dan_esc_map(NULL, pwm, 4, true, ~0u, values, 4), DAN_ERR_ARG);
    /* no outputs at all: the ESCs still hear zeros */
    assert_int_equal(dan_esc_map(&m, NULL, 0, true, ~0u, values, 4), 4);
    assert_int_equal(values[0], 0);
    assert_int_equal(values[3], 0);
}

int main(void)
{
    return UNIT_RUN("esc_map", NULL, NULL, test_table, test_cap_and_null);
}
