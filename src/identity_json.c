/* A discovered peer as a JSON object in a caller's buffer (see
 * dan/identity_json.h): one formatter for the firmware and the tools. */
#include "dan/identity_json.h"
#include "dan/types.h"

/* Bytes go into out[0..cap-1) and out stays NUL-terminated; a piece that
 * does not fit whole is dropped, so the text never ends in half an escape. */
typedef struct {
    char *out;
    size_t cap, len;
} jbuf_t;

static void put(jbuf_t *b, const char *s, size_t n)
{
    size_t i;
    if (b->len + n >= b->cap) {
        return;
    }
    for (i = 0; i < n; i++) {
        b->out[b->len++] = s[i];
    }
    b->out[b->len] = '\0';
}

static void put_str(jbuf_t *b, const char *s)
{
    size_t n = 0;
    while (s[n] != '\0') {
        n++;
    }
    put(b, s, n);
}

static void put_u32(jbuf_t *b, uint32_t v)
{
    char digits[10]; /* UINT32_MAX has 10 */
    size_t n = sizeof digits;
    do {
        digits[--n] = (char)('0' + (int)(v % 10u));
        v /= 10u;
    } while (v != 0u);
    put(b, digits + n, sizeof digits - n);
}

static void put_jstr(jbuf_t *b, const char *s)
{
    static const char hex[] = "0123456789abcdef";
    put(b, "\"", 1);
    for (; *s != '\0'; s++) {
        unsigned char ch = (unsigned char)*s;
        if (ch == '"' || ch == '\\') {
            char esc[2] = {'\\', (char)ch};
            put(b, esc, 2);
        } else if (ch < 0x20u || ch >= 0x7Fu) {
            char esc[6] = {'\\', 'u', '0', '0', hex[ch >> 4], hex[ch & 15u]};
            put(b, esc, 6);
        } else {
            put(b, (const char *)&ch, 1);
        }
    }
    put(b, "\"", 1);
}

/* ,"key": */
static void put_key(jbuf_t *b, const char *key)
{
    put(b, ",\"", 2);
    put_str(b, key);
    put(b, "\":", 2);
}

/* A member: ,"key":v and ,"key":"s" */
static void put_num(jbuf_t *b, const char *key, uint32_t v)
{
    put_key(b, key);
    put_u32(b, v);
}

static void put_text(jbuf_t *b, const char *key, const char *s)
{
    put_key(b, key);
    put_jstr(b, s);
}

static jbuf_t jbuf(char *out, size_t cap)
{
    jbuf_t b;
    b.out = out;
    b.cap = cap;
    b.len = 0;
    if (cap > 0u) {
        out[0] = '\0';
    }
    return b;
}

size_t dan_json_str(char *out, size_t cap, const char *s)
{
    jbuf_t b = jbuf(out, cap);
    put_jstr(&b, s);
    return b.len;
}

size_t dan_peer_json(char *out, size_t cap, const dan_peer_t *p, const dan_identity_t *id,
                     unsigned flags)
{
    const dan_type_info_t *t = dan_type_of_code(p->first_code);
    bool full = (flags & DAN_PEER_JSON_FULL) != 0u;
    jbuf_t b = jbuf(out, cap);
    put_str(&b, "{\"type\":");
    put_jstr(&b, (t != NULL) ? t->name : "?");
    if (full) {
        put_num(&b, "first_code", p->first_code);
    }
    put_num(&b, "baud", p->baud);
    put_num(&b, "dan_version", id->dan_version);
    put_text(&b, "manufacturer", id->manufacturer);
    put_text(&b, "model", id->model);
    if (full) {
        put_text(&b, "hw_version", id->hw_version);
    }
    put_text(&b, "sw_version", id->sw_version);
    put_num(&b, "baud_mask", id->baud_mask);
    if (full) {
        put_num(&b, "capabilities", id->capabilities);
    }
    put(&b, "}", 1);
    return b.len;
}
