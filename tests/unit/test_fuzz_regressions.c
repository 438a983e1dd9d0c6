/* Replays every saved fuzz input (tests/fuzz/corpus/<target>/ and
 * tests/fuzz/regressions/<target>/) through the same entry functions the
 * libFuzzer binaries use (tests/fuzz/targets*.c,
 * included here so the Makefile's unit-test rule links them). A broken invariant aborts; under the
 * ASan build memory errors are reported. The directory is found from
 * $DAN_FUZZ_DIR, else next to $DAN_VECTORS (tests/vectors), else
 * tests/fuzz relative to the current directory. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <dirent.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "../fuzz/targets.c"
#include "../fuzz/targets_files.c"
#include "../fuzz/targets_msgs.c"

static void fuzz_dir(char *out, size_t cap)
{
    const char *d = getenv("DAN_FUZZ_DIR");
    const char *v = getenv("DAN_VECTORS");
    if (d != NULL && d[0] != '\0') {
        snprintf(out, cap, "%s", d);
    } else if (v != NULL && v[0] != '\0') {
        snprintf(out, cap, "%s/../fuzz", v);
    } else {
        snprintf(out, cap, "tests/fuzz");
    }
}

/* Runs every regular file in dir through fn; returns the count. */
static size_t replay_dir(const char *dir, dan_fuzz_fn fn)
{
    static uint8_t buf[1u << 20];
    DIR *dp = opendir(dir);
    struct dirent *e;
    size_t count = 0;
    if (dp == NULL) {
        return 0;
    }
    while ((e = readdir(dp)) != NULL) {
        char path[4096];
        FILE *f;
        size_t n;
        if (e->d_name[0] == '.') {
            continue;
        }
        snprintf(path, sizeof path, "%s/%s", dir, e->d_name);
        f = fopen(path, "rb");
        if (f == NULL) {
            continue;
        }
        n = fread(buf, 1, sizeof buf, f);
        fclose(f);
        (void)fn(buf, n);
        count++;
    }
    closedir(dp);
    return count;
}

static void replay_target(void **state)
{
    const dan_fuzz_target_t *t = (const dan_fuzz_target_t *)*state;
    char base[2048], dir[3072];
    size_t corpus, regress;
    fuzz_dir(base, sizeof base);
    snprintf(dir, sizeof dir, "%s/corpus/%s", base, t->name);
    corpus = replay_dir(dir, t->fn);
    snprintf(dir, sizeof dir, "%s/regressions/%s", base, t->name);
    regress = replay_dir(dir, t->fn);
    print_message("%s: %zu corpus inputs, %zu regression inputs\n", t->name, corpus, regress);
    assert_true(corpus > 0u); /* the seed corpus lives in the repository */
    /* the empty input and a few tiny ones, always */
    {
        static const uint8_t tiny[4] = {0x44, 0x00, 0xFF, 0x80};
        size_t k;
        for (k = 0; k <= sizeof tiny; k++) {
            (void)t->fn(tiny, k);
        }
    }
}

int main(void)
{
    struct CMUnitTest tests[16];
    size_t i;
    for (i = 0; i < dan_fuzz_ntargets && i < 16u; i++) {
        tests[i].name = dan_fuzz_targets[i].name;
        tests[i].test_func = replay_target;
        tests[i].setup_func = NULL;
        tests[i].teardown_func = NULL;
        tests[i].initial_state = (void *)(uintptr_t)&dan_fuzz_targets[i];
    }
    return _cmocka_run_group_tests("fuzz_regressions", tests, i, NULL, NULL);
}
