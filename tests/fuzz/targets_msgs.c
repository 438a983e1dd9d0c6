/* Fuzz target of the gateway's message codecs (dan/can_gw/msgs*.h), both
 * directions (see targets.h). The gw_handlers target reaches the request
 * decoders and response encoders through the node, gw_client the response
 * decoders; this one also runs the encoders a client uses: whatever
 * decodes re-encodes, and that encoding is a fixed point (it decodes, and
 * encodes again to the same bytes). Built into every libFuzzer binary and
 * #included by tests/unit/test_fuzz_regressions.c. */
#include <string.h>

#include "dan/dan.h"
#include "dan/can_gw/msgs.h"
#include "dan/can_gw/msgs_fast.h"
#include "dan/can_gw/msgs_file.h"
#include "dan/can_gw/msgs_mgmt.h"
#include "dan/can_gw/msgs_out.h"
#include "targets.h"

static uint8_t fzm_e1[DAN_MAX_PAYLOAD + 64u], fzm_e2[DAN_MAX_PAYLOAD + 64u];

/* e1 (r1 bytes) and e2 (r2) are one encoding. */
static void fzm_same(int r1, int r2)
{
    FUZZ_CHECK(r1 >= 0 && r1 == r2 && !memcmp(fzm_e1, fzm_e2, (size_t)r1));
}

/* A struct message: decode p, encode, decode that, encode again. */
#define FZM_STRUCT(T, name)                                                             \
    do {                                                                                \
        static T a_, b_;                                                                \
        memset(&a_, 0, sizeof a_);                                                      \
        memset(&b_, 0, sizeof b_);                                                      \
        if (dan_gw_msg_##name##_decode(&a_, p, n) == DAN_OK) {                          \
            int r1_ = dan_gw_msg_##name##_encode(&a_, fzm_e1, sizeof fzm_e1);           \
            FUZZ_CHECK(r1_ >= 0);                                                       \
            FUZZ_CHECK(dan_gw_msg_##name##_decode(&b_, fzm_e1, (size_t)r1_) == DAN_OK); \
            fzm_same(r1_, dan_gw_msg_##name##_encode(&b_, fzm_e2, sizeof fzm_e2));      \
        }                                                                               \
    } while (0)

/* A message of n items into an array: decode(items, &count, p, len). */
#define FZM_ARRAY(T, name, max)                                                              \
    do {                                                                                     \
        static T a_[max], b_[max];                                                           \
        size_t na_ = 0, nb_ = 0;                                                             \
        if (dan_gw_msg_##name##_decode(a_, &na_, p, n) == DAN_OK) {                          \
            int r1_ = dan_gw_msg_##name##_encode(a_, na_, fzm_e1, sizeof fzm_e1);            \
            FUZZ_CHECK(na_ <= (max) && r1_ >= 0);                                            \
            FUZZ_CHECK(dan_gw_msg_##name##_decode(b_, &nb_, fzm_e1, (size_t)r1_) == DAN_OK); \
            FUZZ_CHECK(na_ == nb_);                                                          \
            fzm_same(r1_, dan_gw_msg_##name##_encode(b_, nb_, fzm_e2, sizeof fzm_e2));       \
        }                                                                                    \
    } while (0)

/* ESC values: ESC_CMD (count first) and ESC_FAST (the stream alone). */
static void fzm_esc(bool fast, const uint8_t *p, size_t n)
{
    int16_t a[DAN_GW_ESC_MAX], b[DAN_GW_ESC_MAX];
    size_t na = 0, nb = 0;
    int r1;
    if ((fast ? dan_gw_msg_esc_fast_decode(p, n, a, &na)
              : dan_gw_msg_esc_cmd_decode(p, n, a, &na)) != DAN_OK) {
        return;
    }
    FUZZ_CHECK(na >= 1u && na <= DAN_GW_ESC_MAX);
    r1 = fast ? dan_gw_msg_esc_fast_encode(a, na, fzm_e1, sizeof fzm_e1)
              : dan_gw_msg_esc_cmd_encode(a, na, fzm_e1, sizeof fzm_e1);
    FUZZ_CHECK(r1 >= 0);
    FUZZ_CHECK((fast ? dan_gw_msg_esc_fast_decode(fzm_e1, (size_t)r1, b, &nb)
                     : dan_gw_msg_esc_cmd_decode(fzm_e1, (size_t)r1, b, &nb)) == DAN_OK);
    FUZZ_CHECK(na == nb && !memcmp(a, b, na * sizeof a[0]));
}

static void fzm_stats(const uint8_t *p, size_t n)
{
    uint32_t a[DAN_GW_STAT_COUNT], b[DAN_GW_STAT_COUNT];
    size_t na = 0, nb = 0;
    int r1;
    if (dan_gw_msg_stats_decode(a, DAN_GW_STAT_COUNT, &na, p, n) != DAN_OK) {
        return;
    }
    if (na > DAN_GW_STAT_COUNT) {
        na = DAN_GW_STAT_COUNT; /* a newer gateway's counters: skipped */
    }
    r1 = dan_gw_msg_stats_encode(a, na, fzm_e1, sizeof fzm_e1);
    FUZZ_CHECK(r1 >= 0);
    FUZZ_CHECK(dan_gw_msg_stats_decode(b, DAN_GW_STAT_COUNT, &nb, fzm_e1, (size_t)r1) == DAN_OK);
    FUZZ_CHECK(na == nb && !memcmp(a, b, na * sizeof a[0]));
}

static void fzm_fast_rsp(const uint8_t *p, size_t n)
{
    static dan_gw_fast_rec_t a, b;
    uint8_t fa = 0, fb = 0;
    bool ha = false, hb = false;
    int r1;
    memset(&a, 0, sizeof a);
    memset(&b, 0, sizeof b);
    if (dan_gw_msg_esc_fast_rsp_decode(&fa, &a, &ha, p, n) != DAN_OK) {
        return;
    }
    r1 = dan_gw_msg_esc_fast_rsp_encode(fa, ha ? &a : NULL, fzm_e1, sizeof fzm_e1);
    FUZZ_CHECK(r1 >= 0);
    FUZZ_CHECK(dan_gw_msg_esc_fast_rsp_decode(&fb, &b, &hb, fzm_e1, (size_t)r1) == DAN_OK);
    FUZZ_CHECK(fa == fb && ha == hb);
    fzm_same(r1, dan_gw_msg_esc_fast_rsp_encode(fb, hb ? &b : NULL, fzm_e2, sizeof fzm_e2));
}

static void fzm_file_name(const uint8_t *p, size_t n)
{
    const char *a = NULL, *b = NULL;
    uint8_t la = 0, lb = 0;
    int r1;
    if (dan_gw_msg_file_name_decode(&a, &la, p, n) != DAN_OK) {
        return;
    }
    FUZZ_CHECK(la >= 1u && la <= DAN_GW_FILE_NAME_MAX && a >= (const char *)p &&
               a + la <= (const char *)p + n);
    r1 = dan_gw_msg_file_name_encode(a, la, fzm_e1, sizeof fzm_e1);
    FUZZ_CHECK(r1 >= 0);
    FUZZ_CHECK(dan_gw_msg_file_name_decode(&b, &lb, fzm_e1, (size_t)r1) == DAN_OK);
    FUZZ_CHECK(la == lb && !memcmp(a, b, la));
}

/* Messages 0..15. */
static void fzm_first(unsigned k, const uint8_t *p, size_t n)
{
    switch (k) {
    case 0: fzm_esc(false, p, n); break;
    case 1: fzm_esc(true, p, n); break;
    case 2: FZM_STRUCT(dan_gw_config_t, config_req); break;
    case 3: FZM_STRUCT(dan_gw_config_t, config_rsp); break;
    case 4: fzm_stats(p, n); break;
    case 5: FZM_STRUCT(dan_gw_node_info_t, node_info); break;
    case 6: FZM_STRUCT(dan_gw_tun_open_t, tun_open); break;
    case 7: FZM_STRUCT(dan_gw_tun_xfer_t, tun_xfer_req); break;
    case 8: FZM_STRUCT(dan_gw_tun_xfer_t, tun_xfer_rsp); break;
    case 9: FZM_STRUCT(dan_gw_can_send_t, can_send_rsp); break;
    case 10: FZM_STRUCT(dan_gw_can_recv_t, can_recv_req); break;
    case 11: fzm_fast_rsp(p, n); break;
    case 12: FZM_STRUCT(dan_gw_file_open_t, file_open); break;
    case 13: FZM_STRUCT(dan_gw_file_have_t, file_have); break;
    case 14: FZM_STRUCT(dan_gw_file_write_t, file_write); break;
    default: FZM_STRUCT(dan_gw_file_commit_t, file_commit_req); break;
    }
}

/* Messages 16..31. */
static void fzm_second(unsigned k, const uint8_t *p, size_t n)
{
    switch (k) {
    case 16: FZM_STRUCT(dan_gw_file_commit_t, file_commit_rsp); break;
    case 17: fzm_file_name(p, n); break;
    case 18: FZM_STRUCT(dan_gw_fw_result_t, fw_result); break;
    case 19: FZM_STRUCT(dan_gw_call_t, call); break;
    case 20: FZM_STRUCT(dan_gw_call_state_t, call_state); break;
    case 21: FZM_STRUCT(dan_gw_result_t, result_req); break;
    case 22: FZM_STRUCT(dan_gw_result_t, result_rsp); break;
    case 23: FZM_STRUCT(dan_gw_param_t, param); break;
    case 24: FZM_STRUCT(dan_gw_opcode_result_t, opcode_result); break;
    case 25: FZM_STRUCT(dan_gw_health_t, health); break;
    case 26: FZM_ARRAY(dan_gw_servo_t, servo, DAN_GW_SERVO_MAX); break;
    case 27: FZM_ARRAY(dan_gw_servo_fs_t, servo_fs, DAN_GW_SERVO_MAX); break;
    case 28: FZM_ARRAY(dan_gw_light_t, lights, DAN_GW_LIGHTS_MAX); break;
    default: FZM_STRUCT(dan_gw_beep_t, beep); break;
    }
}

/* data[0] % 30 picks the message (fzm_first, fzm_second); the rest is its
 * payload (inner: no seal). */
int dan_fuzz_gw_msgs(const uint8_t *data, size_t len)
{
    unsigned k;
    if (len < 1u) {
        return 0;
    }
    k = data[0] % 30u;
    if (k < 16u) {
        fzm_first(k, data + 1, len - 1u);
    } else {
        fzm_second(k, data + 1, len - 1u);
    }
    return 0;
}
