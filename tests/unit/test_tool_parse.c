/* The tools' number parser (host_tools/c/dan_tool.c), which every C
 * tool's options go through: decimal, or hex after 0x; a leading 0 is not
 * octal (dan-gatewayd --esc-timeout-ms 0500 was 320 ms); a sign or white
 * space is refused (strtoul took "-1" as ULONG_MAX, in range on a 32-bit
 * build). */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include "dan_tool.h"
#include "unit_run.h"

static uint32_t u32(const char *s)
{
    uint32_t v = 0;
    assert_int_equal(tool_parse_u32(s, 0, UINT32_MAX, &v), 0);
    return v;
}

static void test_accepted(void **state)
{
    unsigned long v = 0;
    (void)state;
    assert_int_equal(u32("0500"), 500);
    assert_int_equal(u32("010"), 10);
    assert_int_equal(u32("0"), 0);
    assert_int_equal(u32("0x62"), 0x62);
    assert_int_equal(u32("0XfF"), 255);
    assert_int_equal(u32("4294967295"), UINT32_MAX);
    assert_int_equal(tool_parse_ulong("ff", 16, 0, 255, &v), 0);
    assert_int_equal(v, 255);
    assert_int_equal(tool_parse_ulong("0750", 10, 0, 1000, &v), 0);
    assert_int_equal(v, 750);
}

static void test_refused(void **state)
{
    static const char *const bad[] = {"",   "-1",   "+5",  " 5",  "5 ",         "1M",
                                      "0x", "0x-1", "abc", "1e3", "4294967296", "0xg"};
    uint32_t v = 7;
    size_t i;
    (void)state;
    for (i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        assert_int_equal(tool_parse_u32(bad[i], 0, UINT32_MAX, &v), -1);
        assert_int_equal(v, 7);
    }
    assert_int_equal(tool_parse_u32("128", 1, 127, &v), -1);
    assert_int_equal(tool_parse_u32("0", 1, 127, &v), -1);
}

int main(void)
{
    return UNIT_RUN("tool_parse", NULL, NULL, test_accepted, test_refused);
}
