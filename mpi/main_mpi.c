/* main_mpi.c: wrt-bake-mpi, wrt-bake on MPI ranks (docs/mpi.md). Every rank runs wrt-bake's
 * command line (precompute/main.c) with the same arguments and loads the scene; the bake
 * divides its DTO pairs and series products among the ranks through the all-gather
 * below (precompute/dist.h) and rank 0 writes the file as wrt-bake does (a temporary
 * renamed over the target). A rank that fails ends every rank (MPI_Abort); a rank that
 * is killed is seen by mpirun, which ends the others, whose signal handler removes the
 * temporary. WRT_MPI_REPORT=1 prints each rank's CPU seconds, peak memory and bytes;
 * WRT_MPI_MERGE_BYTES sets the merges' round size. */
#include <mpi.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#ifdef __GLIBC__
#include <malloc.h>
#endif

#include "../precompute/bake_cli.h"
#include "../precompute/budget.h"
#include "../precompute/dist.h"

/* Bytes per rank per round of MPI_Allgatherv, whose counts are ints */
#define ROUND_BYTES ((uint64_t)1 << 30)

/* CPU and wall seconds spent in the all-gathers (waiting for the slowest rank included:
 * Open MPI polls), for WRT_MPI_REPORT */
static double gather_cpu, gather_wall;

static wrt_status mpi_allgather_timed(void *user, const void *mine, uint64_t len, void **all, uint64_t *lens);

static wrt_status mpi_allgather(void *user, const void *mine, uint64_t len, void **all, uint64_t *lens) {
    double c0 = wrt_dist_cpu_now(), w0 = wrt_now();
    wrt_status st = mpi_allgather_timed(user, mine, len, all, lens);
    gather_cpu += wrt_dist_cpu_now() - c0;
    gather_wall += wrt_now() - w0;
    return st;
}

static wrt_status mpi_allgather_timed(void *user, const void *mine, uint64_t len, void **all, uint64_t *lens) {
    (void)user;
    int nr;
    MPI_Comm_size(MPI_COMM_WORLD, &nr);
    if (MPI_Allgather(&len, 1, MPI_UINT64_T, lens, 1, MPI_UINT64_T, MPI_COMM_WORLD) != MPI_SUCCESS)
        return wrt_fail(WRT_ERR_IO, "MPI_Allgather of the block sizes failed");
    uint64_t total = 0, most = 0;
    uint64_t *at = malloc((size_t)nr * sizeof *at);
    int *cnt = malloc((size_t)nr * sizeof *cnt), *disp = malloc((size_t)nr * sizeof *disp);
    if (!at || !cnt || !disp) { free(at); free(cnt); free(disp); return wrt_fail(WRT_ERR_NOMEM, "out of memory"); }
    for (int r = 0; r < nr; r++) {
        at[r] = total;
        total += lens[r];
        if (lens[r] > most) most = lens[r];
    }
    uint8_t *buf = wrt_xmalloc(total ? total : 1);
    int rank;
    MPI_Comm_rank(MPI_COMM_WORLD, &rank);
    wrt_status st = WRT_OK;
    if (most <= ROUND_BYTES && total <= INT32_MAX) { /* one round: straight into buf, no copy */
        for (int r = 0; r < nr; r++) {
            cnt[r] = (int)lens[r];
            disp[r] = (int)at[r];
        }
        if (MPI_Allgatherv(mine, cnt[rank], MPI_BYTE, buf, cnt, disp, MPI_BYTE, MPI_COMM_WORLD) != MPI_SUCCESS)
            st = wrt_fail(WRT_ERR_IO, "MPI_Allgatherv failed");
        free(at); free(cnt); free(disp);
        if (st != WRT_OK) { free(buf); return st; }
        *all = buf;
        return WRT_OK;
    }
    /* in rounds of at most ROUND_BYTES from each rank, through a packed buffer */
    uint8_t *tmp = wrt_xmalloc((size_t)(most < ROUND_BYTES ? most : ROUND_BYTES) * (size_t)nr + 1);
    for (uint64_t off = 0; off < most && st == WRT_OK; off += ROUND_BYTES) {
        int sum = 0;
        for (int r = 0; r < nr; r++) {
            uint64_t left = lens[r] > off ? lens[r] - off : 0;
            cnt[r] = (int)(left < ROUND_BYTES ? left : ROUND_BYTES);
            disp[r] = sum;
            sum += cnt[r];
        }
        if (MPI_Allgatherv((const uint8_t *)mine + (cnt[rank] ? off : 0), cnt[rank], MPI_BYTE, tmp, cnt, disp,
                           MPI_BYTE, MPI_COMM_WORLD) != MPI_SUCCESS) {
            st = wrt_fail(WRT_ERR_IO, "MPI_Allgatherv failed");
            break;
        }
        for (int r = 0; r < nr; r++)
            if (cnt[r]) memcpy(buf + at[r] + off, tmp + disp[r], (size_t)cnt[r]);
    }
    free(tmp); free(at); free(cnt); free(disp);
    if (st != WRT_OK) { free(buf); return st; }
    *all = buf;
    return WRT_OK;
}

/* The all-to-all (dist.h): the counts, then the bytes in rounds of at most ROUND_BYTES
 * from each rank (each pair's share of a round ROUND_BYTES / nranks), through packed
 * buffers whose displacements are ints */
static wrt_status mpi_alltoall_timed(const void *send, const uint64_t *sendlens, void **recv, uint64_t *recvlens) {
    int nr;
    MPI_Comm_size(MPI_COMM_WORLD, &nr);
    if (MPI_Alltoall((void *)sendlens, 1, MPI_UINT64_T, recvlens, 1, MPI_UINT64_T, MPI_COMM_WORLD) != MPI_SUCCESS)
        return wrt_fail(WRT_ERR_IO, "MPI_Alltoall of the block sizes failed");
    uint64_t stot = 0, rtot = 0, most = 0, chunk = ROUND_BYTES / (uint64_t)nr;
    uint64_t *sat = wrt_xcalloc((size_t)nr, sizeof *sat), *rat = wrt_xcalloc((size_t)nr, sizeof *rat);
    for (int q = 0; q < nr; q++) {
        sat[q] = stot;
        rat[q] = rtot;
        stot += sendlens[q];
        rtot += recvlens[q];
        if (sendlens[q] > most) most = sendlens[q];
        if (recvlens[q] > most) most = recvlens[q];
    }
    uint64_t all_most;
    if (MPI_Allreduce(&most, &all_most, 1, MPI_UINT64_T, MPI_MAX, MPI_COMM_WORLD) != MPI_SUCCESS) {
        free(sat); free(rat);
        return wrt_fail(WRT_ERR_IO, "MPI_Allreduce of the block sizes failed");
    }
    uint8_t *buf = wrt_xmalloc(rtot ? rtot : 1);
    /* one round whose offsets fit in ints: straight from and into the callers' buffers (no
     * packed copies: the series' gather of the stored operator on rank 0 is its size) */
    int direct = all_most <= chunk && stot <= INT32_MAX && rtot <= INT32_MAX;
    size_t cap = direct ? 1 : (size_t)(all_most < chunk ? all_most : chunk) * (size_t)nr + 1;
    uint8_t *stmp = direct ? (uint8_t *)send : wrt_xmalloc(cap), *rtmp = direct ? buf : wrt_xmalloc(cap);
    int *sc = wrt_xcalloc((size_t)nr, sizeof *sc), *sd = wrt_xcalloc((size_t)nr, sizeof *sd);
    int *rc = wrt_xcalloc((size_t)nr, sizeof *rc), *rd = wrt_xcalloc((size_t)nr, sizeof *rd);
    wrt_status st = WRT_OK;
    for (uint64_t off = 0; off < all_most; off += chunk) {
        int ss = 0, rs = 0;
        for (int q = 0; q < nr; q++) {
            uint64_t sl = sendlens[q] > off ? sendlens[q] - off : 0, rl = recvlens[q] > off ? recvlens[q] - off : 0;
            sc[q] = (int)(sl < chunk ? sl : chunk);
            rc[q] = (int)(rl < chunk ? rl : chunk);
            sd[q] = direct ? (int)sat[q] : ss;
            rd[q] = direct ? (int)rat[q] : rs;
            if (sc[q] && !direct) memcpy(stmp + ss, (const uint8_t *)send + sat[q] + off, (size_t)sc[q]);
            ss += sc[q];
            rs += rc[q];
        }
        if (MPI_Alltoallv(stmp, sc, sd, MPI_BYTE, rtmp, rc, rd, MPI_BYTE, MPI_COMM_WORLD) != MPI_SUCCESS) {
            st = wrt_fail(WRT_ERR_IO, "MPI_Alltoallv failed");
            break;
        }
        for (int q = 0; q < nr && !direct; q++)
            if (rc[q]) memcpy(buf + rat[q] + off, rtmp + rd[q], (size_t)rc[q]);
    }
    if (!direct) { free(stmp); free(rtmp); } free(sc); free(sd); free(rc); free(rd); free(sat); free(rat);
    if (st != WRT_OK) { free(buf); return st; }
    *recv = buf;
    return WRT_OK;
}

static wrt_status mpi_alltoall(void *user, const void *send, const uint64_t *sendlens, void **recv, uint64_t *recvlens) {
    (void)user;
    double c0 = wrt_dist_cpu_now(), w0 = wrt_now();
    wrt_status st = mpi_alltoall_timed(send, sendlens, recv, recvlens);
    gather_cpu += wrt_dist_cpu_now() - c0;
    gather_wall += wrt_now() - w0;
    return st;
}

static void report(const wrt_bake_dist *d) {
    const char *e = getenv("WRT_MPI_REPORT");
    if (!e || strcmp(e, "1")) return;
    fprintf(stderr,
            "wrt-bake-mpi: rank %d of %d: cpu dto %.2f s (cluster links %.2f, assembly %.2f) series %.2f s; peak rss %.1f MB (to the series %.1f MB); sent dto %llu series %llu "
            "counters %llu bytes; received dto %llu series %llu counters %llu bytes; in all-gathers cpu %.2f s "
            "wall %.2f s; the tree series' products cpu %.2f s, cost %llu, re-cut %u times, %llu bytes sent in them\n",
            d->rank, d->nranks, d->cpu_dto, d->cpu_links, d->cpu_assemble, d->cpu_series, (double)wrt_bake_peak_rss_bytes() / (1024.0 * 1024.0), (double)d->peak_dto / (1024.0 * 1024.0),
            (unsigned long long)d->bytes_sent[0], (unsigned long long)d->bytes_sent[1],
            (unsigned long long)d->bytes_sent[2], (unsigned long long)d->bytes_recv[0],
            (unsigned long long)d->bytes_recv[1], (unsigned long long)d->bytes_recv[2], gather_cpu, gather_wall,
            d->cpu_products, (unsigned long long)d->products_cost, d->recuts, (unsigned long long)d->recut_bytes);
}

int main(int argc, char **argv) {
    if (MPI_Init(&argc, &argv) != MPI_SUCCESS) {
        fprintf(stderr, "wrt-bake-mpi: error: MPI_Init failed (run it with mpirun)\n");
        return 1;
    }
#ifdef __GLIBC__
    /* Blocks of 1 MiB and more mapped on their own, not from the heap: freed, they go
     * back to the system at once, and the series' sum grows in place (mremap) instead of
     * being copied beside itself. glibc's threshold otherwise rises with the largest
     * block freed (up to 32 MiB), after which a rank's terms and sum came from the heap,
     * whose freed holes stayed resident: on the atrium at detail 1, rank 1 of 2 peaked at
     * 384.6 MB so and at 314.5 MB with the threshold fixed (docs/mpi.md, session 11). */
    mallopt(M_MMAP_THRESHOLD, 1 << 20);
#endif
    wrt_bake_dist d = {.allgather = mpi_allgather, .alltoall = mpi_alltoall};
    /* WRT_MPI_SHARE=0: every rank holds the series' terms whole (the products gathered),
     * for comparison (docs/mpi.md) */
    const char *share = getenv("WRT_MPI_SHARE");
    if (share && !strcmp(share, "0")) d.alltoall = NULL;
    /* WRT_MPI_MERGE_BYTES=N: the per-item merges in rounds of N bytes of all the ranks'
     * records (dist.h's piece_bytes; default 32 MiB), for tests/mpi.sh's many rounds */
    const char *mb = getenv("WRT_MPI_MERGE_BYTES");
    if (mb && *mb) d.piece_bytes = strtoull(mb, NULL, 10);
    /* WRT_MPI_RECUT=X: the tree series' ranges re-cut wherever a rank's cost is above X
     * times the mean (tests/mpi.sh's many re-cuts); -1: cut once (docs/mpi.md's comparison) */
    const char *rc_at = getenv("WRT_MPI_RECUT");
    if (rc_at && *rc_at) d.recut_at = strtod(rc_at, NULL);
    MPI_Comm_rank(MPI_COMM_WORLD, &d.rank);
    MPI_Comm_size(MPI_COMM_WORLD, &d.nranks);
    int rc = wrt_bake_cli(argc, argv, &d);
    if (rc != 0) {
        /* the others may wait in a collective for this rank: end them all */
        fprintf(stderr, "wrt-bake-mpi: rank %d of %d stopped with exit code %d: ending every rank, no file written\n",
                d.rank, d.nranks, rc);
        fflush(stderr);
        MPI_Abort(MPI_COMM_WORLD, rc);
        return rc;
    }
    report(&d);
    MPI_Finalize();
    return 0;
}
