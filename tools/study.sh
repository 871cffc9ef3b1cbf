#!/usr/bin/env bash
# tools/study.sh: the accuracy/time study (the paper's section 6, Figures 6-9, for our
# scenes). For each scene, bakes every quality of a sweep (wrt-bake --json; the median of
# 3 runs when a bake takes under 10 s, else 1 run), compares all the bakes with one
# path-traced reference (wrt-compare: relative RMSE of the indirect light over cell
# averages and in the camera's image, the reference's error floor, the player's median
# milliseconds per light change; the image error of the smooth display and of the Haar
# cells before it), times the path tracer (wrt-ref) per path per pixel so that each row
# states the path tracer's seconds to the same image error, renders the pictures of the
# default quality (OUT/NAME_panel.png: Haar | smooth | path tracer | error map), and
# writes OUT/NAME.csv, OUT/NAME.json, OUT/NAME.png
# (error against bake time, file bytes and milliseconds per light change, floor shown)
# and OUT/README.md (the tables). Needs jq and gnuplot (tools/install-deps.sh).
#
# usage: tools/study.sh [-b BUILD] [-o OUTDIR] [-q "S1 S2 ..."] [-d S] [-P] [SCENE.gltf ...]
#   a setting S is a quality, optionally followed by glossy knobs: gN (--glossy-quality N),
#   aN (--max-angular-level N), kN (--first-bounce-level N; k0: no first-bounce operator);
#   e.g. "5", "5g3a2", "5k0"
#   -d: the setting whose pictures are drawn (default 5, else the last)
#   -P: no bakes; redraw the plots and the tables from OUTDIR/*.json
#   -R: reuse the bakes (and their timings) in BUILD/study/NAME newer than wrt-bake and the
#       scene, and the comparison if newer than wrt-compare and the bakes, with the same options
#   default scenes: assets/cornell.gltf assets/maze.gltf assets/glossy.gltf, swept over
#   1..7, 1..6 and 1..5, and atrium:1.5, over 1..5 (the higher qualities take minutes to
#   hours on 2 cores: see docs/study/README.md); any other scene over 1..6 unless -q is given.
#   A scene atrium:D is generated (wrt-scenegen atrium --detail D) into BUILD/study: the
#   Sponza proxy of the scale benchmark (D 1.5: 5,048 elements, baked with the cluster
#   hierarchy), compared at 2 x 2 cells a quad with 20M cell paths a light (below).
#   WRT_STUDY_COMPARE: wrt-compare's reference options for every scene (default below);
#   WRT_STUDY_PICTURE_SPP: the pictures' reference paths per pixel (default 1024).
set -euo pipefail
cd "$(dirname "$0")/.."
build=build; out=docs/study; quals=""; redraw=0; reuse=0; picq=""
while getopts "b:o:q:d:PRh" opt; do
    case $opt in
        b) build=$OPTARG ;;
        o) out=$OPTARG ;;
        q) quals=$OPTARG ;;
        d) picq=$OPTARG ;;
        P) redraw=1 ;;
        R) reuse=1 ;;
        *) sed -n '2,25p' "$0"; exit 1 ;;
    esac
done
shift $((OPTIND - 1))
scenes=("$@")
[ ${#scenes[@]} -gt 0 ] || scenes=(assets/cornell.gltf assets/maze.gltf assets/glossy.gltf atrium:1.5)
# --sub 16: the bake's image is sampled at 16 x 16 points a pixel, so that pixels across a
# crease or a silhouette weigh its two sides as the path tracer's pixel integral does; at
# the compare's default 4 x 4 that coverage error alone was most of the maze's image error
# (6.1% -> 3.1% debiased, the same bake and reference) and 0.2 points of cornell's.
compare_default="--lights 5 --cell-paths 10000000 --width 64 --spp 4096 --sub 16 --bench 21"
# the atrium's elements are many and small (5,048 at detail 1.5): 2 x 2 cells each
# (4 x 4 would leave about 125 reference paths a cell), and twice the cell paths
compare_atrium="--lights 5 --cells 2 --cell-paths 20000000 --width 64 --spp 4096 --sub 16 --bench 21"
for t in jq gnuplot; do command -v $t >/dev/null || { echo "study: needs $t (make deps)" >&2; exit 1; }; done
for p in wrt-bake wrt-compare; do [ -x "$build/$p" ] || { echo "study: no $build/$p (make all)" >&2; exit 1; }; done
mkdir -p "$out"
t_start=$(date +%s)

default_quals() {
    case $(basename "$1" .gltf) in
        cornell) echo "1 2 3 4 5 6 7" ;;
        maze) echo "1 2 3 4 5 6" ;;
        glossy) echo "1 2 3 4 5 6 7 5k0" ;;
        cornell_glossy) echo "1 2 3 4 5 6 7 5k0" ;;
        atrium*) echo "1 2 3 4 5" ;;
        *) echo "1 2 3 4 5 6" ;;
    esac
}

# setting_args S: wrt-bake's options for setting S (a quality and glossy knobs, see usage).
setting_args() {
    local s=$1 q rest
    q=${s%%[!0-9]*}; rest=${s#"$q"}
    [ -n "$q" ] || { echo "study: bad setting '$s'" >&2; exit 1; }
    printf -- '-q %s' "$q"
    while [ -n "$rest" ]; do
        case ${rest:0:1} in
            g) printf -- ' --glossy-quality %s' "${rest:1:1}" ;;
            a) printf -- ' --max-angular-level %s' "${rest:1:1}" ;;
            k) printf -- ' --first-bounce-level %s' "${rest:1:1}" ;;
            *) echo "study: bad setting '$s'" >&2; exit 1 ;;
        esac
        rest=${rest:2}
    done
}

# plot_scene JSON PNG: cell and image error (log) against bake s, MB and ms (log), each
# with the reference's floor dashed in the same colour; labels are the qualities. The axes
# span the data (and the floors), the legend is drawn once.
plot_scene() {
    local json=$1 png=$2 dat name cf imf ylo yhi
    dat=$(mktemp)
    name=$(jq -r '.name' "$json")
    cf=$(jq '.reference.cell_floor' "$json"); imf=$(jq '.reference.image_floor' "$json")
    ylo=$(jq '[.reference.cell_floor, .reference.image_floor, (.rows[] | .cell_rmse, .image_rmse)]
              | map(select(. > 0)) | min / 1.25' "$json")
    yhi=$(jq '[.rows[] | .cell_rmse, .image_rmse] | max * 1.25' "$json")
    # a setting with knobs (5k0, 5g3a2) is drawn as its own point: a blank line before it
    # breaks the quality sweep's line there (gnuplot), so the sweep is not joined to it
    jq -r '.rows[] | "\(.setting // .quality) \(.bake_s) \(.bytes / 1e6) \(.cpu_ms_per_light_change) \(.cell_rmse) \(.image_rmse)"' \
        "$json" | awk '$1 !~ /^[0-9]+$/ { print "" } { print }' >"$dat"
    gnuplot <<EOF
set terminal pngcairo size 1500,500 font "sans,11" noenhanced
set output "$png.tmp"
set multiplot title "$name: relative RMSE of the indirect light against the path-traced reference (point labels: setting)"
set logscale xy
set grid
set autoscale xfix
# 1-2-5 ticks, so that an axis within one decade still has labels
set xtics ()
set for [e=-3:5] xtics add (sprintf("%g", 10.0**e) 10.0**e, sprintf("%g", 2 * 10.0**e) 2 * 10.0**e, sprintf("%g", 5 * 10.0**e) 5 * 10.0**e)
set ylabel "relative RMSE"
set format y "%g"
set ytics add ("0.002" 0.002, "0.005" 0.005, "0.02" 0.02, "0.05" 0.05, "0.2" 0.2, "0.5" 0.5)
set yrange [$ylo:$yhi]
set offsets graph 0.08, graph 0.08, 0, 0
cf = $cf; imf = $imf
# three panels fitted to the data (a margin of 8% of a panel), no legend in them ...
unset key
set size 0.333, 0.84
do for [c in "2 3 4"] {
  col = c + 0
  set origin (col - 2) * 0.333, 0
  if (col == 2) { set xlabel "bake time (s)" }
  if (col == 3) { set xlabel "file size (MB)" }
  if (col == 4) { set xlabel "player CPU ms per light change (median)" }
  plot "$dat" using col:5 with linespoints lw 2 pt 7 lc rgb "#1f77b4", \
       "" using col:5:1 with labels offset 0.8,0.8 font ",9", \
       "" using col:6 with linespoints lw 2 pt 5 lc rgb "#d62728", \
       "" using col:6:1 with labels offset 0.8,0.8 font ",9", \
       cf with lines dt 2 lw 2 lc rgb "#1f77b4", \
       imf with lines dt 2 lw 2 lc rgb "#d62728"
}
# ... and one legend for the three, in a row above them
set origin 0, 0.83
set size 1, 0.09
unset border; unset tics; unset xlabel; unset ylabel; unset grid; unset logscale
set xrange [0:1]; set yrange [0:1]
set key center center horizontal maxrows 1 width 3
plot NaN with linespoints lw 2 pt 7 lc rgb "#1f77b4" title "cell averages", \
     NaN with linespoints lw 2 pt 5 lc rgb "#d62728" title "image", \
     NaN with lines dt 2 lw 2 lc rgb "#1f77b4" title "path tracer noise (cells)", \
     NaN with lines dt 2 lw 2 lc rgb "#d62728" title "path tracer noise (image)"
unset multiplot
EOF
    rm -f "$dat"
    mv "$png.tmp" "$png"
}

[ $redraw -eq 0 ] || { scenes=(); for j in "$out"/*.json; do plot_scene "$j" "${j%.json}.png"; done; }
for scene in "${scenes[@]}"; do
    compare_args=${WRT_STUDY_COMPARE:-$compare_default}
    if [[ $scene == atrium:* ]]; then
        detail=${scene#atrium:}
        name=atrium; work=$build/study/$name
        mkdir -p "$work"
        "$build/wrt-scenegen" atrium --detail "$detail" -o "$work/atrium.gltf.new"
        # the scene's file keeps its time unless it changed, so that -R can reuse the bakes
        if cmp -s "$work/atrium.gltf.new" "$work/atrium.gltf"; then rm "$work/atrium.gltf.new"
        else mv "$work/atrium.gltf.new" "$work/atrium.gltf"; fi
        scene=$work/atrium.gltf; label="wrt-scenegen atrium --detail $detail"
        compare_args=${WRT_STUDY_COMPARE:-$compare_atrium}
    else
        name=$(basename "$scene"); name=${name%.*}; label=$scene
        work=$build/study/$name
        mkdir -p "$work"
    fi
    qs=${quals:-$(default_quals "$scene")}
    gtos=()
    echo "study: $name, qualities $qs" >&2
    for q in $qs; do
        gto=$work/q$q.gto
        if [ $reuse -eq 1 ] && [ -s "$work/bake_q$q.json" ] && [ "$gto" -nt "$build/wrt-bake" ] &&
           [ "$gto" -nt "$scene" ]; then
            echo "study: reusing $gto" >&2
        else
            rm -f "$work"/bake_q$q.[1-3].json
            # shellcheck disable=SC2046
            "$build/wrt-bake" "$scene" -o "$gto" $(setting_args "$q") --json --quiet >"$work/bake_q$q.1.json"
            runs=1
            if jq -e '.seconds.total < 10' "$work/bake_q$q.1.json" >/dev/null; then
                for r in 2 3; do
                    # shellcheck disable=SC2046
                    "$build/wrt-bake" "$scene" -o "$gto" $(setting_args "$q") --json --quiet >"$work/bake_q$q.$r.json"
                done
                runs=3
            fi
            # The run with the median total time gives every phase's figures.
            jq -s --argjson runs $runs 'sort_by(.seconds.total) | .[(length / 2 | floor)] + {runs: $runs}' \
                "$work"/bake_q$q.[1-3].json >"$work/bake_q$q.json" 2>/dev/null ||
                jq --argjson runs 1 '. + {runs: $runs}' "$work/bake_q$q.1.json" >"$work/bake_q$q.json"
        fi
        jq -r --arg s "$q" '"study: \($s): \(.seconds.total) s, \(.bytes) bytes (\(.runs) run(s))"' \
            "$work/bake_q$q.json" >&2
        gtos+=("$gto")
    done
    # The comparison, unless -R and the last one is newer than wrt-compare and every bake,
    # with the same bakes and options.
    stale=1
    if [ $reuse -eq 1 ] && [ -s "$work/compare.json" ] && [ "$work/compare.json" -nt "$build/wrt-compare" ] &&
       [ "$(cat "$work/compare.args" 2>/dev/null)" = "${gtos[*]} $compare_args" ]; then
        stale=0
        for g in "${gtos[@]}"; do [ "$work/compare.json" -nt "$g" ] || stale=1; done
    fi
    if [ $stale -eq 1 ]; then
        # shellcheck disable=SC2086
        "$build/wrt-compare" "$scene" "${gtos[@]}" $compare_args >"$work/compare.json.tmp"
        mv "$work/compare.json.tmp" "$work/compare.json"
        echo "${gtos[*]} $compare_args" >"$work/compare.args"
    else
        echo "study: reusing $work/compare.json" >&2
    fi
    # The player's time per light change, in a pass of its own (no path tracing beside it).
    "$build/wrt-compare" "$scene" "${gtos[@]}" --bench-only --bench 41 >"$work/bench.json"
    # The alternative: the path tracer's seconds per path per pixel for the same image
    # (same machine, all cores, the scene's light): it reaches a relative RMSE e in
    # spp_ref (floor / e)^2 paths per pixel, floor being the reference's noise at spp_ref.
    "$build/wrt-ref" "$scene" --spp 256 --width "$(jq '.reference.image.width' "$work/compare.json")" \
        --height "$(jq '.reference.image.height' "$work/compare.json")" --json --out "$work/pt" >"$work/pt.json"
    # The pictures: the default quality (5, else the last) beside the path tracer, 192 wide.
    qd=${picq:-$(for q in $qs; do echo "$q"; done | grep -x 5 || for q in $qs; do echo "$q"; done | tail -n 1)}
    "$build/wrt-compare" "$scene" "$work/q$qd.gto" --lights 1 --cell-paths 100000 --width 192 --spp "${WRT_STUDY_PICTURE_SPP:-1024}" \
        --bench 1 --images "$work/img" >/dev/null
    cp "$work/img_panel.png" "$out/${name}_panel.png"

    # One row per quality: the bake's figures and the comparison's.
    for q in $qs; do jq --arg s "$q" '. + {setting: $s}' "$work/bake_q$q.json"; done | jq -s '.' >"$work/bakes.json"
    jq --slurpfile b "$work/bakes.json" --slurpfile t "$work/bench.json" --slurpfile pt "$work/pt.json" \
       --arg name "$name" --arg scene "$label" --arg qd "$qd" \
       --arg nproc "$(nproc)" --arg date "$(date -u +%Y-%m-%dT%H:%MZ)" --arg args "$compare_args" '
      (($pt[0].image.time_s / $pt[0].image.spp)) as $spp_s | .reference.image.spp as $spp_ref |
      {scene: $scene, name: $name, date: $date, cores: ($nproc | tonumber), compare_options: $args,
       lights: .lights, cells_per_side: .cells_per_side, reference: .reference,
       pictures_setting: $qd, path_tracer_s_per_spp: $spp_s,
       rows: [range(0; .bakes | length) as $i | .bakes[$i] as $c | $b[0][$i] as $k | $t[0].bakes[$i] as $m |
         {setting: $k.setting, quality: $k.options.quality, bake_runs: $k.runs,
          dto_s: $k.seconds.dto, gto_s: $k.seconds.gto, bake_s: $k.seconds.total,
          links_dto: $k.links.dto, links_gto: $k.links.gto, links_gathered: (if $k.links.gathered > 0 then $k.links.gathered else null end),
          bytes: $c.bytes, peak_mb: $k.memory_mb.peak_rss, functions: $c.functions, entries: $c.entries,
          ms_per_light_change: $m.ms_per_light_change, ms_min: $m.ms_min,
          cpu_ms_per_light_change: $m.cpu_ms_per_light_change,
          cell_rmse: $c.cell_rmse, cell_floor: $c.cell_floor, cell_rmse_debiased: $c.cell_rmse_debiased,
          image_rmse: $c.image_rmse, image_floor: $c.image_floor, image_rmse_debiased: $c.image_rmse_debiased,
          cell_ratio: $c.cell_ratio,
          cell_rmse_smooth: $c.cell_rmse_smooth, cell_rmse_smooth_debiased: $c.cell_rmse_smooth_debiased,
          image_rmse_haar: $c.image_rmse_haar, image_rmse_haar_debiased: $c.image_rmse_haar_debiased,
          path_tracer_s: (if $c.image_rmse_debiased > 0 then
              $spp_s * $spp_ref * ($c.image_floor / $c.image_rmse_debiased) * ($c.image_floor / $c.image_rmse_debiased)
            else null end),
          per_light: $c.per_light}]}' "$work/compare.json" >"$out/$name.json.tmp"
    mv "$out/$name.json.tmp" "$out/$name.json"
    cols="setting quality bake_runs dto_s gto_s bake_s links_dto links_gto links_gathered bytes peak_mb functions entries ms_per_light_change ms_min cpu_ms_per_light_change cell_rmse cell_floor cell_rmse_debiased image_rmse image_floor image_rmse_debiased cell_ratio cell_rmse_smooth cell_rmse_smooth_debiased image_rmse_haar image_rmse_haar_debiased path_tracer_s"
    { echo "$cols" | tr ' ' ','
      jq -r --arg cols "$cols" '.rows[] as $r | [($cols | split(" "))[] | $r[.]] | @csv' "$out/$name.json"
    } >"$out/$name.csv.tmp"
    mv "$out/$name.csv.tmp" "$out/$name.csv"

    plot_scene "$out/$name.json" "$out/$name.png"
    echo "study: wrote $out/$name.csv, $out/$name.json, $out/$name.png" >&2
done

# The tables, one per scene in $out (all scenes that have a JSON there).
{
    echo "# The accuracy/time study"
    echo
    echo "Generated by \`tools/study.sh\` (\`make study\`). Per setting (a quality; gN: glossy links"
    echo "refined at quality N, aN: glossy angular level capped at N, k0: no first-bounce operator,"
    echo "the glossy surfaces' direct light bouncing through their incident angular cells): bake"
    echo "time (median of 3 runs"
    echo "when under 10 s, else 1 run), links, bytes, the bake's peak resident memory (\"peak MB\","
    echo "empty where not recorded), the player's median milliseconds per light"
    echo "change (projection + multiply + texture synthesis, no display), and the relative RMSE"
    echo "of the indirect light against the path-traced reference, mean over the lights, for"
    echo "cell averages of the incident irradiance and for the camera's image; \"floor\" is the"
    echo "reference's own noise in the same units, \"debiased\" the error with that noise taken out."
    echo "Light changes are timed in a pass of their own (41 changes); \"best ms\" is the fastest"
    echo "(the median suffers first when the machine is shared), \"CPU ms\" the median CPU time of"
    echo "the process (all threads), which other load on the machine does not inflate: the plots"
    echo "use it; \"gathered\" is empty when the bake did not compute the gathered"
    echo "operator (wrt-bake computes it only when it stores it or is given --report-gathered)."
    echo "The image is the player's smooth display (common/reconstruct.h); \"Haar image\" is the"
    echo "same bake shown as its Haar cells (the display before the reconstruction), \"smooth"
    echo "cells\" the display's cell averages. \"path tracer s\" is what the alternative costs:"
    echo "the seconds the path tracer (wrt-ref, same machine, all cores) takes to render the"
    echo "same image to the same error (debiased image error), from its time per path per pixel"
    echo "and its noise at the reference's paths per pixel; compare with ms per light change."
    for j in "$out"/*.json; do
        n=$(jq -r '.name' "$j")
        echo
        echo "## $n"
        echo
        jq -r '"\(.scene), \(.lights | length) light positions, \(.cells_per_side)x\(.cells_per_side) cells per quad, reference: \(.reference.cell_paths_per_light) paths per light over the cells, image \(.reference.image.width)x\(.reference.image.height) at \(.reference.image.spp) paths per pixel (\(.reference.seconds) s); \(.cores) cores, \(.date)."' "$j"
        echo
        echo "![$n]($n.png)"
        echo
        echo "Setting $(jq -r '.pictures_setting // .pictures_quality' "$j"), first light: Haar cells | smooth display | path tracer | error of the smooth display (|difference| / mean, black 0, white 50% and above):"
        echo
        echo "![$n pictures](${n}_panel.png)"
        echo
        echo "| setting | runs | DTO s | GTO s | bake s | links DTO | links GTO | gathered | MB | peak MB | ms/light | best ms | CPU ms | cell rmse | floor | debiased | smooth cells debiased | image rmse | floor | debiased | Haar image debiased | path tracer s |"
        echo "|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"
        jq -r '.rows[] | "| \(.setting // .quality) | \(.bake_runs) | \(.dto_s * 100 | round / 100) | \(.gto_s * 100 | round / 100) | \(.bake_s * 100 | round / 100) | \(.links_dto) | \(.links_gto) | \(.links_gathered // "–") | \(.bytes / 1e4 | round / 100) | \(.peak_mb // "–") | \(.ms_per_light_change * 100 | round / 100) | \(.ms_min * 100 | round / 100) | \(.cpu_ms_per_light_change * 100 | round / 100) | \(.cell_rmse * 1000 | round / 1000) | \(.cell_floor * 1000 | round / 1000) | \(.cell_rmse_debiased * 1000 | round / 1000) | \(.cell_rmse_smooth_debiased * 1000 | round / 1000) | \(.image_rmse * 1000 | round / 1000) | \(.image_floor * 1000 | round / 1000) | \(.image_rmse_debiased * 1000 | round / 1000) | \(.image_rmse_haar_debiased * 1000 | round / 1000) | \(if .path_tracer_s then (.path_tracer_s * 100 | round / 100) else "–" end) |"' "$j"
    done
} >"$out/README.md.tmp"
mv "$out/README.md.tmp" "$out/README.md"
echo "study: done in $(( $(date +%s) - t_start )) s; tables in $out/README.md" >&2
