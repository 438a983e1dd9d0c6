/* IEEE 754 binary16 conversions (see dan/can_gw/f16.h). */
#include <string.h>

#include "dan/can_gw/f16.h"

uint16_t dan_f16_from_f32(float v)
{
    uint32_t x, e, m;
    uint16_t sign, h;
    memcpy(&x, &v, sizeof x);
    sign = (uint16_t)((x >> 16) & 0x8000u);
    x &= 0x7FFFFFFFu;
    e = x >> 23;
    m = x & 0x7FFFFFu;
    if (e == 0xFFu) {
        return (uint16_t)(sign | (m != 0u ? 0x7FFFu : 0x7C00u));
    }
    if (e >= 143u) { /* 2^16 and up: beyond half range */
        return (uint16_t)(sign | 0x7C00u);
    }
    if (e >= 113u) { /* half normal: exponent -14..15 */
        h = (uint16_t)(((e - 112u) << 10) | (m >> 13));
        if ((m & 0x1000u) != 0u) {
            h++; /* ties away; may carry into inf */
        }
        return (uint16_t)(sign | h);
    }
    if (e >= 101u) { /* half subnormal, units of 2^-24 */
        uint32_t mant = m | 0x800000u;
        unsigned shift = 126u - (unsigned)e; /* 14..25 */
        h = (uint16_t)(mant >> shift);
        if (((mant >> (shift - 1u)) & 1u) != 0u) {
            h++;
        }
        return (uint16_t)(sign | h);
    }
    return sign; /* below half the smallest subnormal */
}

float dan_f16_to_f32(uint16_t h)
{
    uint32_t sign = (uint32_t)(h & 0x8000u) << 16;
    uint32_t e = (h >> 10) & 0x1Fu;
    uint32_t m = h & 0x3FFu;
    uint32_t x;
    float f;
    if (e == 0u) {
        f = (float)m * 5.9604644775390625e-8f; /* m * 2^-24, exact */
        return sign != 0u ? -f : f;
    }
    if (e == 31u) {
        x = sign | 0x7F800000u | (m << 13);
    } else {
        x = sign | ((e + 112u) << 23) | (m << 13);
    }
    memcpy(&f, &x, sizeof f);
    return f;
}
