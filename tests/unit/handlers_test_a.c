/* The test-a type's request handlers (see handlers_test_a.h). */
#include "handlers_test_a.h"

#include "dan/codes.h"

/* 0x62: replies with the payload reversed; an empty payload is malformed. */
static int h_reverse(void *user, uint32_t code, const uint8_t *req, size_t len, dan_writer_t *resp,
                     const char **err, uint64_t now)
{
    size_t i;
    (void)user;
    (void)code;
    (void)now;
    if (len == 0) {
        *err = "empty payload";
        return DAN_ERR_MALFORMED;
    }
    for (i = len; i-- > 0;) {
        dan_put_u8(resp, req[i]);
    }
    return DAN_OK;
}

/* 0x63: a command without a reply; counts its calls in *user. */
static int h_silent(void *user, uint32_t code, const uint8_t *req, size_t len, dan_writer_t *resp,
                    const char **err, uint64_t now)
{
    (void)code;
    (void)req;
    (void)len;
    (void)resp;
    (void)err;
    (void)now;
    (*(unsigned *)user)++;
    return DAN_PERIPH_NO_REPLY;
}

const dan_handler_t test_a_handlers[TEST_A_NHANDLERS] = {
    {DAN_TYPE_TEST_A_FIRST + 2u, h_reverse},
    {DAN_TYPE_TEST_A_FIRST + 3u, h_silent},
};

dan_ptype_t test_a_type(unsigned *calls)
{
    static const dan_identity_t ident = {1,       "DAN Project",         "test A", "rev 1",
                                         "1.0.0", DAN_BAUD_MASK_DEFINED, 0,        false};
    dan_ptype_t t = {0};
    t.first = DAN_TYPE_TEST_A_FIRST;
    t.identity = &ident;
    t.handlers = test_a_handlers;
    t.nhandlers = TEST_A_NHANDLERS;
    t.user = calls;
    return t;
}
