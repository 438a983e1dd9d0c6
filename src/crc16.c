/* CRC-16/CCITT-FALSE a byte at a time without a table: the polynomial
 * 0x1021 has its terms at bits 12, 5 and 0, so one byte's step is three
 * shifts of x (the byte xor the CRC's top byte, folded once by x >> 4).
 * No flash for a table (an FC counts it), fewer steps than a nibble table. */
#include "dan/common.h"

uint16_t dan_crc16_ccitt(uint16_t crc, const uint8_t *data, size_t len)
{
    uint32_t c = crc;
    size_t i;
    for (i = 0; i < len; i++) {
        uint32_t x = ((c >> 8) ^ data[i]) & 0xFFu;
        x ^= x >> 4;
        c = (c << 8) ^ (x << 12) ^ (x << 5) ^ x;
    }
    return (uint16_t)c;
}
