/* gto_write.c: writes the .gto file atomically. The writer lays out the header, the
 * section table and the sections (GTO_FORMAT.md, gto_layout.h), checks its own input
 * with the reader's content checks (gto_check.c) before it writes a byte, writes a
 * temporary in the target's folder (unnamed with O_TMPFILE where the file system has it,
 * else a named one the signal handlers remove), syncs it and renames it over the target;
 * a pending file can be mapped and checked (gto_read.c) before the rename. Not part of
 * the runtime library. Depends on gto_layout.h, gto_read.c, scene.h (the records come
 * from the scene), basis.h and POSIX (O_TMPFILE, mkostemp, fsync, linkat, rename,
 * sigaction). */
#include "gto_layout.h"
#include "scene.h"
#include "../common/outfile.h"

#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <inttypes.h>
#include <limits.h>
#include <pthread.h>
#include <signal.h>
#include <stdalign.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "../common/basis.h"

/* ------------------------------------------------------------------------------------
 * Writer
 * ---------------------------------------------------------------------------------- */

/* Temporaries being written, for the signal handler: state 0 free, 1 claimed, 2 armed.
 * Lock-free atomics, so the handler may read them. */
_Static_assert(ATOMIC_INT_LOCK_FREE == 2, "the signal handler needs lock-free atomics");
#define TMP_SLOTS 8
static struct { atomic_int state; char path[PATH_MAX]; } tmp_slots[TMP_SLOTS];
static wrt_gto_write_hook write_hook;

void wrt_gto_set_write_hook(wrt_gto_write_hook hook) { write_hook = hook; }

static int tmp_arm(const char *path) {
    if (strlen(path) >= PATH_MAX) return -1;
    for (int i = 0; i < TMP_SLOTS; i++) {
        int expect = 0;
        if (atomic_compare_exchange_strong(&tmp_slots[i].state, &expect, 1)) {
            strcpy(tmp_slots[i].path, path);
            atomic_store(&tmp_slots[i].state, 2);
            return i;
        }
    }
    return -1; /* more concurrent writes than slots: this one is not cleaned on a signal */
}

static void tmp_disarm(int slot) {
    if (slot >= 0) atomic_store(&tmp_slots[slot].state, 0);
}

void wrt_gto_remove_temporaries(void) {
    int saved = errno;
    for (int i = 0; i < TMP_SLOTS; i++)
        if (atomic_load(&tmp_slots[i].state) == 2) unlink(tmp_slots[i].path);
    errno = saved;
}

static void cleanup_handler(int sig) {
    int saved = errno;
    wrt_gto_remove_temporaries();
    struct sigaction sa;
    memset(&sa, 0, sizeof sa);
    sa.sa_handler = SIG_DFL;
    sigemptyset(&sa.sa_mask);
    sigaction(sig, &sa, NULL);
    raise(sig); /* blocked until the handler returns, then kills with the default action */
    errno = saved;
}

void wrt_gto_install_signal_cleanup(void) {
    static const int sigs[] = {SIGINT, SIGTERM, SIGHUP};
    for (size_t i = 0; i < sizeof sigs / sizeof *sigs; i++) {
        struct sigaction old, sa;
        if (sigaction(sigs[i], NULL, &old) != 0) continue;
        if (old.sa_handler == SIG_IGN || old.sa_handler == cleanup_handler) continue;
        memset(&sa, 0, sizeof sa);
        sa.sa_handler = cleanup_handler;
        sigemptyset(&sa.sa_mask);
        sigaction(sigs[i], &sa, NULL);
    }
}

static int write_all(int fd, const void *data, uint64_t n) {
    const uint8_t *p = data;
    while (n) {
        size_t part = n > (1u << 30) ? (1u << 30) : (size_t)n;
        ssize_t w = write(fd, p, part);
        if (w < 0) {
            if (errno == EINTR) continue;
            return -1;
        }
        if (w == 0) { errno = EIO; return -1; }
        p += w;
        n -= (uint64_t)w;
    }
    return 0;
}

static void copy_name(char dst[64], const char *src) {
    memset(dst, 0, 64);
    if (src) memcpy(dst, src, strnlen(src, 63));
}

typedef struct wsec { uint32_t id; uint64_t count; const void *data; } wsec;

/* Removes PATH.tmp.PID.* left by a process that no longer exists (killed while
 * writing). Temporaries of live processes, and names of another form, are left. */
static void remove_stale_temporaries(const char *path) {
    const char *slash = strrchr(path, '/');
    const char *base = slash ? slash + 1 : path;
    size_t dl = slash ? (size_t)(slash - path) : 0;
    char *dir = wrt_xmalloc(dl + 2);
    if (slash) { memcpy(dir, path, dl); dir[dl] = 0; if (dl == 0) strcpy(dir, "/"); }
    else strcpy(dir, ".");
    DIR *d = opendir(dir);
    size_t bl = strlen(base);
    if (d) {
        struct dirent *e;
        while ((e = readdir(d))) {
            const char *n = e->d_name;
            if (strncmp(n, base, bl) != 0 || strncmp(n + bl, ".tmp.", 5) != 0) continue;
            char *end;
            errno = 0;
            long pid = strtol(n + bl + 5, &end, 10);
            if (errno || end == n + bl + 5 || *end != '.' || pid <= 0 || pid == (long)getpid()) continue;
            if (kill((pid_t)pid, 0) == 0 || errno != ESRCH) continue; /* alive, or not ours to judge */
            int fd = dirfd(d);
            if (unlinkat(fd, n, 0) == 0)
                wrt_log(WRT_LOG_INFO, "removed %s/%s, left by process %ld, which is gone", dir, n, pid);
        }
        closedir(d);
    }
    free(dir);
}

static int force_named;
void wrt_gto_force_named_temporaries(int on) { force_named = on; }

/* Creates the temporary for `path` in its folder: O_TMPFILE if the file system has it
 * (and not forced off), else a named one, armed for the signal handler. */
static wrt_status tmp_create(const char *path, wrt_gto_pending *p) {
    remove_stale_temporaries(path);
    p->path = wrt_xmalloc(strlen(path) + 1);
    strcpy(p->path, path);
    size_t pl = strlen(path);
    int e = 0;
#ifdef O_TMPFILE
    if (!force_named) {
        char *dir = wrt_xmalloc(pl + 2);
        strcpy(dir, path);
        char *slash = strrchr(dir, '/');
        if (!slash) strcpy(dir, ".");
        else if (slash == dir) dir[1] = 0;
        else *slash = 0;
        p->fd = open(dir, O_TMPFILE | O_RDWR | O_CLOEXEC, 0600);
        e = errno;
        free(dir);
        if (p->fd >= 0) return WRT_OK;
        if (e != EOPNOTSUPP && e != EISDIR && e != EINVAL) {
            wrt_gto_discard(p);
            return wrt_fail(WRT_ERR_IO, "cannot create a temporary file for %s: %s", path, strerror(e));
        }
    }
#endif
    p->tmp = wrt_xmalloc(pl + 40);
    snprintf(p->tmp, pl + 40, "%s.tmp.%ld.XXXXXX", path, (long)getpid());
    sigset_t all, old;
    sigfillset(&all);
    pthread_sigmask(SIG_BLOCK, &all, &old);
    p->fd = mkostemp(p->tmp, O_CLOEXEC);
    e = errno;
    if (p->fd >= 0) p->slot = tmp_arm(p->tmp);
    pthread_sigmask(SIG_SETMASK, &old, NULL);
    if (p->fd < 0) {
        free(p->tmp);
        p->tmp = NULL;
        wrt_gto_discard(p);
        return wrt_fail(WRT_ERR_IO, "cannot create a temporary file for %s: %s", path, strerror(e));
    }
    return WRT_OK;
}

wrt_status wrt_gto_check_output(const char *path, const char *const *inputs, int ninputs) {
    if (!path || !path[0]) return wrt_fail(WRT_ERR_INVALID_ARG, "no output path");
    struct stat so;
    int exists = stat(path, &so) == 0;
    if (exists && S_ISDIR(so.st_mode))
        return wrt_fail(WRT_ERR_IO, "%s: the output is a directory", path);
    for (int i = 0; i < ninputs && exists; i++) {
        struct stat si;
        if (inputs[i] && stat(inputs[i], &si) == 0 && si.st_dev == so.st_dev && si.st_ino == so.st_ino)
            return wrt_fail(WRT_ERR_INVALID_ARG, "%s: the output is the input %s (same file)", path,
                            inputs[i]);
    }
    /* Can a temporary be made beside it? (Made and dropped now, before any work.) */
    wrt_gto_pending p;
    memset(&p, 0, sizeof p);
    p.fd = -1;
    p.slot = -1;
    wrt_status st = tmp_create(path, &p);
    wrt_gto_discard(&p);
    return st;
}

/* The contents' counts and pointers, before anything is built from them. */
static wrt_status check_contents(const char *path, const wrt_gto_contents *c) {
    const wrt_scene *sc = c->scene;
    uint32_t nf = c->nfuncs;
    if (sc->nquads < 0 || sc->nmaterials < 0 || sc->nlights < 0 || sc->nnames < 0)
        return wrt_fail(WRT_ERR_INVALID_ARG, "refusing to write %s: negative scene counts", path);
    if (nf && (!c->fkeys || !c->col_start))
        return wrt_fail(WRT_ERR_INVALID_ARG, "refusing to write %s: %u functions but no keys or columns",
                        path, nf);
    if (c->nctree) {
        char what[300];
        snprintf(what, sizeof what, "refusing to write %s: cluster tree", path);
        wrt_status ct = gto_check_ctree(c->ctree, c->nctree, (uint32_t)sc->nquads, WRT_ERR_INVALID_ARG, what);
        if (ct != WRT_OK) return ct;
    }
    uint64_t nnz = c->col_start ? c->col_start[nf] : 0;
    if (nnz && (!c->rows || !c->vals))
        return wrt_fail(WRT_ERR_INVALID_ARG, "refusing to write %s: %" PRIu64 " entries but no rows or vals",
                        path, nnz);
    if (c->op_kind > WRT_GTO_OP_GATHERED)
        return wrt_fail(WRT_ERR_INVALID_ARG, "refusing to write %s: unknown operator kind %u", path, c->op_kind);
    /* The first-bounce operator K: written only when it has columns. */
    uint32_t nk = c->nkcols;
    if (nk && (!c->kkeys || !c->kcol_start))
        return wrt_fail(WRT_ERR_INVALID_ARG, "refusing to write %s: K has %u columns but no kkeys or kcol_start",
                        path, nk);
    if (nk == UINT32_MAX)
        return wrt_fail(WRT_ERR_INVALID_ARG, "refusing to write %s: kkeys: %u columns, too many", path, nk);
    uint64_t knnz = nk ? c->kcol_start[nk] : 0;
    if (knnz && (!c->krows || !c->kvals))
        return wrt_fail(WRT_ERR_INVALID_ARG, "refusing to write %s: K has %" PRIu64 " entries but no krows or kvals",
                        path, knnz);
    return WRT_OK;
}

/* The records the file holds, built from the scene. */
typedef struct gto_records {
    uint32_t nq, nm, nl, nn;
    wrt_gto_quad *quads;
    wrt_gto_material *mats;
    wrt_gto_light *lights;
    char (*names)[64];
    wrt_gto_camera cam;
    wrt_gto_stats stats;
    wrt_gto_srcmap *srcmap; /* NULL: not written (no_srcmap) */
    uint8_t *textures; uint64_t textures_size; /* NULL: the scene has none */
    wrt_gto_normals *normals; /* NULL: not written (no quad's corner normals leave its plane) */
    uint8_t *opcode;        /* the compact operator's section (contents.compact), else NULL */
    uint64_t opcode_size, nblocks;
    uint32_t opcode_id;     /* SEC_OPSTREAM (3.0) or, with contents.opcode_v2, SEC_OPCODE (2.0) */
    uint8_t *kcode;         /* K's compact section (compact and not k_float, with K), else NULL */
    uint64_t kcode_size, knblocks;
} gto_records;

static void free_records(gto_records *R) {
    free(R->quads); free(R->mats); free(R->lights); free(R->names); free(R->srcmap); free(R->opcode); free(R->kcode); free(R->normals); free(R->textures);
}

/* The corner normals (section normals, version 1.3), only where they say something: some
 * quad's vertex normals leave its flat normal by more than half a degree (cosine under
 * 1 - 4e-5; the flat faces of assets/cornell.gltf carry normals up to 0.1 degree off, the
 * float rounding of the exporter's). A scene of flat faces, with or without glTF normals,
 * gives the file as before. */
static void build_normals(const wrt_scene *sc, gto_records *R) {
    uint32_t nq = R->nq;
    int curved = 0;
    for (uint32_t q = 0; q < nq && !curved; q++) {
        const wrt_quad *s = &sc->quads[q];
        for (int k = 0; k < 4 && s->has_nrm; k++)
            if (s->vn[k][0] * s->n.x + s->vn[k][1] * s->n.y + s->vn[k][2] * s->n.z < 1 - 4e-5) curved = 1;
    }
    if (!curved) return;
    wrt_gto_normals *m = R->normals = wrt_xcalloc(nq ? nq : 1, sizeof *m);
    for (uint32_t q = 0; q < nq; q++) {
        const wrt_quad *s = &sc->quads[q];
        for (int k = 0; k < 4; k++) {
            if (s->has_nrm) { memcpy(m[q].n[k], s->vn[k], sizeof m[q].n[k]); continue; }
            m[q].n[k][0] = (float)s->n.x; m[q].n[k][1] = (float)s->n.y; m[q].n[k][2] = (float)s->n.z;
        }
    }
}

/* contents.compact: the float entries checked as a 1.x file's col_start, rows and vals
 * would be (the encoder relies on ascending rows and finite values), then encoded. */
static wrt_status encode_entries(const char *path, const wrt_gto_contents *c, gto_records *R) {
    uint32_t nf = c->nfuncs;
    static const uint64_t zero = 0;
    const uint64_t *cs = c->col_start ? c->col_start : &zero;
    wrt_gto view;
    memset(&view, 0, sizeof view);
    view.nfuncs = nf; view.col_start = cs; view.nnz = cs[nf];
    vctx v;
    memset(&v, 0, sizeof v);
    v.g = &view;
    const struct { uint32_t id; uint64_t count; const void *data; } in[3] = {
        {SEC_COL_START, (uint64_t)nf + 1, cs}, {SEC_ROWS, view.nnz, c->rows}, {SEC_VALS, view.nnz, c->vals}};
    for (int i = 0; i < 3; i++) {
        if (in[i].count == 0) continue;
        gto_scan_section(in[i].data, in[i].count, gto_sec_info[in[i].id].elem_size, gto_sec_checker(in[i].id), &v);
        if (v.bad)
            return wrt_fail(WRT_ERR_INVALID_ARG, "refusing to write %s: %s: %s", path, gto_sec_name(in[i].id), v.err);
    }
    if (view.nnz > UINT32_MAX * (uint64_t)WRT_GTO_BLOCK_MAX)
        return wrt_fail(WRT_ERR_INVALID_ARG, "refusing to write %s: %" PRIu64 " entries, too many to encode", path,
                        view.nnz);
    R->opcode_id = c->opcode_v2 ? SEC_OPCODE : SEC_OPSTREAM;
    R->opcode = c->opcode_v2 ? gto_opcode_encode(nf, cs, c->rows, c->vals, &R->opcode_size)
                             : gto_opstream_encode(nf, cs, c->rows, c->vals, &R->opcode_size);
    if (!R->opcode) return wrt_fail(WRT_ERR_NOMEM, "cannot write %s: no memory to encode the entries", path);
    memcpy(&R->nblocks, R->opcode + offsetof(gto_opcode_head, nblocks), 8);
    return WRT_OK;
}

/* contents.compact without k_float, with K: K's entries encoded (section kcode, 2.0). The
 * float krows and kvals are checked as a 1.x file's would be when the plan is checked
 * (plan_header), before anything is written. */
static wrt_status encode_k(const char *path, const wrt_gto_contents *c, gto_records *R) {
    uint32_t nk = c->nkcols;
    uint64_t knnz = c->kcol_start[nk];
    for (uint32_t j = 0; j < nk; j++)
        if (c->kcol_start[j + 1] < c->kcol_start[j])
            return wrt_fail(WRT_ERR_INVALID_ARG, "refusing to write %s: kcol_start not monotone at column %u", path,
                            j + 1);
    if (c->kcol_start[0] != 0 || knnz > UINT32_MAX * (uint64_t)WRT_GTO_BLOCK_MAX)
        return wrt_fail(WRT_ERR_INVALID_ARG, "refusing to write %s: kcol_start from %" PRIu64 " to %" PRIu64
                        " entries (from 0, fewer than 2^38)", path, c->kcol_start[0], knnz);
    R->kcode = gto_kcode_encode(nk, c->kcol_start, c->krows, c->kvals, &R->kcode_size);
    if (!R->kcode) return wrt_fail(WRT_ERR_NOMEM, "cannot write %s: no memory to encode K's entries", path);
    memcpy(&R->knblocks, R->kcode + offsetof(gto_opcode_head, nblocks), 8);
    return WRT_OK;
}

/* Each quad's function range and deepest levels from the keys, then its geometry. */
static wrt_status build_quads(const char *path, const wrt_gto_contents *c, gto_records *R) {
    const wrt_scene *sc = c->scene;
    uint32_t nf = c->nfuncs, nq = R->nq;
    wrt_gto_quad *quads = R->quads = wrt_xcalloc(nq ? nq : 1, sizeof *quads);
    for (uint32_t i = 0; i < nf; i++) {
        uint32_t q = wrt_fkey_quad(c->fkeys[i]);
        if (q >= nq)
            return wrt_fail(WRT_ERR_INVALID_ARG, "refusing to write %s: fkeys[%u] names quad %u, but there are %u quads",
                            path, i, q, nq);
        wrt_gto_quad *r = &quads[q];
        if (r->func_count == 0) r->func_first = i;
        r->func_count++;
        uint32_t sl = wrt_fkey_snode(c->fkeys[i]).level, al = wrt_fkey_anode(c->fkeys[i]).level;
        if (sl > r->slevel) r->slevel = sl;
        if (al > r->alevel) r->alevel = al;
    }
    uint32_t next = 0;
    for (uint32_t q = 0; q < nq; q++) {
        const wrt_quad *s = &sc->quads[q];
        wrt_gto_quad *r = &quads[q];
        if (r->func_count == 0) r->func_first = next;
        next = r->func_first + r->func_count;
        for (int k = 0; k < 4; k++) { r->p[k][0] = s->p[k].x; r->p[k][1] = s->p[k].y; r->p[k][2] = s->p[k].z; }
        r->n[0] = (float)s->n.x; r->n[1] = (float)s->n.y; r->n[2] = (float)s->n.z;
        r->t[0] = (float)s->t.x; r->t[1] = (float)s->t.y; r->t[2] = (float)s->t.z;
        r->b[0] = (float)s->b.x; r->b[1] = (float)s->b.y; r->b[2] = (float)s->b.z;
        r->area = (float)s->area;
        r->material = (uint32_t)s->material; /* negative -> huge -> refused by the check */
        r->name = (s->name < 0) ? WRT_GTO_NO_NAME : (uint32_t)s->name;
        r->flags = s->parallelogram ? 1u : 0u;
    }
    if (!c->no_srcmap) { /* the quad-to-source map: what the loader knows, as it knows it */
        wrt_gto_srcmap *m = R->srcmap = wrt_xcalloc(nq ? nq : 1, sizeof *m);
        for (uint32_t q = 0; q < nq; q++) {
            const wrt_quad *s = &sc->quads[q];
            m[q].node = s->node; m[q].mesh = s->mesh; m[q].prim = s->prim;
            m[q].tri[0] = s->tri[0]; m[q].tri[1] = s->tri[1];
            m[q].kind = (uint32_t)s->kind; m[q].part = (uint32_t)s->part;
            m[q].twin_of = s->twin ? s->twin_of : -1;
            m[q].flags = (s->twin ? WRT_GTO_SRC_TWIN : 0u) | (s->has_uv ? WRT_GTO_SRC_UV : 0u);
            if (s->has_uv) memcpy(m[q].uv, s->uv, sizeof m[q].uv);
        }
    }
    build_normals(sc, R);
    return WRT_OK;
}

/* Materials, lights, names, camera and statistics. */
static void build_scene_records(const wrt_gto_contents *c, gto_records *R) {
    const wrt_scene *sc = c->scene;
    uint32_t nm = R->nm;
    wrt_gto_material *mats = R->mats = wrt_xcalloc(nm ? nm : 1, sizeof *mats);
    for (uint32_t i = 0; i < nm; i++) {
        const wrt_material *s = &sc->materials[i];
        copy_name(mats[i].name, s->name);
        memcpy(mats[i].base_color, s->base_color, sizeof mats[i].base_color);
        mats[i].metallic = s->metallic;
        mats[i].roughness = s->roughness;
        memcpy(mats[i].emissive, s->emissive, sizeof mats[i].emissive);
        mats[i].lambertian = s->lambertian ? 1u : 0u;
        mats[i].alevel = c->material_alevel ? c->material_alevel[i] : 0u;
    }
    uint32_t nl = R->nl;
    wrt_gto_light *lights = R->lights = wrt_xcalloc(nl ? nl : 1, sizeof *lights);
    for (uint32_t i = 0; i < nl; i++) {
        const wrt_light *s = &sc->lights[i];
        copy_name(lights[i].name, s->name);
        lights[i].type = (uint32_t)s->type;
        memcpy(lights[i].color, s->color, sizeof lights[i].color);
        lights[i].pos[0] = s->pos.x; lights[i].pos[1] = s->pos.y; lights[i].pos[2] = s->pos.z;
        lights[i].dir[0] = s->dir.x; lights[i].dir[1] = s->dir.y; lights[i].dir[2] = s->dir.z;
        lights[i].intensity = s->intensity;
        lights[i].range = s->range;
        lights[i].inner_cone = s->inner_cone;
        lights[i].outer_cone = s->outer_cone;
    }
    uint32_t nn = R->nn;
    char (*names)[64] = R->names = wrt_xcalloc(nn ? nn : 1, 64);
    for (uint32_t i = 0; i < nn; i++) copy_name(names[i], sc->names[i]);
    wrt_gto_camera *cam = &R->cam;
    memset(cam, 0, sizeof *cam);
    const wrt_camera *sca = &sc->camera;
    cam->pos[0] = sca->pos.x; cam->pos[1] = sca->pos.y; cam->pos[2] = sca->pos.z;
    cam->dir[0] = sca->dir.x; cam->dir[1] = sca->dir.y; cam->dir[2] = sca->dir.z;
    cam->up[0] = sca->up.x; cam->up[1] = sca->up.y; cam->up[2] = sca->up.z;
    cam->yfov = sca->yfov; cam->aspect = sca->aspect; cam->znear = sca->znear; cam->zfar = sca->zfar;
    R->stats = c->stats;
}

/* The file as planned: its sections in order, the header and the section table. */
typedef struct gto_plan {
    wsec secs[GTO_MAX_WRITTEN];
    int nsec;
    uint32_t hsize;
    alignas(8) uint8_t head[sizeof(gto_header) + sizeof(gto_section) * GTO_MAX_WRITTEN];
} gto_plan;

static const uint64_t zero_col = 0;

/* The sections in their order; empty ones point at a zero word. */
static void plan_sections(const wrt_gto_contents *c, const gto_records *R, gto_plan *P) {
    uint32_t nf = c->nfuncs, nk = c->nkcols;
    const uint64_t *col_start = c->col_start ? c->col_start : &zero_col;
    uint64_t nnz = col_start[nf], knnz = nk ? c->kcol_start[nk] : 0;
    const char *prov = c->provenance ? c->provenance : "";
    wsec secs[SEC_KNOWN] = {
        {SEC_QUADS, R->nq, R->quads}, {SEC_MATERIALS, R->nm, R->mats}, {SEC_LIGHTS, R->nl, R->lights},
        {SEC_CAMERA, 1, &R->cam}, {SEC_NAMES, R->nn, R->names}, {SEC_FKEYS, nf, c->fkeys},
        {SEC_COL_START, (uint64_t)nf + 1, col_start}, {SEC_ROWS, nnz, c->rows},
        {SEC_VALS, nnz, c->vals}, {SEC_STATS, 1, &R->stats}, {SEC_PROVENANCE, strlen(prov), prov},
        {SEC_KKEYS, nk, c->kkeys}, {SEC_KCOL_START, (uint64_t)nk + 1, c->kcol_start},
        {SEC_KROWS, knnz, c->krows}, {SEC_KVALS, knnz, c->kvals}, {SEC_SRCMAP, R->nq, R->srcmap},
        {SEC_OPCODE, R->opcode_id == SEC_OPCODE ? R->opcode_size : 0, R->opcode},
        {SEC_NORMALS, R->nq, R->normals},
        {SEC_TEXTURES, R->textures_size, R->textures},
    };
    /* Without K and the source map the file is version 1.0 with its 11 sections, byte
     * for byte as before they existed: the minor is the lowest that has everything the
     * file holds (plan_header). */
    P->nsec = 0;
    for (int i = 0; i < SEC_KNOWN; i++) {
        uint32_t id = secs[i].id;
        if (id == 0 || (id >= SEC_KKEYS && id <= SEC_KVALS && !nk) || (id == SEC_SRCMAP && !R->srcmap) ||
            (id == SEC_TEXTURES && !R->textures) || (id == SEC_NORMALS && !R->normals) ||
            ((id == SEC_KROWS || id == SEC_KVALS) && R->kcode))
            continue;
        if ((id == SEC_ROWS || id == SEC_VALS) ? R->opcode != NULL : id == SEC_OPCODE && R->opcode_id != SEC_OPCODE)
            continue;
        if (id == SEC_COL_START && R->opcode_id == SEC_OPSTREAM) continue; /* rebuilt on load from opstream */
        P->secs[P->nsec++] = secs[i];
    }
    if (c->nctree) P->secs[P->nsec++] = (wsec){SEC_CTREE, c->nctree, c->ctree}; /* critical: version 2.0 */
    if (R->kcode) P->secs[P->nsec++] = (wsec){SEC_KCODE, R->kcode_size, R->kcode}; /* critical: version 2.0 */
    if (R->opcode_id == SEC_OPSTREAM) P->secs[P->nsec++] = (wsec){SEC_OPSTREAM, R->opcode_size, R->opcode}; /* 3.0 */
    static const uint32_t csend_one = 1;
    if (c->nctree && c->ctree_senders) P->secs[P->nsec++] = (wsec){SEC_CSEND, 1, &csend_one}; /* critical: 2.0 */

    static const uint64_t nothing = 0;
    for (int i = 0; i < P->nsec; i++)
        if (!P->secs[i].data) P->secs[i].data = &nothing; /* only for empty sections */
}

/* Header, table, and the checks the reader will make, on our own input. */
static wrt_status plan_header(const char *path, const wrt_gto_contents *c, const gto_records *R, gto_plan *P) {
    const int nsec = P->nsec;
    const wsec *secs = P->secs;
    uint32_t nk = c->nkcols;
    const uint32_t hsize = P->hsize = (uint32_t)(sizeof(gto_header) + sizeof(gto_section) * (size_t)nsec);
    uint8_t *head = P->head;
    memset(head, 0, sizeof P->head);
    gto_header *h = (gto_header *)head;
    gto_section *tab = (gto_section *)(head + sizeof(gto_header));
    memcpy(h->magic, GTO_MAGIC, GTO_MAGIC_LEN);
    h->byte_order = GTO_BOM;
    /* compact entries: 3.0 (2.0 with opcode_v2); a cluster tree or compact K: 2.0; float
     * entries: 1.x as before (the lowest that has it all) */
    h->version_major = R->opcode_id == SEC_OPSTREAM ? WRT_GTO_VERSION
                       : R->opcode || c->nctree || R->kcode ? WRT_GTO_VERSION_OPCODE : WRT_GTO_VERSION_FLOAT;
    h->version_minor = h->version_major != WRT_GTO_VERSION_FLOAT ? 0 : R->textures ? GTO_MINOR_TEXTURES
                       : R->normals ? GTO_MINOR_NORMALS : R->srcmap ? GTO_MINOR_SRCMAP : nk ? GTO_MINOR_K : 0;
    h->nsections = (uint32_t)nsec;
    h->header_size = hsize;
    h->op_kind = c->op_kind;

    wrt_gto view;
    memset(&view, 0, sizeof view);
    view.nquads = R->nq; view.nmaterials = R->nm; view.nlights = R->nl; view.nnames = R->nn;
    view.nfuncs = c->nfuncs; view.quads = R->quads; view.materials = R->mats; view.fkeys = c->fkeys;
    view.col_start = c->col_start ? c->col_start : &zero_col;
    view.nnz = view.col_start[c->nfuncs];
    view.nblocks = R->nblocks;
    view.nkcols = nk; view.knnz = nk ? c->kcol_start[nk] : 0; view.kkeys = c->kkeys; view.kcol_start = c->kcol_start;
    view.knblocks = R->knblocks;
    vctx v;
    memset(&v, 0, sizeof v);
    v.g = &view;
    uint64_t off = hsize;
    wrt_status st = WRT_OK;
    for (int i = 0; i < nsec && st == WRT_OK; i++) {
        uint32_t es = gto_sec_elem(secs[i].id);
        if (secs[i].id == SEC_KCODE) /* the float entries it encodes, checked as a 1.x file's */
            for (uint32_t id = SEC_KROWS; id <= SEC_KVALS && !v.bad; id++) {
                gto_scan_section(id == SEC_KROWS ? (const void *)c->krows : (const void *)c->kvals, view.knnz,
                                 gto_sec_elem(id), gto_sec_checker(id), &v);
                if (v.bad) st = wrt_fail(WRT_ERR_INVALID_ARG, "refusing to write %s: %s: %s", path, gto_sec_name(id), v.err);
            }
        if (st != WRT_OK) break;
        tab[i].id = secs[i].id;
        tab[i].elem_size = es;
        tab[i].offset = gto_align_up(off);
        tab[i].count = secs[i].count;
        tab[i].size = secs[i].count * es;
        tab[i].checksum = gto_scan_section(secs[i].data, secs[i].count, es, gto_sec_checker(secs[i].id), &v);
        off = tab[i].offset + tab[i].size;
        if (v.bad)
            st = wrt_fail(WRT_ERR_INVALID_ARG, "refusing to write %s: %s: %s", path,
                          gto_sec_name(secs[i].id), v.err);
    }
    if (st == WRT_OK) {
        gto_check_quad_ranges(&v);
        if (v.bad) st = wrt_fail(WRT_ERR_INVALID_ARG, "refusing to write %s: quads: %s", path, v.err);
    }
    h->file_size = off;
    h->header_checksum = wrt_gto_checksum(head, hsize);
    return st;
}

/* The temporary: unnamed where the file system allows (O_TMPFILE: nothing is left
 * behind whatever kills us), else named PATH.tmp.PID.XXXXXX and armed for the
 * signal handler; a later write to the same path removes a named one whose process
 * is gone. Header, table and sections with their zero padding, then fsync. */
static wrt_status write_temporary(const char *path, const gto_plan *P, wrt_gto_pending *p) {
    const int nsec = P->nsec;
    const uint32_t hsize = P->hsize;
    const gto_section *tab = (const gto_section *)(P->head + sizeof(gto_header));
    wrt_status st = tmp_create(path, p);
    if (st != WRT_OK) return st;
    char proc[64];
    snprintf(proc, sizeof proc, "/proc/self/fd/%d", p->fd);
    if (write_hook) write_hook(p->tmp ? p->tmp : proc);
    mode_t um = umask(0);
    umask(um);
    static const uint8_t zeros[GTO_ALIGN];
    int bad = fchmod(p->fd, 0666 & ~um) != 0 || write_all(p->fd, P->head, hsize) != 0;
    uint64_t at = hsize;
    for (int i = 0; i < nsec && !bad; i++) {
        bad = write_all(p->fd, zeros, tab[i].offset - at) != 0 ||
              write_all(p->fd, P->secs[i].data, tab[i].size) != 0;
        at = tab[i].offset + tab[i].size;
    }
    if (!bad) bad = fsync(p->fd) != 0;
    if (bad) {
        int e = errno;
        wrt_gto_discard(p);
        st = wrt_fail(WRT_ERR_IO, "cannot write %s: %s", path, strerror(e));
    }
    return st;
}

wrt_status wrt_gto_write_pending(const char *path, const wrt_gto_contents *c, wrt_gto_pending *p) {
    if (!p) return wrt_fail(WRT_ERR_INVALID_ARG, "wrt_gto_write_pending: no result");
    memset(p, 0, sizeof *p);
    p->fd = -1;
    p->slot = -1;
    if (!path || !c || !c->scene) return wrt_fail(WRT_ERR_INVALID_ARG, "wrt_gto_write: no path or contents");
    wrt_status st = check_contents(path, c);
    if (st != WRT_OK) return st;
    gto_records R;
    memset(&R, 0, sizeof R);
    R.nq = (uint32_t)c->scene->nquads;
    R.nm = (uint32_t)c->scene->nmaterials;
    R.nl = (uint32_t)c->scene->nlights;
    R.nn = (uint32_t)c->scene->nnames;
    st = build_quads(path, c, &R);
    if (st == WRT_OK && c->compact) st = encode_entries(path, c, &R);
    if (st == WRT_OK && c->compact && !c->k_float && c->nkcols) st = encode_k(path, c, &R);
    if (st == WRT_OK) {
        build_scene_records(c, &R);
        R.textures = gto_build_textures(c->scene, &R.textures_size); /* docs/textures.md */
        gto_plan P;
        plan_sections(c, &R, &P);
        st = plan_header(path, c, &R, &P);
        if (st == WRT_OK) st = write_temporary(path, &P, p);
    }
    free_records(&R);
    return st;
}

wrt_status wrt_gto_write(const char *path, const wrt_gto_contents *c) {
    wrt_gto_pending p;
    wrt_status st = wrt_gto_write_pending(path, c, &p);
    if (st == WRT_OK) st = wrt_gto_commit(&p);
    return st;
}

wrt_status wrt_gto_open_pending(const wrt_gto_pending *p, wrt_gto *out) {
    memset(out, 0, sizeof *out);
    if (!p || p->fd < 0) return wrt_fail(WRT_ERR_INVALID_ARG, "wrt_gto_open_pending: nothing pending");
    void *map; size_t len;
    wrt_status st = gto_map_fd(p->fd, p->path, &map, &len);
    if (st != WRT_OK) return st;
    return gto_adopt_map(map, len, p->path, out);
}

wrt_status wrt_gto_commit(wrt_gto_pending *p) {
    if (!p || p->fd < 0) return wrt_fail(WRT_ERR_INVALID_ARG, "wrt_gto_commit: nothing pending");
    wrt_status st = WRT_OK;
    int e = 0;
    if (!p->tmp) {
        /* Give the unnamed file a name (armed for the signal handler while it has one),
         * then rename it over the target: the target is the old file or the new one. */
        size_t pl = strlen(p->path);
        char *name = wrt_xmalloc(pl + 48);
        char proc[64];
        snprintf(proc, sizeof proc, "/proc/self/fd/%d", p->fd);
        static atomic_uint counter;
        int linked = 0;
        for (int tries = 0; tries < 100 && !linked; tries++) {
            snprintf(name, pl + 48, "%s.tmp.%ld.%u", p->path, (long)getpid(),
                     atomic_fetch_add(&counter, 1u));
            sigset_t all, old;
            sigfillset(&all);
            pthread_sigmask(SIG_BLOCK, &all, &old);
            if (linkat(AT_FDCWD, proc, AT_FDCWD, name, AT_SYMLINK_FOLLOW) == 0) {
                linked = 1;
                p->slot = tmp_arm(name);
            } else {
                e = errno;
            }
            pthread_sigmask(SIG_SETMASK, &old, NULL);
            if (!linked && e != EEXIST) break;
        }
        if (!linked) {
            free(name);
            wrt_gto_discard(p);
            return wrt_fail(WRT_ERR_IO, "cannot write %s: cannot name the temporary: %s", p->path ? p->path : "",
                            strerror(e));
        }
        p->tmp = name;
    }
    if (close(p->fd) != 0) { st = WRT_ERR_IO; e = errno; }
    p->fd = -1;
    /* the target checked again right before the rename: a FIFO, device or link put there
     * during the bake is refused, not replaced (common/outfile.h) */
    if (st == WRT_OK && wrt_output_check(p->path) != WRT_OK) {
        unlink(p->tmp);
        tmp_disarm(p->slot);
        p->slot = -1;
        wrt_gto_discard(p);
        return WRT_ERR_IO;
    }
    if (st == WRT_OK && rename(p->tmp, p->path) != 0) { st = WRT_ERR_IO; e = errno; }
    if (st != WRT_OK) {
        unlink(p->tmp);
        tmp_disarm(p->slot);
        p->slot = -1;
        wrt_status r = wrt_fail(WRT_ERR_IO, "cannot write %s: %s", p->path, strerror(e));
        wrt_gto_discard(p);
        return r;
    }
    tmp_disarm(p->slot);
    p->slot = -1;
    free(p->tmp);
    p->tmp = NULL; /* the name is the target's now */
    /* Make the rename durable. */
    char *dir = wrt_xmalloc(strlen(p->path) + 2);
    strcpy(dir, p->path);
    char *slash = strrchr(dir, '/');
    if (!slash) strcpy(dir, ".");
    else if (slash == dir) dir[1] = 0;
    else *slash = 0;
    int dfd = open(dir, O_RDONLY | O_DIRECTORY | O_CLOEXEC);
    if (dfd < 0 || fsync(dfd) != 0)
        wrt_log(WRT_LOG_WARN, "wrote %s but could not sync its directory: %s", p->path, strerror(errno));
    if (dfd >= 0) close(dfd);
    free(dir);
    wrt_gto_discard(p);
    return WRT_OK;
}

void wrt_gto_discard(wrt_gto_pending *p) {
    if (!p) return;
    if (p->fd >= 0) close(p->fd);
    if (p->tmp) unlink(p->tmp);
    tmp_disarm(p->slot);
    free(p->tmp);
    free(p->path);
    memset(p, 0, sizeof *p);
    p->fd = -1;
    p->slot = -1;
}
