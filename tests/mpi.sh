#!/usr/bin/env bash
# mpi.sh: wrt-bake-mpi (docs/mpi.md) against wrt-bake. The same bytes at -np 1, 2 and 3
# (oversubscribed) on cornell and a 9 x 9 maze (with and without --clusters), the atrium
# with --clusters (the tree series and the quads') and the glossy asset (its first-bounce
# operator K), each compared
# with the single process's file: the ranks divide the DTO's pairs, the balance's senders,
# the pair list's occluder search and the series' product columns, and any slip in a
# merge's order or a share computed twice or not at all changes the file. Then the
# failures: a rank that fails (rank 0 cannot write its output), a rank killed with
# SIGKILL, and SIGINT to mpirun each end every rank with a non-zero exit and a message,
# and leave no file. Skipped, with the reason, where mpirun or build/wrt-bake-mpi is
# missing (`make deps` installs Open MPI; `make` then builds it). About 80 s of CPU.
# Usage: tests/mpi.sh BUILD. Prints "mpi: N passed, N failed".
set -u
build=${1:-build}
cd "$(dirname "$0")/.."
. tests/lib.sh mpi
bake=$build/wrt-bake
mpibake=$build/wrt-bake-mpi
gen=$build/wrt-scenegen
if ! command -v mpirun >/dev/null 2>&1; then
    skipped "wrt-bake-mpi: no mpirun here (make deps installs openmpi-bin)"; summary; exit
fi
if [ ! -x "$mpibake" ]; then
    skipped "wrt-bake-mpi: $mpibake not built (make builds it where mpicc is found)"; summary; exit
fi
tmp=$(mktemp -d /tmp/wrt_mpi_XXXXXX)
trap 'rm -rf "$tmp"' EXIT
mpi() { mpirun --allow-run-as-root --oversubscribe ${MPIX:-} -np "$@"; }
# config=sanitize: Open MPI's own allocations outlive MPI_Finalize; not ours to report
[[ "$build" == *sanitize* ]] && export ASAN_OPTIONS="${ASAN_OPTIONS:+$ASAN_OPTIONS:}detect_leaks=0"

# ---- the same bytes
"$gen" maze --cells 9 -o "$tmp/maze9.gltf" >/dev/null 2>&1 || ko "wrt-scenegen maze --cells 9"
"$gen" atrium --detail 0.5 -o "$tmp/atrium.gltf" >/dev/null 2>&1 || ko "wrt-scenegen atrium"
same() { # NAME NPS SCENE OPTIONS...
    local name=$1 nps=$2 scene=$3; shift 3
    if ! "$bake" "$scene" -o "$tmp/$name.gto" --quiet "$@" >/dev/null 2>"$tmp/err"; then
        ko "$name: wrt-bake failed"; show_err; return
    fi
    for n in $nps; do
        if ! mpi "$n" "$mpibake" "$scene" -o "$tmp/$name-$n.gto" --quiet "$@" >"$tmp/out" 2>"$tmp/err"; then
            ko "$name: wrt-bake-mpi -np $n failed"; show_err; continue
        fi
        cmp -s "$tmp/$name.gto" "$tmp/$name-$n.gto" && ok "$name -np $n: the same bytes as wrt-bake" ||
            ko "$name -np $n: the file differs from wrt-bake's"
        rm -f "$tmp/$name-$n.gto"
    done
}
same cornell "1 2 3" assets/cornell.gltf -q 3
same maze9 "2 3" "$tmp/maze9.gltf" -q 1
# --clusters: the series in the senders' tree basis, each rank holding its column range
# of the terms and the sum (series.c series_tree_share_start)
same cornell-clusters "2 3" assets/cornell.gltf -q 3 --clusters
same maze9-clusters "2 3" "$tmp/maze9.gltf" -q 1 --clusters
# the DTO's merges in rounds of 256 KiB (the pairs' 12 MB in tens of rounds, where the
# default 32 MiB takes each in one): the rounds' count agreed, each rank's pairs in order
if MPIX="-x WRT_MPI_MERGE_BYTES=262144" mpi 3 "$mpibake" "$tmp/maze9.gltf" -o "$tmp/maze9-r.gto" --quiet -q 1 \
    >"$tmp/out" 2>"$tmp/err"; then
    cmp -s "$tmp/maze9.gto" "$tmp/maze9-r.gto" && ok "maze9 -np 3, merges in 256 KiB rounds: the same bytes" ||
        ko "maze9 -np 3, merges in 256 KiB rounds: the file differs from wrt-bake's"
else
    ko "maze9: wrt-bake-mpi -np 3 in 256 KiB rounds failed"; show_err
fi
# the atrium at detail 0.5 (1,060 elements; the cluster links' tasks divided too), the
# series capped at 3 bounces (each bounce is the same divided product): 26 s of CPU for
# the three bakes (detail 0.25 with the whole series took 15 s; detail 1, 93 s for one)
same atrium-clusters "2 3" "$tmp/atrium.gltf" -q 1 --clusters --max-bounces 3
# the terms whole (--series-columns 0: each bounce's product divided between the ranks;
# by default each rank takes its columns through every bounce on its own, series_cols.c)
same atrium-whole "3" "$tmp/atrium.gltf" -q 1 --clusters --max-bounces 3 --series-columns 0
# and there the ranges re-cut before a product wherever a rank's cost is 0.1% above the
# mean (by default 10%, where the work saved is worth it: series_recut.c): the term's and
# the sum's columns that change owner move between the ranks, and the file keeps its bytes
if MPIX="-x WRT_MPI_RECUT=1.001 -x WRT_MPI_REPORT=1" mpi 3 "$mpibake" "$tmp/atrium.gltf" -o "$tmp/atrium-rc.gto" \
    --quiet -q 1 --clusters --max-bounces 3 --series-columns 0 >"$tmp/out" 2>"$tmp/err"; then
    n=$(grep -c "re-cut [1-9]" "$tmp/err")
    cmp -s "$tmp/atrium-whole.gto" "$tmp/atrium-rc.gto" && [ "$n" = 3 ] &&
        ok "atrium-clusters -np 3, the ranges re-cut on the 3 ranks: the same bytes" ||
        ko "atrium-clusters -np 3 re-cut: $n ranks re-cut, the file $(cmp -s "$tmp/atrium-whole.gto" "$tmp/atrium-rc.gto" && echo same || echo differs)"
else
    ko "atrium-clusters: wrt-bake-mpi -np 3 with re-cuts failed"; show_err
fi
# --clusters' series runs in the senders' tree basis (series.c), each rank its column
# range of the terms and the sum; the quads' series (--clusters-series-quads) streamed, by
# the ranks' shares of the terms and the right factor
same atrium-quads-series "2 3" "$tmp/atrium.gltf" -q 1 --clusters --clusters-series-quads --max-bounces 3
same glossy "3" assets/glossy.gltf -q 1   # the first-bounce operator K's pairs and the glossy balances
# the summary on stdout is rank 0's alone, once
mpi 2 "$mpibake" assets/cornell.gltf -o "$tmp/c.gto" -q 2 >"$tmp/out" 2>"$tmp/err"
[ "$(grep -c '^baked ' "$tmp/out")" = 1 ] && ok "one summary from two ranks" || ko "summary lines: $(grep -c '^baked ' "$tmp/out")"

# ---- failures: no file, every rank gone, a message
gone() { # PIDS...: none of them is alive after a moment
    local p t
    for t in 1 2 3 4 5 6 7 8 9 10; do
        local alive=0
        for p in "$@"; do kill -0 "$p" 2>/dev/null && alive=1; done
        [ $alive = 0 ] && return 0
        sleep 0.5
    done
    return 1
}
mkdir -p "$tmp/w"
# a rank that fails: rank 0 cannot make its output (the others go on baking until it ends them)
mpi 2 "$mpibake" "$tmp/maze9.gltf" -o "$tmp/w/no/such/dir/out.gto" --quiet -q 1 >"$tmp/out" 2>"$tmp/err"
rc=$?
[ $rc -ne 0 ] && grep -q "rank 0 of 2 stopped" "$tmp/err" && grep -q "wrt-bake: error" "$tmp/err" &&
    ok "a failing rank ends the bake (exit $rc, its error and the rank named)" || { ko "failing rank: exit $rc"; show_err; }
# ranks: the children of this mpirun (Open MPI starts the local ranks itself)
ranks_of() { ps -o pid= --ppid "$1" 2>/dev/null | tr -d ' '; }
wait_ranks() { # MPIRUN-PID N: the ranks' pids once N are running (empty after 20 s)
    local t r
    for ((t = 0; t < 80; t++)); do
        r=$(ranks_of "$1")
        [ "$(wc -w <<<"$r")" -ge "$2" ] && { echo $r; return; }
        sleep 0.25
    done
}
# KILL-rank-series: rank 1 killed in the series, where the ranks exchange their shares of
# the terms (an all-to-all) and sum the norms rank after rank: rank 0's progress line
# "series" (--progress) says when
for how in KILL-rank INT-mpirun KILL-rank-series; do
    rm -rf "$tmp/w" && mkdir -p "$tmp/w"
    # KILL-rank and INT-mpirun wait for rank 0's "dto" progress line and bake at quality 3
    # (6 s on 3 ranks): at quality 2 the whole bake (3 s since session 8) could end inside
    # a fixed 2 s sleep, and the file was then rightly left
    show=--progress q=3
    [ $how = KILL-rank-series ] && q=2
    env --default-signal=INT mpirun --allow-run-as-root --oversubscribe -np 3 "$mpibake" "$tmp/maze9.gltf" \
        -o "$tmp/w/out.gto" $show -q $q >"$tmp/out" 2>"$tmp/err" &
    run=$!
    ranks=$(wait_ranks $run 3)
    if [ -z "$ranks" ]; then ko "$how: the 3 ranks did not start"; kill -9 $run 2>/dev/null; wait $run; continue; fi
    if [ $how = KILL-rank-series ]; then
        for ((t = 0; t < 1200; t++)); do grep -q series "$tmp/err" && break; sleep 0.1; done
        grep -q series "$tmp/err" || ko "$how: the series did not start in 120 s"
        sleep 0.2
    else
        for ((t = 0; t < 1200; t++)); do grep -q dto "$tmp/err" && break; sleep 0.1; done
        grep -q dto "$tmp/err" || ko "$how: the DTO did not start in 120 s"
        sleep 0.5 # into the DTO
    fi
    if [ $how != INT-mpirun ]; then kill -9 "$(awk '{print $2}' <<<"$ranks")"; else kill -INT $run; fi
    wait $run; rc=$?
    [ $rc -ne 0 ] && ok "$how: mpirun exits $rc" || ko "$how: mpirun exits 0"
    gone $ranks && ok "$how: every rank is gone" || ko "$how: a rank is still running"
    left=$(ls -A "$tmp/w")
    [ -z "$left" ] && ok "$how: no file left" || ko "$how: left $left"
    if [ $how != INT-mpirun ]; then
        grep -Eqi "signal 9|killed" "$tmp/err" && ok "$how: the message names the killed rank" || { ko "$how: no message"; show_err; }
    fi
    kill -9 $ranks 2>/dev/null # only ours, should any have stayed
done
summary
