/* DSDL codecs of the file services (see dan/can_gw/dsdl_file.h). */
#include "dan/can_gw/dsdl_file.h"

/* ---- file.GetInfo ---- */

static const dan_dc_field_t GETINFO_REQ[] = {
    DAN_DC_TAO(dan_dc_file_req_t, path, path_len, DAN_DC_FILE_PATH_MAX),
};
static const dan_dc_field_t GETINFO_RSP[] = {
    DAN_DC_U(dan_dc_file_getinfo_rsp_t, size, 40),
    DAN_DC_I(dan_dc_file_getinfo_rsp_t, error, 16),
    DAN_DC_U(dan_dc_file_getinfo_rsp_t, entry_type, 8),
};
DAN_DC_TABLE_CODEC(dan_dc_file_getinfo_req, dan_dc_file_req_t, GETINFO_REQ)
DAN_DC_TABLE_CODEC(dan_dc_file_getinfo_rsp, dan_dc_file_getinfo_rsp_t, GETINFO_RSP)

/* ---- file.Read ---- */

static const dan_dc_field_t READ_REQ[] = {
    DAN_DC_U(dan_dc_file_req_t, offset, 40),
    DAN_DC_TAO(dan_dc_file_req_t, path, path_len, DAN_DC_FILE_PATH_MAX),
};
DAN_DC_TABLE_CODEC(dan_dc_file_read_req, dan_dc_file_req_t, READ_REQ)

/* The response's data holds up to 256 bytes: more than a table's tail
 * array (uint8 length) can say, so it is written out here. */
int dan_dc_file_read_rsp_encode(const dan_dc_file_read_rsp_t *m, uint8_t *buf, size_t cap)
{
    dan_dc_bw_t w;
    if (m == NULL || m->data_len > DAN_DC_FILE_READ_MAX) {
        return DAN_ERR_ARG;
    }
    dan_dc_bw_init(&w, buf, cap);
    dan_dc_put_int(&w, 16, m->error);
    dan_dc_put_bytes(&w, m->data, m->data_len); /* TAO */
    return dan_dc_bw_finish(&w);
}

int dan_dc_file_read_rsp_decode(dan_dc_file_read_rsp_t *m, const uint8_t *buf, size_t len)
{
    dan_dc_br_t r;
    size_t n;
    if (!dan_dc_dec_begin(&r, m, sizeof *m, buf, len)) {
        return DAN_ERR_ARG;
    }
    m->error = (int16_t)dan_dc_get_int(&r, 16);
    n = dan_dc_tao_count(&r, 8);
    if (n > DAN_DC_FILE_READ_MAX) {
        return DAN_ERR_MALFORMED;
    }
    dan_dc_get_bytes(&r, m->data, n);
    m->data_len = (uint16_t)n;
    return dan_dc_br_finish(&r);
}
