/* Replays saved inputs through one fuzz entry function without libFuzzer:
 * the coverage build of `make fuzz-cov` (tests/fuzz/fuzz.mk), chosen at
 * compile time with -DDAN_FUZZ_FN=dan_fuzz_<target>. Arguments are files
 * or directories (their regular files, not recursively); a missing one is
 * skipped. Prints how many inputs ran. */
#include <dirent.h>
#include <stdio.h>
#include <string.h>
#include <sys/stat.h>

#include "targets.h"

#ifndef DAN_FUZZ_FN
#error "define DAN_FUZZ_FN"
#endif

static uint8_t input[1u << 20]; /* far above every target's max_len */

/* Runs one file; returns 1 if it ran. */
static int replay_file(const char *path)
{
    FILE *f = fopen(path, "rb");
    size_t n;
    if (f == NULL) {
        return 0;
    }
    n = fread(input, 1, sizeof input, f);
    fclose(f);
    (void)DAN_FUZZ_FN(input, n);
    return 1;
}

static long replay_path(const char *path)
{
    struct stat st;
    struct dirent *e;
    DIR *d;
    long count = 0;
    if (stat(path, &st) != 0) {
        return 0;
    }
    if (!S_ISDIR(st.st_mode)) {
        return replay_file(path);
    }
    d = opendir(path);
    if (d == NULL) {
        return 0;
    }
    while ((e = readdir(d)) != NULL) {
        char full[4096];
        if (e->d_name[0] == '.') {
            continue;
        }
        snprintf(full, sizeof full, "%s/%s", path, e->d_name);
        if (stat(full, &st) == 0 && S_ISREG(st.st_mode)) {
            count += replay_file(full);
        }
    }
    closedir(d);
    return count;
}

int main(int argc, char **argv)
{
    long total = 0;
    int i;
    for (i = 1; i < argc; i++) {
        total += replay_path(argv[i]);
    }
    printf("%ld inputs replayed\n", total);
    return 0;
}
