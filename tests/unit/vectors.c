#include <ctype.h>
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>

#include "dan/common.h"
#include "vectors.h"

void vec_open(vec_file_t *v, const char *name)
{
    const char *dir = getenv("DAN_VECTORS");
    if (dir == NULL || dir[0] == '\0') {
        dir = "tests/vectors";
    }
    snprintf(v->path, sizeof v->path, "%s/%s", dir, name);
    v->f = fopen(v->path, "r");
    v->lineno = 0;
    if (v->f == NULL) {
        fail_msg("cannot open vector file %s", v->path);
    }
}

bool vec_next(vec_file_t *v)
{
    while (fgets(v->line, sizeof v->line, v->f) != NULL) {
        size_t n = strlen(v->line);
        v->lineno++;
        while (n > 0 && (v->line[n - 1] == '\n' || v->line[n - 1] == '\r')) {
            v->line[--n] = '\0';
        }
        if (n == 0 || v->line[0] == '#') {
            continue;
        }
        return true;
    }
    return false;
}

void vec_close(vec_file_t *v)
{
    if (v->f != NULL) {
        fclose(v->f);
        v->f = NULL;
    }
}

size_t vec_each(const char *name, void (*row)(vec_file_t *v, void *ctx), void *ctx)
{
    static vec_file_t v; /* 8 KiB line buffer: not on the stack */
    size_t count = 0;
    vec_open(&v, name);
    while (vec_next(&v)) {
        row(&v, ctx);
        count++;
    }
    vec_close(&v);
    return count;
}

void vec_check_message(const vec_file_t *v, char *f[3], const uint8_t *p, size_t len,
                       vec_codec_fn codec)
{
    char txt[2048];
    uint8_t enc[DAN_MAX_PAYLOAD];
    int n = codec(f[0], f[1], p, len, txt, sizeof txt, enc, sizeof enc);
    if (strcmp(txt, f[2]) != 0) {
        fail_msg("line %d: decoded\n  %s\nexpected\n  %s", v->lineno, txt, f[2]);
    }
    assert_int_equal(n, (int)len);
    assert_memory_equal(enc, p, len);
}

int vec_split(char *s, char sep, char **fields, int max)
{
    int n = 0;
    while (n < max) {
        char *e = strchr(s, sep);
        fields[n++] = s;
        if (e == NULL) {
            break;
        }
        *e = '\0';
        s = e + 1;
    }
    return n;
}

size_t vec_hex(const char *hex, uint8_t *out, size_t cap)
{
    size_t n = 0;
    if (strcmp(hex, "-") == 0) {
        return 0;
    }
    while (hex[0] != '\0') {
        char pair[3] = {hex[0], hex[1], '\0'};
        if (!isxdigit((unsigned char)pair[0]) || !isxdigit((unsigned char)pair[1]) || n >= cap) {
            fail_msg("bad hex or too long: %s", hex);
        }
        out[n++] = (uint8_t)strtoul(pair, NULL, 16);
        hex += 2;
    }
    return n;
}

void vec_cat(char *out, size_t cap, const char *fmt, ...)
{
    size_t n = strlen(out);
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(out + n, cap - n, fmt, ap);
    va_end(ap);
}

void vec_cat_hex(char *out, size_t cap, const uint8_t *p, size_t n)
{
    size_t i;
    if (n == 0u) {
        vec_cat(out, cap, "-");
    }
    for (i = 0; i < n; i++) {
        vec_cat(out, cap, "%02x", p[i]);
    }
}

size_t vec_message(vec_file_t *v, char *f[3], uint8_t *p, size_t cap)
{
    char *colon = strstr(v->line, " : ");
    size_t len;
    assert_non_null(colon);
    *colon = '\0';
    len = vec_hex(colon + 3, p, cap);
    f[0] = v->line;
    f[1] = strchr(v->line, ' ');
    assert_non_null(f[1]);
    *f[1]++ = '\0';
    f[2] = strchr(f[1], ' ');
    if (f[2] != NULL) {
        *f[2]++ = '\0';
    } else {
        f[2] = f[1] + strlen(f[1]);
    }
    return len;
}
