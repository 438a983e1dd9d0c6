/* One runner for the unit test binaries: a list of test functions, each run
 * with the same setup and teardown, as one cmocka group. */
#ifndef UNIT_RUN_H
#define UNIT_RUN_H

#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

typedef void (*unit_test_fn)(void **state);

/* Runs fns[0..n) as group `group`; names is their comma-separated list (the
 * test names cmocka prints). Returns cmocka's count of failed tests. */
int unit_run(const char *group, const char *names, const unit_test_fn *fns, size_t n,
             CMFixtureFunction setup, CMFixtureFunction teardown);

/* UNIT_RUN("group", setup, teardown, test_a, test_b, ...): the tests named,
 * each between setup and teardown (either may be NULL). */
#define UNIT_RUN(group, setup, teardown, ...)                          \
    unit_run(group, #__VA_ARGS__, (const unit_test_fn[]){__VA_ARGS__}, \
             sizeof((const unit_test_fn[]){__VA_ARGS__}) / sizeof(unit_test_fn), setup, teardown)

#endif /* UNIT_RUN_H */
