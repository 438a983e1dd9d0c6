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
/* Splits s in place at sep; returns the number of fields (at most max). */
int vec_split(char *s, char sep, char **fields, int max);
/* Hex to bytes ("-" is empty); fails the current test on bad hex. */
size_t vec_hex(const char *hex, uint8_t *out, size_t cap);

#endif
