/* bake_cli.h: wrt-bake's command line as a function (main.c), so that wrt-bake-mpi
 * (mpi/main_mpi.c) runs exactly the same program on each of its ranks. */
#ifndef WRT_BAKE_CLI_H
#define WRT_BAKE_CLI_H

struct wrt_bake_dist;

/* wrt-bake's whole run on argv; dist NULL for one process, else this rank's share of a
 * divided bake (dist.h; only rank 0 prints and writes). Returns the exit code. */
int wrt_bake_cli(int argc, char **argv, struct wrt_bake_dist *dist);

#endif
