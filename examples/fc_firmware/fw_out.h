/*
 * fc_firmware's output: one JSON object per line (semihosting), built in
 * out_line: o_begin("step"), then o_key("name") and a value per member,
 * then o_end() sends it. Code that formats into the buffer itself writes
 * at out_line + out_len (room: FW_OUT_LINE - 1 - out_len) and adds what
 * it wrote to out_len.
 */
#ifndef FC_FW_OUT_H
#define FC_FW_OUT_H

#include <stddef.h>
#include <stdint.h>

#define FW_OUT_LINE 1024u

extern char out_line[FW_OUT_LINE];
extern size_t out_len;

void o_str(const char *s);
void o_u64(uint64_t v);
void o_u32(uint32_t v);
void o_int(int32_t v);
void o_hex(const uint8_t *p, size_t n);
/* A JSON string, escaped by libdan's one JSON formatter. */
void o_jstr(const char *s);
/* ,"key": */
void o_key(const char *k);
/* A member, key and value: ,"key":v and ,"key":"s" */
void o_key_num(const char *k, uint64_t v);
void o_key_jstr(const char *k, const char *s);
void o_begin(const char *step);
void o_end(void);
/* ,"result":r,"error":"its name" */
void o_result(int r);

#endif /* FC_FW_OUT_H */
