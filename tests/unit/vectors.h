/* Reading the vector files in tests/vectors from the C unit tests. The directory comes
 * from $DAN_VECTORS (the Makefile sets it), default "tests/vectors". */
#ifndef DAN_TEST_VECTORS_H
#define DAN_TEST_VECTORS_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>

typedef struct {
    FILE *f;
    char line[8192];
    int lineno;
    char path[512];
} vec_file_t;

/* Opens a vector file; fails the current test if it cannot. */
void vec_open(vec_file_t *v, const char *name);
/* Next non-empty, non-comment line into v->line (newline stripped). */
bool vec_next(vec_file_t *v);
void vec_close(vec_file_t *v);
/* Calls row for each line of the vector file name (open, next, close in
 * one place); returns the number of lines. */
size_t vec_each(const char *name, void (*row)(vec_file_t *v, void *ctx), void *ctx);
/* Splits s in place at sep; returns the number of fields (at most max). */
int vec_split(char *s, char sep, char **fields, int max);
/* Splits a message vector line "<msg> <dir> <fields...> : <payload hex>"
 * in place: f[0] msg, f[1] dir, f[2] the field text ("" if none); the
 * payload goes into p (cap bytes). Returns its length. */
size_t vec_message(vec_file_t *v, char *f[3], uint8_t *p, size_t cap);
/* A message codec under test: decodes p as msg/dir into its field text
 * (txt) and encodes it back into enc; returns the encoded length. */
typedef int (*vec_codec_fn)(const char *msg, const char *dir, const uint8_t *p, size_t len,
                            char *txt, size_t cap, uint8_t *enc, size_t ecap);
/* Checks one message line split by vec_message: codec gives the line's
 * field text f[2] and encodes the same len bytes back. */
void vec_check_message(const vec_file_t *v, char *f[3], const uint8_t *p, size_t len,
                       vec_codec_fn codec);
/* Appends printf-style text to out (cap bytes in all). */
void vec_cat(char *out, size_t cap, const char *fmt, ...);
/* Appends n bytes as hex ("-" when none). */
void vec_cat_hex(char *out, size_t cap, const uint8_t *p, size_t n);
/* Hex to bytes ("-" is empty); fails the current test on bad hex. */
size_t vec_hex(const char *hex, uint8_t *out, size_t cap);

#endif
