#include "unit_run.h"

#include <string.h>

#define UNIT_MAX_TESTS 64
#define UNIT_NAMES_MAX 2048

int unit_run(const char *group, const char *names, const unit_test_fn *fns, size_t n,
             CMFixtureFunction setup, CMFixtureFunction teardown)
{
    static char buf[UNIT_NAMES_MAX];
    struct CMUnitTest tests[UNIT_MAX_TESTS];
    size_t i, len = strlen(names);
    char *name = buf;
    if (n > UNIT_MAX_TESTS || len >= sizeof buf) {
        return -1;
    }
    memcpy(buf, names, len + 1);
    for (i = 0; i < n; i++) {
        char *comma = strchr(name, ',');
        if (comma) {
            *comma = '\0';
        }
        tests[i].name = name;
        tests[i].test_func = fns[i];
        tests[i].setup_func = setup;
        tests[i].teardown_func = teardown;
        tests[i].initial_state = NULL;
        name = comma ? comma + 1 : name + strlen(name);
        while (*name == ' ') {
            name++;
        }
    }
    return _cmocka_run_group_tests(group, tests, n, NULL, NULL);
}
