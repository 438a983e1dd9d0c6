/* The common DAN v1 payloads. */
#include "dan/payloads.h"

static const uint32_t mask_bauds[4] = {19200u, 38400u, 57600u, 115200u};

const uint32_t dan_fast_bauds[DAN_NFAST_BAUDS] = {230400u,  460800u,  921600u,
                                                  1000000u, 1500000u, 2000000u};

bool dan_baud_is_v1(uint32_t baud)
{
    return baud == DAN_BAUD_BASE || dan_mask_bit_of_baud(baud) != 0u;
}

uint32_t dan_baud_of_mask_bit(uint16_t bit)
{
    unsigned i;
    for (i = 0; i < 4u; i++) {
        if (bit == (uint16_t)(1u << i)) {
            return mask_bauds[i];
        }
    }
    return 0;
}

uint16_t dan_mask_bit_of_baud(uint32_t baud)
{
    unsigned i;
    for (i = 0; i < 4u; i++) {
        if (baud == mask_bauds[i]) {
            return (uint16_t)(1u << i);
        }
    }
    return 0;
}

uint32_t dan_baud_highest(uint16_t mask)
{
    unsigned i = 4u;
    while (i-- > 0u) {
        if ((mask & (1u << i)) != 0u) {
            return mask_bauds[i];
        }
    }
    return DAN_BAUD_BASE;
}

int dan_identity_encode(const dan_identity_t *id, uint8_t *out, size_t cap)
{
    dan_writer_t w;
    dan_writer_init(&w, out, cap);
    dan_put_u8(&w, id->dan_version);
    dan_put_string(&w, id->manufacturer);
    dan_put_string(&w, id->model);
    dan_put_string(&w, id->hw_version);
    dan_put_string(&w, id->sw_version);
    dan_put_u16(&w, id->baud_mask);
    dan_put_u16(&w, id->capabilities);
    return dan_writer_finish(&w);
}

int dan_identity_decode(dan_identity_t *id, const uint8_t *p, size_t len)
{
    dan_reader_t r;
    bool t;
    dan_reader_init(&r, p, len);
    id->dan_version = dan_get_u8(&r);
    t = dan_get_string(&r, id->manufacturer, sizeof id->manufacturer);
    t = dan_get_string(&r, id->model, sizeof id->model) || t;
    t = dan_get_string(&r, id->hw_version, sizeof id->hw_version) || t;
    t = dan_get_string(&r, id->sw_version, sizeof id->sw_version) || t;
    id->baud_mask = dan_get_u16(&r);
    id->capabilities = dan_get_u16(&r);
    id->truncated = t;
    return dan_reader_finish(&r);
}

int dan_identity_baud_mask(const uint8_t *p, size_t len, uint16_t *mask)
{
    dan_reader_t r;
    const uint8_t *s;
    size_t n;
    int i;
    dan_reader_init(&r, p, len);
    (void)dan_get_u8(&r); /* dan_version */
    for (i = 0; i < 4; i++) {
        dan_get_array_view(&r, &s, &n); /* the four strings, as dan_get_string() reads them */
    }
    *mask = dan_get_u16(&r);
    (void)dan_get_u16(&r); /* capabilities */
    return dan_reader_finish(&r);
}

int dan_configure_encode(const dan_configure_t *c, uint8_t *out, size_t cap)
{
    dan_writer_t w;
    dan_writer_init(&w, out, cap);
    dan_put_u8(&w, c->type);
    if (c->type == DAN_CONFIGURE_BPS) {
        dan_put_uvarint(&w, c->baud);
    }
    return dan_writer_finish(&w);
}

int dan_configure_decode(dan_configure_t *c, const uint8_t *p, size_t len)
{
    dan_reader_t r;
    dan_reader_init(&r, p, len);
    c->type = dan_get_u8(&r);
    c->baud = 0;
    if (r.error) {
        return DAN_ERR_MALFORMED;
    }
    if (c->type != DAN_CONFIGURE_BPS) {
        return DAN_ERR_UNSUPPORTED;
    }
    c->baud = dan_get_uvarint(&r);
    return dan_reader_finish(&r);
}

int dan_ack_encode(uint8_t ack, uint8_t *out, size_t cap)
{
    dan_writer_t w;
    if (ack > DAN_ACK_FAIL) {
        return DAN_ERR_ARG;
    }
    dan_writer_init(&w, out, cap);
    dan_put_u8(&w, ack);
    return dan_writer_finish(&w);
}

int dan_ack_decode(uint8_t *ack, const uint8_t *p, size_t len)
{
    *ack = (p != NULL && len > 0u) ? p[0] : 0u; /* as a reader would give it */
    return (p == NULL || len == 0u || *ack > DAN_ACK_FAIL) ? DAN_ERR_MALFORMED : DAN_OK;
}

int dan_error_encode(uint32_t code, uint32_t error, const char *text, uint8_t *out, size_t cap)
{
    dan_writer_t w;
    dan_writer_init(&w, out, cap);
    dan_put_uvarint(&w, code);
    dan_put_uvarint(&w, error);
    dan_put_string(&w, text);
    return dan_writer_finish(&w);
}

int dan_error_code(const uint8_t *p, size_t len, uint32_t *code)
{
    dan_reader_t r;
    const uint8_t *s;
    size_t n;
    dan_reader_init(&r, p, len);
    *code = dan_get_uvarint(&r);
    (void)dan_get_uvarint(&r);      /* error */
    dan_get_array_view(&r, &s, &n); /* text, as dan_get_string() reads it */
    return dan_reader_finish(&r);
}

int dan_error_decode(dan_error_msg_t *e, const uint8_t *p, size_t len)
{
    dan_reader_t r;
    dan_reader_init(&r, p, len);
    e->code = dan_get_uvarint(&r);
    e->error = dan_get_uvarint(&r);
    e->truncated = dan_get_string(&r, e->text, sizeof e->text);
    return dan_reader_finish(&r);
}
