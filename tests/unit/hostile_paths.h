/* Paths a file request may carry that must never reach a file store: the
 * gateway's path rule (docs/PROTOCOL.md, "File store") refuses each, both
 * where the name is parsed (test_file_codec.c) and where a node's
 * file.Read arrives (test_file_server.c). One list, so the two cannot
 * drift apart. */
#ifndef DAN_TEST_HOSTILE_PATHS_H
#define DAN_TEST_HOSTILE_PATHS_H

#include <stddef.h>

static const char *const HOSTILE_PATHS[] = {
    "",
    "/",
    "//fw.bin",
    "../fw.bin",
    "/../fw.bin",
    "../etc/passwd",
    "/etc/passwd",
    "a/b/c",
    "fw.bin/",
    ".hidden",
    "/.hidden",
    "./fw.bin",
    "abcdefghijklmnopqrstuvwxyz0123456",  /* 33 bytes: one over the name maximum */
    "/abcdefghijklmnopqrstuvwxyz0123456", /* the same after the leading '/' */
};
#define HOSTILE_PATH_COUNT (sizeof HOSTILE_PATHS / sizeof HOSTILE_PATHS[0])

#endif
