/* outfile.c: regular-file outputs through a checked temporary (see outfile.h). */
#include "outfile.h"

#include <errno.h>
#include <fcntl.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

static const char *kind_of(mode_t m) {
    if (S_ISLNK(m)) return "a symbolic link";
    if (S_ISFIFO(m)) return "a FIFO";
    if (S_ISCHR(m)) return "a character device";
    if (S_ISBLK(m)) return "a block device";
    if (S_ISSOCK(m)) return "a socket";
    if (S_ISDIR(m)) return "a directory";
    return "not a regular file";
}

#define MAX_PROTECTED 16
static struct { dev_t dev; ino_t ino; char name[256]; } protected_in[MAX_PROTECTED];
static int nprotected;

void wrt_output_protect(const char *path) {
    struct stat st;
    if (!path || nprotected == MAX_PROTECTED || stat(path, &st) != 0) return;
    protected_in[nprotected].dev = st.st_dev;
    protected_in[nprotected].ino = st.st_ino;
    snprintf(protected_in[nprotected].name, sizeof protected_in[nprotected].name, "%s", path);
    nprotected++;
}

wrt_status wrt_output_check(const char *path) {
    if (!path || !path[0]) return wrt_fail(WRT_ERR_IO, "no output path");
    struct stat st;
    if (lstat(path, &st) != 0) {
        if (errno == ENOENT) return WRT_OK;
        return wrt_fail(WRT_ERR_IO, "%s: cannot check the output: %s", path, strerror(errno));
    }
    if (S_ISREG(st.st_mode)) {
        for (int i = 0; i < nprotected; i++)
            if (protected_in[i].dev == st.st_dev && protected_in[i].ino == st.st_ino)
                return wrt_fail(WRT_ERR_IO, "%s: is %s, an input of this run: not replaced by an output", path,
                                protected_in[i].name);
        return WRT_OK;
    }
    return wrt_fail(WRT_ERR_IO, "%s: is %s: outputs are only written as regular files (not replaced)", path,
                    kind_of(st.st_mode));
}

int wrt_output_tmpfile(const char *path, const char *suffix, char **tmp) {
    static _Atomic unsigned counter;
    *tmp = NULL;
    if (!suffix) suffix = "";
    size_t n = strlen(path) + strlen(suffix) + 48;
    char *name = malloc(n);
    if (!name) {
        wrt_fail(WRT_ERR_NOMEM, "%s: out of memory", path);
        return -1;
    }
    for (int tries = 0; tries < 100; tries++) {
        snprintf(name, n, "%s.tmp.%ld.%u%s", path, (long)getpid(), counter++, suffix);
        int fd = open(name, O_WRONLY | O_CREAT | O_EXCL | O_NOFOLLOW | O_CLOEXEC, 0666);
        if (fd >= 0) {
            *tmp = name;
            return fd;
        }
        if (errno != EEXIST) break;
    }
    int e = errno;
    free(name);
    wrt_fail(WRT_ERR_IO, "%s: cannot create a temporary file beside it: %s", path, strerror(e));
    return -1;
}

wrt_status wrt_output_begin(const char *path, const char *mode, wrt_output *o) {
    memset(o, 0, sizeof *o);
    wrt_status st = wrt_output_check(path);
    if (st != WRT_OK) return st;
    o->path = strdup(path);
    if (!o->path) return wrt_fail(WRT_ERR_NOMEM, "%s: out of memory", path);
    int fd = wrt_output_tmpfile(path, "", &o->tmp); /* O_EXCL: never opens through a link */
    if (fd < 0) {
        wrt_output_abort(o);
        return WRT_ERR_IO;
    }
    o->f = fdopen(fd, mode ? mode : "w");
    if (!o->f) {
        close(fd);
        wrt_output_abort(o);
        return wrt_fail(WRT_ERR_IO, "%s: cannot open the temporary file", path);
    }
    return WRT_OK;
}

void wrt_output_abort(wrt_output *o) {
    if (!o) return;
    if (o->f) fclose(o->f);
    if (o->tmp) unlink(o->tmp);
    free(o->tmp);
    free(o->path);
    memset(o, 0, sizeof *o);
}

wrt_status wrt_output_commit(wrt_output *o) {
    if (!o || !o->f || !o->tmp || !o->path) return wrt_fail(WRT_ERR_INVALID_ARG, "wrt_output_commit: nothing open");
    int bad = ferror(o->f);
    bad |= fflush(o->f) != 0;
    int e = errno;
    bad |= fsync(fileno(o->f)) != 0;
    bad |= fclose(o->f) != 0;
    o->f = NULL;
    if (bad) {
        wrt_status st = wrt_fail(WRT_ERR_IO, "%s: write failed: %s", o->path, strerror(e ? e : EIO));
        wrt_output_abort(o);
        return st;
    }
    wrt_status st = wrt_output_check(o->path); /* it may have changed while we wrote */
    if (st == WRT_OK && rename(o->tmp, o->path) != 0)
        st = wrt_fail(WRT_ERR_IO, "%s: cannot rename the temporary file over it: %s", o->path, strerror(errno));
    if (st == WRT_OK) {
        free(o->tmp);
        o->tmp = NULL;
    }
    wrt_output_abort(o);
    return st;
}
