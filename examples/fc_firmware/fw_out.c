/*
 * fc_firmware's output: one JSON object per line over semihosting, built
 * in one line buffer (fw_out.h).
 */
#include "fw_out.h"

#include "dan/dan.h"
#include "dan/identity_json.h"
#include "board.h"

char out_line[FW_OUT_LINE];
size_t out_len;

void o_str(const char *s)
{
    while (*s != '\0' && out_len < sizeof out_line - 2u) {
        out_line[out_len++] = *s++;
    }
}

void o_u64(uint64_t v)
{
    char tmp[21];
    size_t n = 0;
    do {
        tmp[n++] = (char)('0' + (int)(v % 10u));
        v /= 10u;
    } while (v != 0u);
    while (n > 0u && out_len < sizeof out_line - 2u) {
        out_line[out_len++] = tmp[--n];
    }
}

void o_u32(uint32_t v)
{
    o_u64(v);
}

void o_int(int32_t v)
{
    if (v < 0) {
        o_str("-");
        o_u64((uint64_t)(-(int64_t)v));
    } else {
        o_u64((uint64_t)v);
    }
}

void o_hex(const uint8_t *p, size_t n)
{
    static const char digits[] = "0123456789abcdef";
    size_t i;
    for (i = 0; i < n && out_len < sizeof out_line - 3u; i++) {
        out_line[out_len++] = digits[p[i] >> 4];
        out_line[out_len++] = digits[p[i] & 15u];
    }
}

/* A JSON string, escaped by libdan's one JSON formatter. */
void o_jstr(const char *s)
{
    out_len += dan_json_str(out_line + out_len, sizeof out_line - 1u - out_len, s);
}

/* ,"key": */
void o_key(const char *k)
{
    o_str(",\"");
    o_str(k);
    o_str("\":");
}

void o_key_num(const char *k, uint64_t v)
{
    o_key(k);
    o_u64(v);
}

void o_key_jstr(const char *k, const char *s)
{
    o_key(k);
    o_jstr(s);
}

void o_begin(const char *step)
{
    out_len = 0;
    o_str("{\"step\":");
    o_jstr(step);
}

void o_end(void)
{
    out_line[out_len++] = '}';
    out_line[out_len++] = '\n';
    out_line[out_len < sizeof out_line ? out_len : sizeof out_line - 1u] = '\0';
    sh_puts(out_line);
    out_len = 0;
}

void o_result(int r)
{
    o_key("result");
    o_int(r);
    o_key("error");
    o_jstr(r == DAN_OK ? "" : dan_strerror(r));
}
