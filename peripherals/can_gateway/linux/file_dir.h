/*
 * The gateway's file store on a directory (dan-gatewayd --file-dir DIR
 * [--file-max BYTES]): every callback of dan_gw_file_store_t
 * (dan/can_gw/file_store.h) on DIR.
 *
 *     if (dan_file_dir_open(&fd, dir, max, err, sizeof err) < 0) exit 2;
 *     cfg.files = &fd.store;
 *     ...
 *     dan_file_dir_close(&fd);
 *
 * A file is DIR/name, reached only with openat()/fstatat()/renameat()
 * relative to DIR's O_DIRECTORY descriptor and O_NOFOLLOW: a symlink is
 * never followed, and names are checked again (dan_gw_file_name_ok) so no
 * '/', '..' or absolute name can leave DIR. Only regular files count
 * (a FIFO, device or directory of a valid name is "not found"). The
 * partial upload is DIR/~name (the node's one upload): kept across a
 * daemon restart, so up_open(name, keep = true) resumes it; any other
 * ~partial is removed when an upload opens. up_commit fsyncs it and
 * renames it over DIR/name (a reader sees the old file or the new one),
 * then fsyncs DIR. list pages the regular files of valid names in name
 * order ('~' partials and dot files are not valid names). A commit that
 * would make the store hold more than max_files files or max_total bytes
 * (its own files: regular, valid names, the one replaced not counted) is
 * refused with DAN_GW_FS_ENOSPC, so an uploader cannot fill the volume
 * the daemon's other state lives on.
 */
#ifndef DAN_GWD_FILE_DIR_H
#define DAN_GWD_FILE_DIR_H

#include <stddef.h>
#include <stdint.h>

#include "dan/can_gw/file_store.h"

#define DAN_FILE_DIR_DEFAULT_MAX   (4u * 1024u * 1024u)  /* bytes per file */
#define DAN_FILE_DIR_MAX_MAX       0x7FFFFFFFu           /* sizes are int32 */
#define DAN_FILE_DIR_DEFAULT_TOTAL (64u * 1024u * 1024u) /* bytes of all files */
#define DAN_FILE_DIR_DEFAULT_FILES 64u
#define DAN_FILE_DIR_FILES_MAX     254u /* FILE_LIST pages indexes 0..254 */
#define DAN_FILE_DIR_ERR_MAX       320

typedef struct {
    dan_gw_file_store_t store; /* give &store to dan_gw_node_config_t.files */
    int dirfd;                 /* DIR, O_DIRECTORY; -1 closed */
    int up_fd;                 /* the partial ~up_name; -1 none open */
    uint32_t up_len;           /* its bytes */
    char up_name[DAN_GW_FILE_NAME_MAX + 1u];
    uint32_t errors;    /* callbacks that failed on the medium (EIO/ENOSPC) */
    uint32_t max_total; /* bytes of all files (default DAN_FILE_DIR_DEFAULT_TOTAL) */
    uint32_t max_files; /* files (default DAN_FILE_DIR_DEFAULT_FILES, at most _FILES_MAX) */
} dan_file_dir_t;

/* Opens DIR (it must exist, be a directory and be writable); max_size is
 * the cap per file (1..DAN_FILE_DIR_MAX_MAX); max_total and max_files get
 * their defaults (set them after). 0, or -1 with a one-line reason in err. */
int dan_file_dir_open(dan_file_dir_t *d, const char *dir, uint32_t max_size, char *err,
                      size_t errlen);
void dan_file_dir_close(dan_file_dir_t *d);

#endif /* DAN_GWD_FILE_DIR_H */
