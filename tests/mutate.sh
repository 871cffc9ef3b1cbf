#!/usr/bin/env bash
# mutate.sh: the mutation run (`make mutate`). Applies small deliberate faults to the core
# numerics one at a time (the kernel, the power balance, the series and its tail,
# compression, the player's projection, multiply and synthesis, channel handling, the
# BRDF, the .gto reader), rebuilds what each needs into BUILD/mutate, runs the tests
# that should notice (fast cases only), restores the file, and prints
# "N caught, N survived" with every survivor named. Not part of `make test` (minutes).
#
# Each fault is a table entry below: the file, an exact code snippet that must occur
# exactly once in it, and its replacement (several find/repl pairs make one fault), so
# that after a file is renamed only its path needs updating. An entry whose snippet is
# missing or not unique is reported as stale and counts against the run. The tree is
# restored even when the run is interrupted (trap); a restored file is touched so that
# the next build recompiles it.
#
# Usage: tests/mutate.sh [--build DIR] [--check] [--list] [--min-score PCT] [ID...]
#   --build DIR      the build folder (default build); it need not exist yet
#   --check          only verify that every snippet matches exactly once (seconds)
#   --list           print the table's ids and descriptions
#   --min-score PCT  fail unless at least PCT% of the faults run are caught (CI: 90)
#   ID...            run only these faults; an id the table does not have is refused
# A first argument that names an existing folder is taken as --build (older callers).
# A run in which no fault ran fails: "0 caught, 0 survived" is never a pass.
set -u
cd "$(dirname "$0")/.."
build=build; check_only=0; list_only=0; min_score=0; only=()
while [ $# -gt 0 ]; do
    a=$1; shift
    case "$a" in
    --check) check_only=1 ;;
    --list) list_only=1 ;;
    --build) [ $# -gt 0 ] || { echo "mutate: --build needs a folder" >&2; exit 1; }; build=$1; shift ;;
    --min-score)
        [[ "${1:-}" =~ ^[0-9]+$ ]] && [ "$1" -le 100 ] || { echo "mutate: --min-score needs a percentage 0..100, got '${1:-}'" >&2; exit 1; }
        min_score=$1; shift ;;
    -*) echo "mutate: unknown option $a" >&2; exit 1 ;;
    *) if [ -d "$a" ] && [ ${#only[@]} -eq 0 ] && [ "$build" = build ]; then build=$a; else only+=("$a"); fi ;;
    esac
done
B=$build/mutate
jobs=${JOBS:-2}

# ---------------------------------------------------------------- the faults ----
# mutation ID: what the fault does
#   file PATH        (once per entry)
#   find TEXT        exact snippet, leading spaces of the line ignored
#   repl TEXT        its replacement (find/repl pairs may repeat)
#   run PROG [CASE..] a test program of BUILD/tests, or a tests/*.sh script
read -r -d '' TABLE <<'EOF'
mutation kernel-closed-form: Lambert's point-to-polygon form factor 1% high
  file precompute/dto.c
  find return fabs(sum) / (2 * WRT_PI);
  repl return fabs(sum) / (1.98 * WRT_PI);
  run test_bake test_point_polygon test_form_factors test_distribution

mutation link-kernel-x1.05: every diffuse link's value scaled by 1.05
  file precompute/dto.c
  find for (int ch = 0; ch < 3; ch++) e[n].v[ch] = (float)(d->g * rho[ch]);
  repl for (int ch = 0; ch < 3; ch++) e[n].v[ch] = (float)(1.05 * d->g * rho[ch]);
  run test_bake test_form_factors test_distribution test_reciprocity

mutation gauss-nodes: the 2 x 2 Gauss-Legendre nodes of a receiver quadrant moved (0.2887 -> 0.3)
  file precompute/dto.c
  find fu = 0.5 + ((s & 1) ? 0.28867513459481287 : -0.28867513459481287);
  repl fu = 0.5 + ((s & 1) ? 0.3 : -0.3);
  run test_bake test_form_factors test_distribution

mutation swapped-levels: a swapped leaf keeps the unswapped level scale
  file precompute/dto.c
  find if (swapped) scale = wrt_pow2((int)rn.level - (int)sn.level) / ns;
  repl if (0) scale = wrt_pow2((int)rn.level - (int)sn.level) / ns;
  run test_bake test_form_factors test_distribution

mutation transposed-albedo: the symmetric entry T[s][r] takes the sender's albedo, not the receiver's
  file precompute/dto.c
  find for (int ch = 0; ch < 3; ch++) { vt[ch] = g * rho_r[ch]; mt = fmax(mt, fabs(vt[ch])); }
  repl for (int ch = 0; ch < 3; ch++) { vt[ch] = g * rho[ch]; mt = fmax(mt, fabs(vt[ch])); }
  run test_bake test_reciprocity test_coloured_furnace
  run test_accuracy

mutation haar-sign: the type-3 wavelet's sign on a child quadrant loses its v factor
  file common/basis.h
  find return type == 1 ? s1 : type == 2 ? s2 : type == 3 ? s1 * s2 : 1.0;
  repl return type == 1 ? s1 : type == 2 ? s2 : type == 3 ? s1 : 1.0;
  run test_bake test_distribution

mutation concentric-map: the concentric map's angle off by 5% in one wedge
  file common/basis.h
  find if (fabs(sx) > fabs(sy)) { r = sx; phi = (M_PI / 4) * (sy / sx); }
  repl if (fabs(sx) > fabs(sy)) { r = sx; phi = (M_PI / 4.2) * (sy / sx); }
  run test_bake test_glossy_receiver test_glossy_power_balance

mutation balance-power: a closed scene's column power set 0.1% above what it emits
  file precompute/balance.c
  find for (int ch = 0; ch < 3; ch++) want[ch] = rho[ch] * emitted;
  repl for (int ch = 0; ch < 3; ch++) want[ch] = 1.001 * rho[ch] * emitted;
  run test_bake test_power_balance test_furnace

mutation balance-channel: the balance's re-derived root entries use channel 0's albedo for all channels
  file precompute/balance.c
  find if (m * wfloor >= floor_) for (int ch = 0; ch < 3; ch++) o[ch] = rho[ch] * t;
  repl if (m * wfloor >= floor_) for (int ch = 0; ch < 3; ch++) o[ch] = rho[0] * t;
  run test_bake test_coloured_furnace
  run test_accuracy

mutation balance-merged-centre: a leaf's links merged into one closed form take it at the leaf's centre even where one was near
  file precompute/balance.c
  find vr[li] += side_integral(Sq, e, Rq, rpoly, b->plane_eps, (how & EVAL_ON_E) ? 4 : 1) / jq;
  repl vr[li] += side_integral(Sq, e, Rq, rpoly, b->plane_eps, 1) / jq;
  run test_accuracy
  run test_bake test_power_balance test_form_factors

mutation balance-merged-high: a leaf's links merged into one closed form 1% high
  file precompute/balance.c
  find vr[li] += side_integral(Sq, e, Rq, rpoly, b->plane_eps, (how & EVAL_ON_E) ? 4 : 1) / jq;
  repl vr[li] += 1.01 * side_integral(Sq, e, Rq, rpoly, b->plane_eps, (how & EVAL_ON_E) ? 4 : 1) / jq;
  run test_accuracy
  run test_bake test_power_balance test_form_factors

mutation balance-never-closed: the closed-scene test always says open
  file precompute/balance.c
  find c.closed = scene_closed(b, &open_quad);
  repl c.closed = 0 * scene_closed(b, &open_quad);
  run test_bake test_furnace test_power_balance

mutation balance-keep-links: where an occluder may lie between, what the links miss is not added
  file precompute/balance.c
  find for (int ch = 0; ch < 3; ch++) o[ch] = cur[((size_t)ri * ncol + j) * 3 + ch] + (keep ? rho[ch] * ad : 0);
  repl for (int ch = 0; ch < 3; ch++) o[ch] = cur[((size_t)ri * ncol + j) * 3 + ch];
  run test_stress test_furnace_occluded
  run test_accuracy

mutation series-tail: the geometric tail of each column's power 1% short (series_power.c
sets every column's power of G - I since session 4; series.c's own tail now shapes only
the light within a column, and its 1% went unseen by every flux test)
  file precompute/series_power.c
  find u[i] += v[i] * rr / (1 - rr);
  repl u[i] += 0.99 * v[i] * rr / (1 - rr);
  run test_stress test_furnace

mutation series-tail-channel: the power tail of every channel from channel 0's ratio
  file precompute/series_power.c
  find double rr = r[i % 3];
  repl double rr = r[0];
  run test_bake test_coloured_furnace

mutation series-stop: the series stops when the last term is 1% of the sum
  file precompute/series.c
  find if (C->energy_left < 1e-6) break;
  repl if (C->energy_left < 1e-2) break;
  run test_bake test_coloured_furnace
  run test_stress test_furnace test_furnace_occluded
  run test_accuracy

mutation compress-power: compression hands a column's dropped power to its kept entries twice
  file precompute/sparse.c
  find acc[ACC_STRIDE * i + ch] = v + lost * fabs(v) / wsum;
  repl acc[ACC_STRIDE * i + ch] = v + 2 * lost * fabs(v) / wsum;
  run test_bake test_compression_keeps_power test_small_quads_furnace test_coloured_furnace
  run test_stress test_furnace test_furnace_occluded
  run test_accuracy

mutation sparse-apply-channel: the bake's sparse multiply uses channel 0 of x for every channel
  file precompute/sparse.c
  find for (int c = 0; c < 3; c++) y[3 * i + c] += (double)m->val[3 * k + c] * xj[c];
  repl for (int c = 0; c < 3; c++) y[3 * i + c] += (double)m->val[3 * k + c] * xj[0];
  run test_sparse test_apply_brute_force

mutation projection-falloff: the projection's point light falls off as 1 / d^2.1
  file player/relight_internal.h
  find double e = l->intensity * cosx * inv_d / d2;
  repl double e = l->intensity * cosx * inv_d / pow(d2, 1.05);
  run test_relight test_far_light_root test_cell_irradiance

mutation projection-spot: the spot cone's falloff linear, not squared
  file player/relight_internal.h
  find e *= s * s;
  repl e *= s;
  run test_relight test_mean_irradiance test_exact_zeros

mutation projection-colour: the light's colour applied as channel 0 to every channel of E
  file player/relight_project.c
  find for (int c = 0; c < 3; c++) w->oval[w->on * 3 + c] = (float)(cv * col[c]);
  repl for (int c = 0; c < 3; c++) w->oval[w->on * 3 + c] = (float)(cv * col[0]);
  run test_relight test_multiply_dense
  run test_accuracy

mutation occluder-tree-sphere: the occluder tree prunes a node by its centre, not its whole sphere
  file player/relight_project.c
  find if (v3_dot(v3_sub(nd->c, pp->o[k]), pp->nrm[k]) + nd->rad * nlen[k] <= 0) return 1;
  repl if (v3_dot(v3_sub(nd->c, pp->o[k]), pp->nrm[k]) + 0.5 * nd->rad * nlen[k] <= 0) return 1;
  run test_relight test_occluder_tree

mutation multiply-channel-0: the player's multiply uses channel 0 of E for all three channels
  file player/relight_multiply.c
  find __m128 ev = _mm_set_ps(0.0f, e[2], e[1], e[0]);
  repl __m128 ev = _mm_set_ps(0.0f, e[0], e[0], e[0]);
  find x[1] += e[1] * v[1];
  repl x[1] += e[0] * v[1];
  find x[2] += e[2] * v[2];
  repl x[2] += e[0] * v[2];
  run test_relight test_multiply_dense
  run test_accuracy

mutation multiply-last-entry: the player's multiply drops each column's last entry
  file player/relight_multiply.c
  find uint64_t end = op->col_start[s + 1], vend = end < op->nnz ? end : op->nnz - 1; /* 4-float loads stay inside */
  repl uint64_t end = op->col_start[s + 1] - 1, vend = end < op->nnz ? end : op->nnz - 1; /* 4-float loads stay inside */
  run test_relight test_multiply_dense

mutation synthesis-albedo: diffuse synthesis radiance rho E / pi off by 2%
  file player/relight_synth.c
  find double k = q->parallelogram ? ldexp(1.0, Lt) * sqrt(WRT_PI / q->area) / WRT_PI : 1;
  repl double k = q->parallelogram ? ldexp(1.0, Lt) * sqrt(WRT_PI / q->area) / (1.02 * WRT_PI) : 1;
  run test_relight test_round_trip test_mean_irradiance

mutation brdf-f0: the dielectric's F0 0.04 -> 0.06
  file common/brdf.c
  find f0[c] = 0.04 * (1 - metal) + base * metal;
  repl f0[c] = 0.06 * (1 - metal) + base * metal;
  run test_brdf test_fresnel

mutation brdf-schlick-exponent: Schlick's (1 - v.h)^5 -> ^4
  file common/brdf.c
  find double s5 = pow(1 - vh, 5);
  repl double s5 = pow(1 - vh, 4);
  run test_brdf test_fresnel test_ggx_albedo_quadrature

mutation brdf-smith: the Smith visibility 10% high
  file common/brdf.c
  find return s > 0 ? 0.5 / s : 0;
  repl return s > 0 ? 0.55 / s : 0;
  run test_brdf test_ggx_albedo_quadrature test_white_furnace

mutation brdf-ggx-d: GGX's D with t instead of t^2 in the denominator
  file common/brdf.c
  find return a2 / (WRT_PI * t * t);
  repl return a2 / (WRT_PI * t);
  run test_brdf test_ggx_albedo_quadrature test_fresnel

mutation brdf-table-scale: the shared angular BRDF table 2% high
  file common/brdf_table.c
  find for (int k = 0; k < WRT_BRDF_TABLE_NANG * 3; k++) out[k] *= WRT_PI;
  repl for (int k = 0; k < WRT_BRDF_TABLE_NANG * 3; k++) out[k] *= 1.02 * WRT_PI;
  run test_brdf test_brdf_table
  run test_bake test_glossy_power_balance

mutation gto-section-checksum: the reader ignores a section's checksum
  file formats/gto_read.c
  find if (sum != s->checksum)
  repl if (0 && sum != s->checksum)
  run test_gto test_flipped_bytes test_checksum
  run tests/play.sh

mutation gto-header-checksum: the reader ignores the header's checksum
  file formats/gto_read.c
  find if (sum != h->header_checksum)
  repl if (0 && sum != h->header_checksum)
  run test_gto test_flipped_bytes test_checksum

mutation triangle-centroid: a triangle's three quads meet 3% off its centroid (they no longer tile it)
  file formats/scene.c
  find wrt_v3 v[3] = {a, b, c}, g = v3_scale(v3_add(v3_add(a, b), c), 1.0 / 3.0);
  repl wrt_v3 v[3] = {a, b, c}, g = v3_scale(v3_add(v3_add(a, b), c), 1.0 / 3.09);
  run test_triangles test_triangle_form_factors test_icosphere_furnace

mutation linear-display-limited: the linear display keeps the slope limiter (data-dependent again)
  file common/reconstruct_run.c
  find limit = 0;
  repl limit = 1;
  run test_reconstruct test_linear_superposes

mutation curved-as-flat: a curved mesh's quads keep their facets' cells and limited slopes (the tiles)
  file common/reconstruct_run.c
  find int curved = rc->curved[q] && !facets;
  repl int curved = 0 && rc->curved[q] && !facets;
  run test_reconstruct test_smooth_strip

mutation apart-weight-lost: the sum's walk decides the nodes apart but no longer raises their columns' weights
  file precompute/cluster_send.c
  find if (x->apart_w && x->apart[p]) x->apart_w[x->root[t->slot[p]]] *= x->apart_f;
  repl if (0 && x->apart_w && x->apart[p]) x->apart_w[x->root[t->slot[p]]] *= x->apart_f;
  run test_cluster test_albedo_split

mutation bands-in-place-unscratched: the right factor's bands are made in place reading the column being overwritten
  file precompute/sparse_order.c
  find bands_col(k, c0, row, val, m, x->row_w, x->power_w, x->out);
  repl bands_col(k, c0, a->row + c0, a->val + 3 * c0, m, x->row_w, x->power_w, x->out);
  run test_sparse test_product_skip

mutation order-skip-power: the plain series' skip also skips rows that carry power (all banded by size)
  file precompute/sparse_order.c
  find return pw && pw[i] != 0 ? -1 : band_of(entry_size(&a->val[3 * e], rw, i), tp);
  repl return 0 ? -1 : band_of(entry_size(&a->val[3 * e], rw, i), tp);
  run test_sparse test_product_skip_order

mutation order-skip-band: the plain series' skip leaves out one band too many (contributions up to twice its limit)
  file precompute/sparse.c
  find int e = exponent_of((double)o->top[k] * bm / lim) + 1;
  repl int e = exponent_of((double)o->top[k] * bm / lim);
  run test_sparse test_product_skip_order

mutation receivers-ancestors-dropped: the receivers' tree rows keep no ancestor of a kept entry
  file precompute/cluster_ops.c
  find keep[i] = p == -2 || (p >= 0 && need[p] == epoch2);
  repl keep[i] = 0;
  run test_triangles test_icosphere_furnace_many

mutation cluster-eps-old: the cluster oracle's power criterion back at 1e-4 (the far wall's tiles)
  file precompute/cluster.h
  find #define WRT_CLUSTER_EPS_DEFAULT 1e-6
  repl #define WRT_CLUSTER_EPS_DEFAULT 1e-4
  run test_cluster test_far_wall

mutation open-cancel-ignored: the open goes on when the progress callback returns 0
  file player/relight_base.c
  find return r->opt.progress(r->opt.progress_user, fraction) != 0;
  repl (void)r->opt.progress(r->opt.progress_user, fraction); return 1;
  run tests/runtime.sh
EOF

# ------------------------------------------------------------------ machinery ----
# one run at a time in a tree: two would mutate and restore the same files
mkdir -p "$build"
exec 9>"$build/.mutate.lock"
flock -n 9 || { echo "mutate: another run is using this tree ($build/.mutate.lock)" >&2; exit 1; }
tmp=$(mktemp -d /tmp/wrt_mutate_XXXXXX)
mutated=""   # the file currently mutated, restored by the trap
restore() {
    if [ -n "$mutated" ] && [ -f "$tmp/orig" ]; then
        cp "$tmp/orig" "$mutated" && touch "$mutated"
        mutated=""
    fi
}
child=""     # the build or test running now: waited for in the background, so that a
             # signal is handled at once (bash defers traps while a foreground child runs)
trap 'restore; rm -rf "$tmp"' EXIT
trap 'echo "mutate: interrupted, restoring the tree" >&2; [ -n "$child" ] && kill -TERM "$child" 2>/dev/null; restore; exit 4' INT TERM
run_child() { "$@" & child=$!; wait "$child"; local rc=$?; child=""; return $rc; }

# apply FILE PAIRS-FILE [--check]: every snippet must occur exactly once; replaces them.
apply() {
    python3 - "$1" "$2" "${3:-}" <<'PY'
import sys
path, pairs, check = sys.argv[1], sys.argv[2], sys.argv[3] == "--check"
src = open(path).read()
lines = open(pairs).read().split("\n")
out = src
for i in range(0, len(lines) - 1, 2):
    find, repl = lines[i], lines[i + 1]
    n = src.count(find)
    if n != 1:
        print(f"snippet found {n} times in {path}: {find}")
        sys.exit(1)
    out = out.replace(find, repl, 1)
if not check:
    open(path, "w").write(out)
PY
}

ids=(); descs=(); files=(); pairfiles=(); runs=()
n=-1
while IFS= read -r line; do
    line="${line#"${line%%[![:space:]]*}"}"
    case "$line" in
    "mutation "*)
        n=$((n + 1)); rest=${line#mutation }
        ids[n]=${rest%%:*}; descs[n]=${rest#*: }; files[n]=""; runs[n]=""
        pairfiles[n]=$tmp/pairs.$n; : >"${pairfiles[n]}" ;;
    "file "*) files[n]=${line#file } ;;
    "find "*) printf '%s\n' "${line#find }" >>"${pairfiles[n]}" ;;
    "repl "*) printf '%s\n' "${line#repl }" >>"${pairfiles[n]}" ;;
    "run "*) runs[n]+="${line#run }"$'\n' ;;
    esac
done <<<"$TABLE"
total=$((n + 1))

if [ $list_only -eq 1 ]; then
    for ((i = 0; i < total; i++)); do printf '%-26s %-22s %s\n' "${ids[i]}" "${files[i]}" "${descs[i]}"; done
    exit 0
fi

# every id asked for must be in the table (a typo, or a folder name, would run nothing)
for x in "${only[@]}"; do
    known=0
    for ((i = 0; i < total; i++)); do [ "${ids[i]}" = "$x" ] && known=1; done
    [ $known -eq 1 ] || { echo "mutate: no fault named '$x' (--list shows them; a build folder is given with --build)" >&2; exit 1; }
done

selected() {
    [ ${#only[@]} -eq 0 ] && return 0
    local x; for x in "${only[@]}"; do [ "$x" = "$1" ] && return 0; done; return 1
}

stale=0
for ((i = 0; i < total; i++)); do
    selected "${ids[i]}" || continue
    if [ ! -f "${files[i]}" ]; then echo "stale ${ids[i]}: no file ${files[i]}"; stale=$((stale + 1)); continue; fi
    msg=$(apply "${files[i]}" "${pairfiles[i]}" --check) || { echo "stale ${ids[i]}: $msg"; stale=$((stale + 1)); }
done
if [ $check_only -eq 1 ]; then
    echo "mutate --check: $total faults, $stale stale"
    [ $stale -eq 0 ]; exit
fi
[ $stale -eq 0 ] || { echo "mutate: update the stale entries above first"; exit 1; }

# targets a run line needs
targets_for() {
    local prog=$1
    case "$prog" in
    tests/*.sh) echo "$B/wrt-bake $B/wrt-play $B/wrt-compare $B/wrt-scenegen $B/tests/test_image $B/tests/test_play" \
                     "$B/tests/runtime_api $B/tests/runtime_core $B/tests/runtime_instances" ;; # runtime.sh's too
    *) echo "$B/tests/$prog $B/wrt-bake" ;;
    esac
}

echo "mutate: building the unmutated tree into $B"
if ! run_child make --no-print-directory BUILD="$B" -j"$jobs" all >"$tmp/build.log" 2>&1; then
    tail -n 20 "$tmp/build.log"; echo "mutate: the unmutated tree does not build"; exit 1
fi
caught=0; survived=0; broken=0; survivors=(); t_all=$(date +%s)
for ((i = 0; i < total; i++)); do
    selected "${ids[i]}" || continue
    id=${ids[i]}; f=${files[i]}; t0=$(date +%s)
    cp "$f" "$tmp/orig"; mutated=$f
    apply "$f" "${pairfiles[i]}" >/dev/null || { restore; echo "stale $id"; broken=$((broken + 1)); continue; }
    tg=""
    while IFS= read -r r; do [ -n "$r" ] && tg+=" $(targets_for ${r%% *})"; done <<<"${runs[i]}"
    # shellcheck disable=SC2086
    if ! run_child make --no-print-directory BUILD="$B" -j"$jobs" $tg >"$tmp/build.log" 2>&1; then
        restore; broken=$((broken + 1)); echo "did not build  $id"; tail -n 5 "$tmp/build.log"; continue
    fi
    verdict=survived; by=""
    while IFS= read -r r; do
        [ -n "$r" ] || continue
        prog=${r%% *}; cases=""; [ "$prog" != "$r" ] && cases=${r#* }
        if [[ "$prog" == tests/*.sh ]]; then
            WRT_BUILD=$B run_child timeout 600 bash "$prog" "$B" >"$tmp/run.log" 2>&1; rc=$?
        else
            # shellcheck disable=SC2086
            WRT_BUILD=$B run_child timeout 600 "$B/tests/$prog" $cases >"$tmp/run.log" 2>&1; rc=$?
            for c in $cases; do # a misspelt case would run nothing and pass
                grep -q "ok $c (" "$tmp/run.log" || { echo "stale $id: $prog has no case $c"; broken=$((broken + 1)); }
            done
        fi
        if [ $rc -ne 0 ]; then
            verdict=caught
            by="$prog: $(grep -m1 -E '^FAIL|FAIL ' "$tmp/run.log" | cut -c1-150)"
            [ $rc -ge 124 ] && by="$prog: exit $rc (timeout or crash)"
            break
        fi
    done <<<"${runs[i]}"
    restore
    dt=$(( $(date +%s) - t0 ))
    if [ $verdict = caught ]; then
        caught=$((caught + 1)); printf 'caught    %-26s %4ds  %s\n' "$id" "$dt" "$by"
    else
        survived=$((survived + 1)); survivors+=("$id"); printf 'SURVIVED  %-26s %4ds  %s\n' "$id" "$dt" "${descs[i]}"
    fi
done
echo "mutate: $(( $(date +%s) - t_all )) s"
[ $broken -eq 0 ] || echo "$broken faults did not build or apply"
[ ${#survivors[@]} -eq 0 ] || echo "survivors: ${survivors[*]}"
echo "$caught caught, $survived survived"
ran=$((caught + survived))
[ $ran -gt 0 ] || { echo "mutate: no fault ran"; exit 1; }
score=$((100 * caught / ran))
echo "mutate: score $score% ($caught of $ran caught; required ${min_score}%)"
[ $broken -eq 0 ] || exit 1
[ $score -ge "$min_score" ] || exit 1
[ "$min_score" -gt 0 ] || [ $survived -eq 0 ]
