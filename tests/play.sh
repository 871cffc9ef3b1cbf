#!/usr/bin/env bash
# play.sh: end-to-end tests of wrt-play. Bakes a small scene with wrt-bake, renders it
# headless to PNG and EXR and checks the pictures are not blank (read back through
# formats/image.h by build/tests/test_image), that direct + indirect = both in linear
# radiance, that the window opens under Xvfb and its screenshot is not blank, that the
# statistics, benchmark and script outputs are well formed, and that missing, truncated
# and foreign files and bad options give the documented exit codes with a message, and
# complemented bytes are refused by the checksums. A check that cannot run here (no
# xvfb-run) prints "skipped" and is counted.
# Usage: tests/play.sh BUILD. Prints "play: N passed, N failed"; non-zero exit on a failure.
set -u
build=${1:-build}
cd "$(dirname "$0")/.."
play=$build/wrt-play
bake=$build/wrt-bake
img=$build/tests/test_image
. tests/lib.sh play
lib_ko_shows_err=1 # a failure shows what the command said
tmp=$(mktemp -d /tmp/wrt_play_XXXXXX)
trap 'rm -rf "$tmp"' EXIT

if [ ! -x "$play" ] || [ ! -x "$img" ]; then
    ko "$play or $img not built"
    summary
    exit 1
fi

# Options and errors that need no scene.
check "--help exits 0" "$play" --help
check "--version exits 0" "$play" --version
expect_exit "missing file: exit 2" 2 "no such file|cannot open|i/o" "$play" "$tmp/nope.gto" --headless --out "$tmp/x.png"
printf 'this is not a gto file, just text\n%.0s' {1..50} >"$tmp/foreign.gto"
expect_exit "foreign file: exit 2" 2 "not|foreign|magic" "$play" "$tmp/foreign.gto" --headless --out "$tmp/x.png"
expect_exit "unknown option: exit 1" 1 "unknown option" "$play" x.gto --frobnicate
expect_exit "bad vector: exit 1" 1 "bad value" "$play" x.gto --light-pos 1,2
expect_exit "headless without output: exit 1" 1 "needs -o/--out" "$play" x.gto --headless
expect_exit "bad --emitter-scale: exit 1" 1 "expected M=S" "$play" x.gto --emitter-scale 3=-1

# A small baked scene.
scene=""
for s in assets/cornell.gltf assets/*.gltf; do [ -f "$s" ] && { scene=$s; break; }; done
if [ -z "$scene" ] && [ -x "$build/wrt-scenegen" ]; then
    "$build/wrt-scenegen" --all "$tmp/assets" >/dev/null 2>&1
    for s in "$tmp"/assets/cornell.gltf "$tmp"/assets/*.gltf; do [ -f "$s" ] && { scene=$s; break; }; done
fi
gto=$tmp/scene.gto
if [ -n "$scene" ] && [ -x "$bake" ]; then
    check "bake $scene (quality 1)" "$bake" "$scene" -o "$gto" -q 1 --quiet
elif [ -x "$build/tests/test_play" ]; then
    # no bake: the room test_play builds in C, with a stand-in operator
    check "write the test room (no wrt-bake)" "$build/tests/test_play" --write-gto "$gto"
else
    echo "FAIL no scene and wrt-bake, nor tests/test_play, to make a .gto"
    fail=$((fail + 1))
fi

if [ -f "$gto" ]; then
    W=(--width 200 --height 150)
    check "headless PNG" "$play" "$gto" --headless "${W[@]}" --out "$tmp/both.png"
    check "PNG not blank" "$img" --nonblank "$tmp/both.png"
    check "headless EXR" "$play" "$gto" --headless "${W[@]}" --out "$tmp/both.exr"
    check "EXR not blank" "$img" --nonblank "$tmp/both.exr"
    check "direct-only EXR" "$play" "$gto" --headless "${W[@]}" --direct-only --out "$tmp/direct.exr"
    check "indirect-only EXR" "$play" "$gto" --headless "${W[@]}" --indirect-only --out "$tmp/indirect.exr"
    check "indirect-only not blank" "$img" --nonblank "$tmp/indirect.exr"
    check "both = direct + indirect (1e-3)" "$img" --sum "$tmp/both.exr" "$tmp/direct.exr" "$tmp/indirect.exr" 1e-3
    cat "$tmp/out"

    # every light switched off: black (whatever the number of lights)
    nl=$("$play" "$gto" --headless --stats-json "$tmp/stats.json" >/dev/null 2>&1; jq '.lights | length' "$tmp/stats.json" 2>/dev/null)
    check "stats JSON parses with one entry per quad" \
        jq -e '(.quads | length) == .nquads and (.quads[0] | has("area") and has("centroid") and has("normal") and has("mesh") and has("direct") and has("indirect"))' "$tmp/stats.json"
    check "stats: some quad receives direct and indirect light" \
        jq -e '([.quads[].direct[0]] | max) > 0 and ([.quads[].indirect[0]] | max) > 0' "$tmp/stats.json"
    if [ "${nl:-0}" -ge 1 ] 2>/dev/null; then
        "$play" "$gto" --headless "${W[@]}" --lights-off "$(seq -s, 1 "$nl")" --out "$tmp/off.exr" 2>"$tmp/err"
        "$img" --stats "$tmp/off.exr" >"$tmp/out" 2>>"$tmp/err"
        if grep -q "max 0 " "$tmp/out"; then ok "--lights-off all $nl: black"; else cat "$tmp/out"; ko "--lights-off all $nl: black"; fi
    else
        ko "stats JSON lists the scene's lights (got '${nl:-}')"
    fi

    check "--bench prints JSON" "$play" "$gto" --headless "${W[@]}" --bench 5
    check "bench JSON has the stages and fps" jq -e '.median_ms | has("projection") and has("multiply") and has("brdf") and has("synthesis") and has("upload") and has("draw")' "$tmp/out"

    printf '# t key values\n0 light_pos 0 1.5 0\n1 light_intensity 20\n2\n' >"$tmp/script.txt"
    c=$(jq -r '.lights[0].pos | map(tostring) | join(" ")' "$tmp/stats.json" 2>/dev/null)
    [ -n "$c" ] && printf '0 light_pos %s\n1\n2.5\n' "$c" >"$tmp/script.txt"
    check "script renders" "$play" "$gto" --headless "${W[@]}" --script "$tmp/script.txt" --out-pattern "$tmp/frame_%03d.png"
    if [ -f "$tmp/frame_000.png" ] && [ -f "$tmp/frame_002.png" ] && [ ! -f "$tmp/frame_003.png" ]; then ok "script: 3 frames"; else ko "script: 3 frames"; fi
    check "script --script-fps 2: 6 frames" "$play" "$gto" --headless "${W[@]}" --script "$tmp/script.txt" --script-fps 2 --out-pattern "$tmp/f2_%d.png"
    [ -f "$tmp/f2_5.png" ] && [ ! -f "$tmp/f2_6.png" ] && ok "6 frames written" || ko "6 frames written"

    if command -v xvfb-run >/dev/null; then
        check "window under Xvfb" timeout 60 xvfb-run -a -s "-screen 0 800x600x24" "$play" "$gto" "${W[@]}" --frames 3 --screenshot "$tmp/shot.png"
        check "window screenshot not blank" "$img" --nonblank "$tmp/shot.png"
        # the overlay (panel, text, light markers) is drawn: the picture differs from --no-overlay
        timeout 60 xvfb-run -a -s "-screen 0 800x600x24" "$play" "$gto" "${W[@]}" --frames 3 --no-overlay --screenshot "$tmp/shot0.png" >/dev/null 2>&1
        m1=$("$img" --stats "$tmp/shot.png" | sed -E 's/.*mean ([0-9.e+-]+).*/\1/')
        m0=$("$img" --stats "$tmp/shot0.png" | sed -E 's/.*mean ([0-9.e+-]+).*/\1/')
        awk -v a="$m1" -v b="$m0" 'BEGIN { d = (a - b) / b; exit !(d > 0.01 || d < -0.01) }' &&
            ok "overlay drawn (mean $m1 with, $m0 without)" || ko "overlay drawn (mean $m1 with, $m0 without)"
    else
        skipped "window under Xvfb: xvfb-run missing (tools/install-deps.sh installs xvfb)"
        skipped "window screenshot not blank: xvfb-run missing"
    fi

    # --supersample 2 averages 2 x 2 rendered pixels: the picture's mean stays (within 2%),
    # its edges are smoothed
    check "headless --supersample 2" "$play" "$gto" --headless "${W[@]}" --supersample 2 -o "$tmp/ss2.exr"
    m1=$("$img" --stats "$tmp/both.exr" | sed -E 's/.*mean ([0-9.e+-]+).*/\1/')
    m2=$("$img" --stats "$tmp/ss2.exr" | sed -E 's/.*mean ([0-9.e+-]+).*/\1/')
    awk -v a="$m1" -v b="$m2" 'BEGIN { d = (b - a) / a; exit !(d < 0.02 && d > -0.02) }' &&
        ok "supersampled mean $m2 = plain mean $m1 (2%)" || ko "supersampled mean $m2 = plain mean $m1 (2%)"

    # keys are events: a tap (press and release between two frames) of Space switches the
    # light off, then F12 saves the window; the saved picture is darker than the first one
    if command -v xvfb-run >/dev/null && command -v xdotool >/dev/null; then
        cat >"$tmp/keys.sh" <<KEYS
#!/bin/bash
cd "$tmp" && rm -f wrt-play-*.png
"$PWD/$play" "$gto" "\${@}" >"$tmp/win.log" 2>&1 &
pid=\$!
for i in \$(seq 50); do wid=\$(xdotool search --name wrt-play 2>/dev/null | head -n 1); [ -n "\$wid" ] && break; sleep 0.2; done
sleep 2
xdotool key --window "\$wid" F12; sleep 2
xdotool key --window "\$wid" space; sleep 1
xdotool key --window "\$wid" F12; sleep 2
xdotool key --window "\$wid" Escape
wait \$pid
KEYS
        timeout 90 xvfb-run -a -s "-screen 0 800x600x24" bash "$tmp/keys.sh" "${W[@]}" --msaa 1 --no-overlay >/dev/null 2>&1
        if [ -f "$tmp/wrt-play-0001.png" ] && [ -f "$tmp/wrt-play-0002.png" ]; then
            m1=$("$img" --stats "$tmp/wrt-play-0001.png" | sed -E 's/.*mean ([0-9.e+-]+).*/\1/')
            m2=$("$img" --stats "$tmp/wrt-play-0002.png" | sed -E 's/.*mean ([0-9.e+-]+).*/\1/')
            if awk -v a="$m1" -v b="$m2" 'BEGIN { exit !(b < 0.5 * a) }'; then ok "window: Space tap switches the light off (mean $m1 -> $m2)"
            else ko "window: Space tap switches the light off (mean $m1 -> $m2)"; fi
        else
            cat "$tmp/win.log"; ko "window: F12 saved two screenshots"
        fi
        # F12 saves the picture without the overlay: saved with the overlay on, then after H
        # hid it, the two pictures' means agree within 0.5% (the overlay moves the mean by
        # more than 1%, checked above); the confirmation names the file as it is written
        cat >"$tmp/f12.sh" <<KEYS
#!/bin/bash
cd "$tmp" && rm -f wrt-play-*.png
"$PWD/$play" "$gto" "\${@}" >"$tmp/f12.log" 2>&1 &
pid=\$!
for i in \$(seq 50); do wid=\$(xdotool search --name wrt-play 2>/dev/null | head -n 1); [ -n "\$wid" ] && break; sleep 0.2; done
sleep 3
xdotool key --window "\$wid" F12; sleep 2
xdotool key --window "\$wid" h; sleep 1
xdotool key --window "\$wid" F12; sleep 2
xdotool key --window "\$wid" Escape
wait \$pid
KEYS
        timeout 90 xvfb-run -a -s "-screen 0 800x600x24" bash "$tmp/f12.sh" "${W[@]}" >/dev/null 2>&1
        if [ -f "$tmp/wrt-play-0001.png" ] && [ -f "$tmp/wrt-play-0002.png" ]; then
            m2=$("$img" --stats "$tmp/wrt-play-0001.png" | sed -E 's/.*mean ([0-9.e+-]+).*/\1/')
            m3=$("$img" --stats "$tmp/wrt-play-0002.png" | sed -E 's/.*mean ([0-9.e+-]+).*/\1/')
            awk -v a="$m2" -v b="$m3" 'BEGIN { d = (a - b) / b; exit !(d < 0.005 && d > -0.005) }' &&
                ok "F12 saves without the overlay (mean $m2 with the overlay shown, $m3 hidden)" ||
                ko "F12 saves without the overlay (mean $m2 with the overlay shown, $m3 hidden)"
            grep -q "^wrt-play: saved wrt-play-0001.png$" "$tmp/f12.log" && ok "F12 names the file it wrote" ||
                ko "F12 names the file it wrote: $(cat "$tmp/f12.log")"
        else
            cat "$tmp/f12.log"; ko "window: F12 with the overlay saved a screenshot"
        fi
    fi

    # truncated copies: a clear message and exit 2, never a crash
    size=$(stat -c %s "$gto")
    for cut in 0 7 64 $((size / 2)) $((size - 1)); do
        head -c "$cut" "$gto" >"$tmp/cut.gto"
        expect_exit "truncated to $cut bytes: exit 2" 2 "trunc|corrupt|short|small|empty|not" "$play" "$tmp/cut.gto" --headless --out "$tmp/x.png"
    done
    # one byte complemented in the header, the middle (operator values) and near the end
    # (provenance): each caught by its section's checksum, exit 2 and a message
    for off in 200 $((size / 2)) $((size - 100)); do
        cp "$gto" "$tmp/flip.gto"
        b=$(od -An -tu1 -j "$off" -N1 "$gto" | tr -d ' ')
        printf "\\$(printf %o $((255 - b)))" | dd of="$tmp/flip.gto" bs=1 seek="$off" conv=notrunc status=none
        cmp -s "$gto" "$tmp/flip.gto" && { ko "byte $off complemented"; continue; }
        expect_exit "byte $off of $size complemented: exit 2, checksum" 2 "checksum|corrupt" "$play" "$tmp/flip.gto" --headless --out "$tmp/x.png"
    done
fi

summary
