/* outfile.h: outputs created only as regular files. Every writer of wrt (the bake's .gto
 * and --stats-json, wrt-play's pictures, wrt-ref, wrt-compare, wrt-scenegen, the image
 * shim) checks its target here and writes through a private temporary beside it, renamed
 * over the target only when complete. A target that exists and is not a regular file (a
 * symbolic link, a FIFO, a character or block device, a socket, a directory) is refused,
 * before any work and again just before the rename: `-o /dev/null`, `-o fifo` or a link
 * planted where the output goes must never be replaced or written through. Depends on
 * wrt_common.h and POSIX (lstat, mkostemp, fsync, rename). Thread-safe. */
#ifndef WRT_OUTFILE_H
#define WRT_OUTFILE_H

#include <stdio.h>

#include "wrt_common.h"

/* WRT_OK if `path` does not exist or is a regular file (not through a link) that is not
 * an input registered with wrt_output_protect; else WRT_ERR_IO with wrt_last_error()
 * saying "PATH: is a FIFO: outputs are only written as regular files" (or a symbolic
 * link, a device, a socket, a directory, an input of this run). */
wrt_status wrt_output_check(const char *path);

/* Registers a file this run reads (the scene, the .gto, a script), by device and inode:
 * wrt_output_check then refuses any output that is that file, under any name (a hard
 * link too), instead of replacing the input with the results ("PATH: is FILE, an input
 * of this run: not replaced"). A path that does not exist is ignored; at most 16 inputs.
 * Call from the program's main before the work starts (not thread-safe against checks
 * running at the same time). */
void wrt_output_protect(const char *path);

/* Creates a new temporary beside `path`, named PATH.tmp.PID.N`suffix` (suffix may be ""),
 * with O_CREAT | O_EXCL | O_NOFOLLOW and mode 0666 less the umask (as the target would
 * get); *tmp receives its name (malloc'ed). Returns the open descriptor, or -1 with a
 * message (WRT_ERR_IO) and *tmp NULL. */
int wrt_output_tmpfile(const char *path, const char *suffix, char **tmp);

/* An output in progress: a temporary PATH.tmp.XXXXXX made with O_EXCL (never through a
 * link) in the target's folder. */
typedef struct wrt_output {
    FILE *f;      /* write here */
    char *tmp;    /* the temporary's name (owned) */
    char *path;   /* the target (owned copy) */
} wrt_output;

/* Checks `path` (wrt_output_check) and creates the temporary; `mode` is fdopen's ("w" or
 * "wb"). On failure returns WRT_ERR_IO with a message and leaves *o zeroed. */
wrt_status wrt_output_begin(const char *path, const char *mode, wrt_output *o);
/* Flushes, syncs and closes the temporary, checks the target once more and renames the
 * temporary over it. Any write error (a full disk) or a target that became a special
 * file fails with WRT_ERR_IO and removes the temporary; the target is left as it was. */
wrt_status wrt_output_commit(wrt_output *o);
/* Drops the temporary (on an error of the caller). NULL or zeroed: no-op. */
void wrt_output_abort(wrt_output *o);

#endif
