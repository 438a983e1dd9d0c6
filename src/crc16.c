/* CRC-16/CCITT-FALSE a nibble at a time: a 32-byte table instead of 512
 * (flash matters on an FC), about 4x fewer steps than bit by bit. */
#include "dan/common.h"

static const uint16_t crc16_nibble[16] = {0x0000, 0x1021, 0x2042, 0x3063, 0x4084, 0x50A5,
                                          0x60C6, 0x70E7, 0x8108, 0x9129, 0xA14A, 0xB16B,
                                          0xC18C, 0xD1AD, 0xE1CE, 0xF1EF};

uint16_t dan_crc16_ccitt(uint16_t crc, const uint8_t *data, size_t len)
{
    size_t i;
    for (i = 0; i < len; i++) {
        uint8_t b = data[i];
        crc = (uint16_t)((unsigned)(crc << 4) ^ crc16_nibble[((crc >> 12) ^ (b >> 4)) & 0xFu]);
        crc = (uint16_t)((unsigned)(crc << 4) ^ crc16_nibble[((crc >> 12) ^ b) & 0xFu]);
    }
    return crc;
}
