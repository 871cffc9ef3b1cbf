#!/usr/bin/env bash
# cli.sh: the command-line vocabulary every tool shares (cli/cli.h): --version in each,
# the one exit-code table in each --help, -o accepted for the output everywhere, and the
# light options refused with a message and exit 1 when they name a light the scene does
# not have, or aim a point light, in wrt-play, wrt-ref and wrt-compare alike.
# Usage: tests/cli.sh BUILD. Prints "cli: N passed, N failed"; non-zero exit on a failure.
set -u
build=${1:-build}
cd "$(dirname "$0")/.."
. tests/lib.sh cli
lib_ko_shows_err=1 # a failure shows what the command said
tmp=$(mktemp -d /tmp/wrt_cli_XXXXXX)
trap 'rm -rf "$tmp"' EXIT
# expect NAME CODE REGEX CMD...: exit code CODE and stderr (or stdout) matching REGEX
expect() {
    local name=$1 code=$2 re=$3; shift 3
    "$@" >"$tmp/out" 2>"$tmp/err"; local rc=$?
    if [ $rc -eq "$code" ] && { [ -z "$re" ] || cat "$tmp/err" "$tmp/out" | grep -Eq -- "$re"; }; then ok "$name"; else echo "    exit $rc"; ko "$name"; fi
}

tools=(wrt-bake wrt-play wrt-ref wrt-compare wrt-scenegen)
for t in "${tools[@]}"; do
    [ -x "$build/$t" ] || { ko "$build/$t not built"; continue; }
    if [ "$t" = wrt-scenegen ]; then  # it writes glTF and never a .gto: no .gto version
        expect "$t --version" 0 "^$t [0-9]+\.[0-9]+\.[0-9]+ \(writes glTF 2\.0\)$" "$build/$t" --version
        grep -q "gto" "$tmp/out" && ko "$t --version names no .gto version" || ok "$t --version names no .gto version"
    else
        expect "$t --version" 0 "^$t [0-9]+\.[0-9]+\.[0-9]+ \(\.gto version [0-9]+\)" "$build/$t" --version
    fi
    "$build/$t" --help >"$tmp/help" 2>&1
    # the table, the same lines in every tool
    if grep -q "exit codes (the same in every wrt tool)" "$tmp/help" &&
       grep -Eq "0 ok +4 interrupted" "$tmp/help" && grep -Eq "1 bad command line +5 accuracy not met" "$tmp/help" &&
       grep -Eq "2 bad input \(scene, .gto\) +6 no display" "$tmp/help" &&
       grep -Eq "3 output cannot be written +7 out of memory" "$tmp/help"; then
        ok "$t --help prints the exit-code table"
    else
        ko "$t --help prints the exit-code table"
    fi
    grep -Eq -- "-o, --out|-o FILE|-o OUT" "$tmp/help" && ok "$t --help names -o" || ko "$t --help names -o"
    expect "$t unknown option: exit 1" 1 "unknown option" "$build/$t" --frobnicate
done

# the same exit code for the same failure in every tool that reads a scene / a .gto
expect "wrt-bake missing scene: exit 2" 2 "nope.gltf" "$build/wrt-bake" "$tmp/nope.gltf" -o "$tmp/x.gto"
expect "wrt-ref missing scene: exit 2" 2 "nope.gltf" "$build/wrt-ref" "$tmp/nope.gltf" -o "$tmp/r"
expect "wrt-compare missing scene: exit 2" 2 "nope.gltf" "$build/wrt-compare" "$tmp/nope.gltf" "$tmp/x.gto"
expect "wrt-play missing file: exit 2" 2 "nope.gto" "$build/wrt-play" "$tmp/nope.gto" --headless -o "$tmp/x.png"
expect "wrt-bake --info missing file: exit 2, said once" 2 "nope.gto: No such file" "$build/wrt-bake" --info "$tmp/nope.gto"
[ "$(grep -c nope.gto "$tmp/err" "$tmp/out" | awk -F: '{s += $2} END {print s}')" = 1 ] && ok "--info: one message" || ko "--info: one message"
expect "wrt-ref bad value: exit 1" 1 "bad value for --spp" "$build/wrt-ref" assets/cornell.gltf --spp 0

# the light options, on the Cornell box's one point light
scene=assets/cornell.gltf
gto=$tmp/c.gto
"$build/wrt-bake" "$scene" -o "$gto" -q 1 --quiet >/dev/null 2>"$tmp/err" && ok "bake $scene (-o)" || ko "bake $scene (-o)"
expect "wrt-bake --out is -o" 0 "baked" "$build/wrt-bake" assets/test/facing.gltf --out "$tmp/f.gto" -q 1 --quiet
play=("$build/wrt-play" "$gto" --headless --width 64 --height 48 -o "$tmp/p.png")
ref=("$build/wrt-ref" "$scene" --width 16 --height 16 --spp 1 -o "$tmp/r")
cmp=("$build/wrt-compare" "$scene" "$gto" --no-image --cell-paths 2000 --lights 1 --bench 1)
for tool in play ref cmp; do
    eval "cmd=(\"\${$tool[@]}\")"
    expect "$tool --light-scale 2=3: no light 2, exit 1" 1 "light-scale 2: the scene has 1 light" "${cmd[@]}" --light-scale 2=3
    expect "$tool --lights-off 3: no light 3, exit 1" 1 "lights-off 3: the scene has 1 light" "${cmd[@]}" --lights-off 3
    expect "$tool --light 2: no light 2, exit 1" 1 "light 2: the scene has 1 light" "${cmd[@]}" --light 2 --light-pos 0,0.5,0
    expect "$tool --light-dir on a point light: exit 1" 1 "point light.*--light-cone" "${cmd[@]}" --light-dir 0,-1,0
    expect "$tool --light-scale 0=1: exit 1" 1 "bad value for --light-scale" "${cmd[@]}" --light-scale 0=1
    expect "$tool --light-pos 1,2: exit 1" 1 "bad value for --light-pos" "${cmd[@]}" --light-pos 1,2
    expect "$tool --light-cone 1,0.5: exit 1" 1 "bad value for --light-cone" "${cmd[@]}" --light-cone 1,0.5
done
expect "wrt-play: a spot made with --light-cone and aimed: exit 0" 0 "" "${play[@]}" --light-dir 0,-1,0 --light-cone 0.3,0.5
expect "wrt-ref: the same spot: exit 0" 0 "wrote" "${ref[@]}" --light-dir 0,-1,0 --light-cone 0.3,0.5
expect "wrt-play --msaa 3: exit 1" 1 "bad value for --msaa" "${play[@]}" --msaa 3
# a directional light (sun): --light-dir turns it, a position or a cone is refused
sun=assets/sun_room.gltf
"$build/wrt-bake" "$sun" -o "$tmp/s.gto" -q 1 --quiet >/dev/null 2>"$tmp/err" && ok "bake $sun" || ko "bake $sun"
"$build/wrt-bake" --scan "$sun" | grep -q "^  \[1\] sun .*intensity 10 lux" && ok "--scan lists the sun in lux" || ko "--scan lists the sun in lux"
splay=("$build/wrt-play" "$tmp/s.gto" --headless --width 64 --height 48 -o "$tmp/sx.png")
sref=("$build/wrt-ref" "$sun" --width 16 --height 16 --spp 1 -o "$tmp/rs")
for tool in splay sref; do
    eval "cmd=(\"\${$tool[@]}\")"
    expect "$tool --light-pos on a sun: exit 1" 1 "directional light.*no position" "${cmd[@]}" --light-pos 0,1,0
    expect "$tool --light-cone on a sun: exit 1" 1 "directional light.*no cone" "${cmd[@]}" --light-cone 0.3,0.5
done
expect "wrt-ref: a sun turned: exit 0" 0 "wrote" "${sref[@]}" --light-dir 0.9,-0.5,0.3
splay=("${splay[@]:0:$((${#splay[@]} - 2))}")   # its own -o below (an option given twice is refused)
expect "wrt-play: the sun as baked: exit 0" 0 "" "${splay[@]}" -o "$tmp/s0.png"
expect "wrt-play: the sun turned: exit 0" 0 "" "${splay[@]}" -o "$tmp/s1.png" --light-dir 0.9,-0.5,0.3
[ -s "$tmp/s0.png" ] && ! cmp -s "$tmp/s0.png" "$tmp/s1.png" && ok "--light-dir turns the sun (another picture)" ||
    ko "--light-dir turns the sun (another picture)"
# a light switched off by number 1 (the first, as --scan numbers it) gives a black picture
"$build/wrt-bake" --scan "$scene" | grep -q "^  \[1\] point" && ok "--scan numbers lights from 1" || ko "--scan numbers lights from 1"
if [ -x "$build/tests/test_image" ]; then
    "$build/wrt-play" "$gto" --headless --width 64 --height 48 --lights-off 1 -o "$tmp/off.exr" 2>"$tmp/err"
    "$build/tests/test_image" --stats "$tmp/off.exr" >"$tmp/out" 2>>"$tmp/err"
    grep -q "max 0 " "$tmp/out" && ok "--lights-off 1 switches the first light off" || ko "--lights-off 1 switches the first light off"
fi
# --scan takes its scene before or after it, with bake options anywhere; alone it names what it needs
"$build/wrt-bake" assets/cornell.gltf --scan --clusters --json | grep -q '"elements"' && ok "wrt-bake SCENE --scan --clusters: the scene's report" || ko "wrt-bake SCENE --scan --clusters: the scene's report"
expect "wrt-bake --scan alone: exit 1, says it needs a scene" 1 "--scan needs a scene" "$build/wrt-bake" --scan --json
# --scan of a baked file says what it is; --info prints no raw JSON and no unrecorded times
expect "--scan of a .gto: exit 2, named" 2 "is a baked .gto file, not a scene" "$build/wrt-bake" --scan "$gto"
"$build/wrt-bake" --info "$gto" >"$tmp/info" 2>"$tmp/err"
grep -q '^provenance: wrt-bake .* from assets/cornell.gltf' "$tmp/info" && ! grep -q '{' "$tmp/info" &&
    ok "--info: provenance as text, no raw JSON" || ko "--info: provenance as text, no raw JSON"
grep -q "0\.00 s" "$tmp/info" && ko "--info shows no 0.00 s" || ok "--info shows no 0.00 s"
# Messages: each wrong input below gets its exit code and one line on stderr, starting
# "TOOL: error:" and saying what is wrong (the same prefix in every tool).
# one_line NAME CODE TOOL REGEX ARGS...
one_line() {
    local name=$1 code=$2 tool=$3 re=$4; shift 4
    "$build/$tool" "$@" >"$tmp/out" 2>"$tmp/err"; local rc=$? n
    n=$(wc -l <"$tmp/err")
    if [ $rc -eq "$code" ] && [ "$n" -eq 1 ] && grep -Eq -- "^$tool: error: $re" "$tmp/err"; then
        ok "$name: exit $code, one line: $(cat "$tmp/err")"
    else
        echo "    exit $rc, $n lines"; ko "$name"
    fi
}
one_line "wrt-bake of a .gto" 2 wrt-bake "$gto: this is a \.gto file; bake a \.gltf, or use --info$" "$gto" -o "$tmp/y.gto"
one_line "wrt-bake of a .gto, no -o" 2 wrt-bake "$gto: this is a \.gto file" "$gto"
one_line "wrt-scenegen without -o" 1 wrt-scenegen "no output file: wrt-scenegen cornell -o FILE\.gltf$" cornell
one_line "wrt-scenegen -o without a scene" 1 wrt-scenegen "no scene name before -o $tmp/s.gltf" -o "$tmp/s.gltf"
one_line "wrt-scenegen unknown scene" 1 wrt-scenegen "unknown scene nope" nope -o "$tmp/s.gltf"
one_line "wrt-play -o given twice" 1 wrt-play "-o given twice$" "$gto" --headless -o "$tmp/x.png" -o "$tmp/y.png"
one_line "wrt-play --out after -o" 1 wrt-play "--out given twice$" "$gto" --headless -o "$tmp/x.png" --out "$tmp/y.png"
one_line "wrt-play missing file, named once" 2 wrt-play "$tmp/nope\.gto: cannot open: No such file or directory$" \
    "$tmp/nope.gto" --headless -o "$tmp/x.png"
[ "$(grep -o "nope\.gto" "$tmp/err" | wc -l)" -eq 1 ] && ok "wrt-play names the missing file once" || ko "wrt-play names the missing file once"
printf 'not a gto at all' >"$tmp/foreign.gto"
one_line "wrt-play foreign file, named" 2 wrt-play "$tmp/foreign\.gto: not a \.gto file" "$tmp/foreign.gto" --headless -o "$tmp/x.png"
one_line "wrt-ref bad value" 1 wrt-ref "bad value for --spp: '0'" "$scene" --spp 0
one_line "wrt-ref no scene" 1 wrt-ref "no scene" --spp 4
one_line "wrt-compare unknown option" 1 wrt-compare "unknown option --frobnicate" "$scene" "$gto" --frobnicate
one_line "wrt-play light out of range" 1 wrt-play "--light 2: the scene has 1 light" "$gto" --headless -o "$tmp/x.png" --light 2 --light-pos 0,0.5,0
one_line "wrt-bake unknown option" 1 wrt-bake "unknown option '--frobnicate'" "$scene" -o "$tmp/x.gto" --frobnicate
# an option of [0, 1] whose 0 means something of its own: in --help, a value out of range
# refused with nothing written, 0 accepted and recorded ($1 option, $2 its json key, $3 what 0 is)
unit_option() {
    "$build/wrt-bake" --help | grep -q -- "$1 [A-Z]" && ok "--help lists $1" || ko "--help lists $1"
    rm -f "$tmp/x.gto"
    one_line "wrt-bake $1 out of range" 1 wrt-bake "bad value for $1: '2' \(a number in \[0, 1\]\)$" \
        "$scene" -o "$tmp/x.gto" "$1" 2
    [ ! -e "$tmp/x.gto" ] && ok "$1 2: nothing written" || ko "$1 2: nothing written"
    "$build/wrt-bake" "$scene" -o "$tmp/x.gto" --quality 1 "$1" 0 --json >"$tmp/opt0.json" 2>/dev/null &&
        grep -q "\"$2\":0[,}]" "$tmp/opt0.json" && ok "$1 0: accepted, recorded as $3" ||
        ko "$1 0: accepted, recorded as $3"
}
unit_option --depth-share depth_share off
unit_option --small-lost small_lost always

# no display: exit 6
expect "wrt-play without a display: exit 6" 6 "display|window" env -u DISPLAY -u WAYLAND_DISPLAY "$build/wrt-play" "$gto"

summary
