#!/usr/bin/env bash
# harden.sh: nothing wrong gets through (issue 25). One regression check per class of bad
# input or fault: the wrong input, its exit code and its one line of message.
#   1 JSON nested 20,000 deep (inside extras): refused before parsing, exit 2
#   2 outputs only as regular files: a FIFO or a symlink as -o / --stats-json / wrt-ref
#     / wrt-scenegen output refused with exit 3, the target unchanged
#   3 results on stdout lost on a full disk (> /dev/full): exit 3
#   4 JSON outputs parse whatever the names (quotes, control characters, invalid UTF-8,
#     a name cut at 63 bytes inside a UTF-8 character)
#   5 numbers beyond what the computation carries refused where they enter
#   6 glTF specification: uris leaving the folder, GLB framing, quantized positions,
#     normalized floats, a camera whose up is its view direction
#   7 wrt-play: a script asking for too many frames; a .gto truncated while playing
#   8 out of memory: exit 7 with a message
# Usage: tests/harden.sh BUILD. Prints "harden: N passed, N failed".
set -u
build=${1:-build}
cd "$(dirname "$0")/.."
. tests/lib.sh harden
lib_ko_shows_err=1   # a failure shows the first lines of $tmp/err
tmp=$(mktemp -d /tmp/wrt_harden_XXXXXX)
trap 'rm -rf "$tmp"' EXIT
bake=$build/wrt-bake play=$build/wrt-play
# expect NAME CODE REGEX CMD...: exit code CODE, stderr matching REGEX on one line
expect() {
    local name=$1 code=$2 re=$3; shift 3
    "$@" >"$tmp/out" 2>"$tmp/err"; local rc=$?
    if [ $rc -eq "$code" ] && { [ -z "$re" ] || grep -Eq -- "$re" "$tmp/err"; }; then ok "$name"; else echo "    exit $rc"; ko "$name"; fi
}

# ---- the test scenes: variants of tests/data/quad.gltf
mkdir -p "$tmp/scenes/sub"
python3 - "$tmp/scenes" <<'PY'
import json, struct, sys
d0 = json.load(open('tests/data/quad.gltf'))
out = sys.argv[1]
def variant(name, f, text=None):
    d = json.loads(json.dumps(d0)); f(d)
    open(f"{out}/{name}", 'w').write(text if text is not None else json.dumps(d))
def light(d, intensity=3.0, pos=(0.5, 0.5, 1.0)):
    d['extensionsUsed'] = ['KHR_lights_punctual']
    d['extensions'] = {'KHR_lights_punctual': {'lights': [{'type': 'point', 'intensity': intensity}]}}
    d['nodes'].append({'extensions': {'KHR_lights_punctual': {'light': 0}}, 'translation': list(pos)})
    d['scenes'][0]['nodes'].append(len(d['nodes']) - 1)
txt = json.dumps(d0)
open(f"{out}/deep.gltf", 'w').write(txt[:-1] + ',"extras":' + '[' * 20000 + ']' * 20000 + '}')
open(f"{out}/deep_obj.gltf", 'w').write(txt[:-1] + ',"extras":' + '{"a":' * 200 + '1' + '}' * 200 + '}')
variant('uri_up.gltf', lambda d: d['buffers'][0].update(uri='../outside.bin'))
variant('uri_abs.gltf', lambda d: d['buffers'][0].update(uri='/etc/hostname'))
variant('uri_pct.gltf', lambda d: d['buffers'][0].update(uri='sub/%2e%2e/%2E%2E/outside.bin'))
variant('img_up.gltf', lambda d: d.update(images=[{'uri': '../tex.png'}]))
variant('norm_float.gltf', lambda d: d['accessors'][0].update(normalized=True))
variant('ubyte_pos.gltf', lambda d: d['accessors'][0].update(componentType=5121))
variant('light_huge.gltf', lambda d: light(d, intensity=3.4e38))
variant('light_far.gltf', lambda d: light(d, pos=(1e30, 1, 0)))
variant('lit.gltf', lambda d: light(d))
def cam(d):
    d['cameras'] = [{'type': 'perspective', 'perspective': {'yfov': 0.8, 'znear': 0.01}}]
    d['nodes'].append({'camera': 0, 'matrix': [1,0,0,0, 0,0,1,0, 0,1e-9,1,0, 0.5,0.5,5,1]})
    d['scenes'][0]['nodes'].append(len(d['nodes']) - 1)
variant('cam_up.gltf', cam)
glb = open('tests/data/quad.glb', 'rb').read()
open(f"{out}/trail.glb", 'wb').write(glb + b'\0' * 16)
n = struct.unpack('<I', glb[8:12])[0]
open(f"{out}/twobin.glb", 'wb').write(glb[:8] + struct.pack('<I', n + 16) + glb[12:] +
                                      struct.pack('<II', 8, 0x004E4942) + b'\0' * 8)
# the outside file the uris aim at: a real buffer, so that only the folder rule refuses it
b64 = d0['buffers'][0]['uri'].split(',', 1)[1]
import base64
open(f"{out}/../outside.bin", 'wb').write(base64.b64decode(b64))
PY
S=$tmp/scenes

# ---- 1 JSON depth
expect "JSON 20,000 deep in extras: exit 2" 2 "deep.gltf: JSON nested deeper than 128 levels" "$bake" --scan "$S/deep.gltf"
expect "the same in a bake: exit 2" 2 "JSON nested deeper than 128 levels" "$bake" "$S/deep.gltf" -o "$tmp/d.gto"
expect "200 nested objects: exit 2" 2 "JSON nested deeper than 128 levels" "$bake" --scan "$S/deep_obj.gltf"
expect "the fuzz seed (130 levels): exit 2" 2 "JSON nested deeper than 128 levels" "$bake" --scan tests/data/bad_deep.gltf

# ---- 6 glTF specification
expect "buffer uri ../: exit 2" 2 "buffers\[0\]\.uri: '\.\./outside\.bin' leaves the scene's folder" "$bake" --scan "$S/uri_up.gltf"
expect "buffer uri absolute: exit 2" 2 "buffers\[0\]\.uri: '/etc/hostname' leaves the scene's folder" "$bake" --scan "$S/uri_abs.gltf"
expect "buffer uri %2e%2e: exit 2" 2 "buffers\[0\]\.uri: .* leaves the scene's folder" "$bake" --scan "$S/uri_pct.gltf"
expect "image uri ../: exit 2" 2 "images\[0\]\.uri: '\.\./tex\.png' leaves the scene's folder" "$bake" --scan "$S/img_up.gltf"
expect "--allow-outside-files reads it: exit 0" 0 "" "$bake" --scan "$S/uri_up.gltf" --allow-outside-files
ln -s ../outside.bin "$S/link.bin"
python3 -c "
import json,sys; d=json.load(open('tests/data/quad.gltf')); d['buffers'][0]['uri']='link.bin'
open(sys.argv[1],'w').write(json.dumps(d))" "$S/uri_link.gltf"
expect "a link inside the folder to a file outside: exit 2" 2 "link.bin: outside the scene's folder" "$bake" --scan "$S/uri_link.gltf"
expect "GLB with trailing bytes: exit 2" 2 "16 bytes after the end of the GLB" "$bake" --scan "$S/trail.glb"
expect "GLB with two BIN chunks: exit 2" 2 "second BIN chunk" "$bake" --scan "$S/twobin.glb"
expect "UNSIGNED_BYTE positions without KHR_mesh_quantization: exit 2" 2 "attributes\.POSITION: accessor 0 has componentType 5121.*KHR_mesh_quantization" "$bake" --scan "$S/ubyte_pos.gltf"
expect "normalized on FLOAT: exit 2" 2 "accessors\[0\]\.normalized: is true on a FLOAT accessor" "$bake" --scan "$S/norm_float.gltf"
expect "camera up parallel to its view: exit 2" 2 "camera of node 1: its up direction .* is parallel to its view direction" "$bake" --scan "$S/cam_up.gltf"

# ---- 5 numbers
expect "light intensity 3.4e38: exit 2" 2 "lights\[0\]\.intensity: 3\.4e\+38 is outside \[0, 1e\+12\]" "$bake" --scan "$S/light_huge.gltf"
expect "light at 1e30: exit 2" 2 "light 'light0' \(node 1\): position \(1e\+30, 1, 0\) is outside" "$bake" --scan "$S/light_far.gltf"

# ---- 2 outputs only as regular files: a FIFO and a link, each refused (exit 3), unchanged
"$bake" assets/cornell.gltf -q 1 -o "$tmp/c.gto" --quiet >/dev/null 2>"$tmp/err" && ok "bake the Cornell box" || ko "bake the Cornell box"
echo precious >"$tmp/target"
# special TOOL-NAME CODE REGEX CMD-WITH-@OUT@...: runs the command with @OUT@ replaced by a
# FIFO, then by a symlink to $tmp/target; both refused, the FIFO still a FIFO, the link
# still a link, the target's bytes unchanged
special() {
    local name=$1 code=$2 re=$3 suffix=$4; shift 4
    local f=$tmp/fifo$suffix l=$tmp/link$suffix
    rm -f "$f" "$l"; mkfifo "$f"; ln -s "$tmp/target" "$l"
    local args=() a
    for a in "$@"; do args+=("${a//@OUT@/$f}"); done
    expect "$name: a FIFO refused, exit $code" "$code" "fifo.*is a FIFO: outputs are only written as regular files" timeout 60 "${args[@]}"
    [ -p "$f" ] && ok "$name: the FIFO is still a FIFO" || ko "$name: the FIFO is still a FIFO"
    args=()
    for a in "$@"; do args+=("${a//@OUT@/$l}"); done
    expect "$name: a symlink refused, exit $code" "$code" "link.*is a symbolic link: outputs are only written as regular files" timeout 60 "${args[@]}"
    [ -L "$l" ] && [ "$(cat "$tmp/target")" = precious ] && ok "$name: the link and its target unchanged" || ko "$name: the link and its target unchanged"
    rm -f "$f" "$l"
}
special "wrt-bake -o" 3 "" .gto "$bake" tests/data/quad.gltf -o @OUT@ --quiet
special "wrt-play -o" 3 "" .png "$play" "$tmp/c.gto" --headless --width 32 --height 24 -o @OUT@
special "wrt-play --stats-json" 3 "" .json "$play" "$tmp/c.gto" --headless --width 32 --height 24 --stats-json @OUT@
special "wrt-scenegen -o" 3 "" .gltf "$build/wrt-scenegen" cornell -o @OUT@
rm -f "$tmp/r_both.png"; mkfifo "$tmp/r_both.png"
expect "wrt-ref: a FIFO among its outputs refused, exit 3" 3 "r_both.png: is a FIFO" timeout 60 "$build/wrt-ref" assets/cornell.gltf --width 8 --height 8 --spp 1 -o "$tmp/r"
[ -p "$tmp/r_both.png" ] && ok "wrt-ref: the FIFO is still a FIFO" || ko "wrt-ref: the FIFO is still a FIFO"
ls "$tmp" | grep -q '\.tmp\.' && ko "no temporary left behind" || ok "no temporary left behind"

# ---- 3 results on stdout lost (a full disk): exit 3, said on stderr
full() {
    local name="$1 > /dev/full: exit 3"; shift
    "$@" >/dev/full 2>"$tmp/err"; local rc=$?
    if [ $rc -eq 3 ] && grep -q "cannot write the results to standard output" "$tmp/err"; then ok "$name"; else echo "    exit $rc"; ko "$name"; fi
}
full "wrt-bake --scan" "$bake" --scan assets/cornell.gltf
full "wrt-bake --scan --json" "$bake" --scan assets/cornell.gltf --json
full "wrt-bake --info --json" "$bake" --info "$tmp/c.gto" --json
full "wrt-bake --json (a bake)" "$bake" tests/data/quad.gltf -o "$tmp/q.gto" --json --quiet
full "wrt-play --bench" "$play" "$tmp/c.gto" --headless --width 16 --height 16 --bench 2
full "wrt-ref --json" "$build/wrt-ref" assets/cornell.gltf --width 8 --height 8 --spp 1 -o "$tmp/rr" --json
full "wrt-scenegen --help" "$build/wrt-scenegen" --help
full "wrt-compare --version" "$build/wrt-compare" --version

# ---- 4 JSON outputs parse whatever the names (and the paths) hold
hostile=$tmp/$'we"ird\\ name\x01.gltf'
python3 - "$hostile" <<'PY'
import json, sys
d = json.load(open('assets/cornell.gltf'))
nasty = ['quote " back \\ slash', 'esc \x1b[31m red \x07 bell', 'new\nline\ttab\x7f',
         'a' * 62 + '\u00e9' + 'tail', 'b' * 61 + '\u20ac' + 'tail', 'c' * 60 + '\U0001F600' + 'tail']
k = 0
def name(o):
    global k
    o['name'] = nasty[k % len(nasty)] + str(k); k += 1
for key in ('nodes', 'meshes', 'materials'):
    for o in d.get(key, []): name(o)
for l in d['extensions']['KHR_lights_punctual']['lights']: name(l)
d['materials'][0]['name'] = 'a' * 62 + '\u00e9' + 'tail'   # cut at 63 bytes inside the e-acute
open(sys.argv[1], 'w').write(json.dumps(d))
PY
parses() { if python3 -m json.tool "$2" >/dev/null 2>"$tmp/err"; then ok "$1 parses"; else ko "$1 parses"; fi; }
"$bake" --scan "$hostile" --json >"$tmp/scan.json" 2>"$tmp/err"; parses "--scan --json of hostile names" "$tmp/scan.json"
python3 -c "
import json,sys; d=json.load(open(sys.argv[1])); n=d['materials'][0]['name']
sys.exit(0 if n == 'a' * 62 else 1)" "$tmp/scan.json" && ok "a name cut at 63 bytes ends at a character boundary (62 bytes)" || ko "a name cut at 63 bytes ends at a character boundary (62 bytes)"
"$bake" "$hostile" -o "$tmp/h.gto" -q 1 --quiet --json >"$tmp/bake.json" 2>"$tmp/err"; parses "a bake's --json (the path holds a quote, a backslash, a control character)" "$tmp/bake.json"
"$bake" --info "$tmp/h.gto" --json >"$tmp/info.json" 2>"$tmp/err"; parses "--info --json of that bake" "$tmp/info.json"
"$play" "$tmp/h.gto" --headless --width 16 --height 16 --stats-json "$tmp/stats.json" 2>"$tmp/err"; parses "wrt-play --stats-json of that bake" "$tmp/stats.json"
"$play" "$tmp/h.gto" --headless --width 16 --height 16 --bench 2 >"$tmp/bench.json" 2>"$tmp/err"; parses "wrt-play --bench" "$tmp/bench.json"
# a scene where no light is exchanged (one quad): ratios of zero energies stay numbers
"$bake" tests/data/quad.gltf -o "$tmp/q1.gto" -q 1 --quiet --json >"$tmp/q1.json" 2>"$tmp/err"; parses "a one-quad bake's --json" "$tmp/q1.json"
"$bake" --info "$tmp/q1.gto" --json >"$tmp/q1i.json" 2>"$tmp/err"; parses "its --info --json" "$tmp/q1i.json"

# ---- 5 numbers on the command line (and in a script) beyond what the computation carries
P=("$play" "$tmp/c.gto" --headless --width 16 --height 16 -o "$tmp/n.png")
expect "--light-color 1e38,1,1: exit 1" 1 "bad value for --light-color: '1e38,1,1'.*within" "${P[@]}" --light-color 1e38,1,1
expect "--light-intensity 3.4e38: exit 1" 1 "bad value for --light-intensity: '3.4e38' \(a number in \[0, 1e\+12\]\)" "${P[@]}" --light-intensity 3.4e38
expect "--light-pos 1e30,0,0: exit 1" 1 "bad value for --light-pos: '1e30,0,0'" "${P[@]}" --light-pos 1e30,0,0
expect "--light-scale 1=1e30: exit 1" 1 "bad value for --light-scale \(the factor\): '1e30'" "${P[@]}" --light-scale 1=1e30
expect "--camera-pos 1e30,0,0: exit 1" 1 "bad value for --camera-pos: '1e30,0,0'" "${P[@]}" --camera-pos 1e30,0,0
expect "wrt-ref --light-color 1e38,1,1: exit 1" 1 "bad value for --light-color" "$build/wrt-ref" assets/cornell.gltf --width 8 --height 8 --spp 1 -o "$tmp/r2" --light-color 1e38,1,1
printf '0 light_pos 0 1 0\n1 light_intensity 3.4e38\n' >"$tmp/s_int.txt"
expect "a script's light_intensity 3.4e38: exit 2" 2 "s_int.txt:2: light_intensity needs an intensity in \[0, 1e12\]" "$play" "$tmp/c.gto" --headless --width 16 --height 16 --script "$tmp/s_int.txt" --out-pattern "$tmp/f%d.png"
printf '0 light_pos 0 1e30 0\n' >"$tmp/s_pos.txt"
expect "a script's light_pos 0 1e30 0: exit 2" 2 "s_pos.txt:1: light_pos needs three numbers, each within" "$play" "$tmp/c.gto" --headless --width 16 --height 16 --script "$tmp/s_pos.txt" --out-pattern "$tmp/f%d.png"
P2=("$play" "$tmp/c.gto" --headless --width 16 --height 16 -o "$tmp/n.exr")
expect "the largest values allowed still give a picture: exit 0" 0 "" "${P2[@]}" --light-intensity 1e12 --light-color 1000,1000,1000 --light-scale 1=1000
"$build/tests/test_image" --stats "$tmp/n.exr" >"$tmp/stats.txt" 2>"$tmp/err"
python3 - "$tmp/stats.txt" <<'PY' && ok "that picture is finite everywhere (EXR mean, min, max)" || ko "that picture is finite everywhere (EXR mean, min, max)"
import math, re, sys
t = open(sys.argv[1]).read().split(':', 1)[1]
v = [float(x) for x in re.findall(r'(?<![0-9x])[-+]?(?:[0-9.]+(?:e[-+]?[0-9]+)?|nan|inf)', t)]
sys.exit(0 if len(v) >= 7 and all(math.isfinite(x) for x in v) and max(v) > 0 else 1)
PY

# ---- 6 text from a file (names, provenance) printed for a terminal: no raw control bytes
noctl() { if LC_ALL=C grep -q $'[\x01-\x08\x0b-\x1f\x7f]' "$2"; then ko "$1"; else ok "$1"; fi; }
"$bake" --scan "$hostile" >"$tmp/scan.txt" 2>"$tmp/err"
grep -q 'esc \\x1b\[31m red \\x07 bell' "$tmp/scan.txt" && ok "--scan shows an escape code in a name as \\x1b" || ko "--scan shows an escape code in a name as \\x1b"
noctl "--scan prints no raw control character" "$tmp/scan.txt"
"$bake" --info "$tmp/h.gto" >"$tmp/info.txt" 2>"$tmp/err"
noctl "--info prints no raw control character" "$tmp/info.txt"

# ---- 7 wrt-play: bounded scripts; a .gto truncated or replaced while it plays
printf '0 light_pos 0 1 0\n1e6 light_pos 0 1.5 0\n' >"$tmp/long.txt"
expect "a script asking for 10^9 frames: exit 2" 2 "long.txt: the keyframes ask for 1e\+09 frames .*; at most 100000" "$play" "$tmp/c.gto" --headless --width 16 --height 16 --script "$tmp/long.txt" --script-fps 1000 --out-pattern "$tmp/long_%d.png"
ls "$tmp" | grep -q '^long_' && ko "no frame written before the refusal" || ok "no frame written before the refusal"
# 400 frames; as soon as the first is written, the file is truncated, then a new bake is
# copied over it: every frame still comes out, exit 0 (a shared mapping died with SIGBUS)
cp "$tmp/c.gto" "$tmp/live.gto"
{ echo "0 light_pos 0 1.0 0"; echo "399 light_pos 0 1.8 0"; } >"$tmp/sweep.txt"
mkdir -p "$tmp/frames"
"$play" "$tmp/live.gto" --headless --width 24 --height 16 --msaa 1 --script "$tmp/sweep.txt" --script-fps 1 \
    --out-pattern "$tmp/frames/f_%04d.png" --stats-json "$tmp/live_stats.json" >/dev/null 2>"$tmp/play_err" &
pid=$!
for _ in $(seq 1 600); do [ -e "$tmp/frames/f_0000.png" ] && break; kill -0 $pid 2>/dev/null || break; sleep 0.05; done
truncate -s 100 "$tmp/live.gto"; at_truncate=$(ls "$tmp/frames" | wc -l)
sleep 0.2; cp "$tmp/h.gto" "$tmp/live.gto"
wait $pid; rc=$?
nframes=$(ls "$tmp/frames" | grep -c '^f_')
echo "    truncated after $at_truncate of 400 frames; exit $rc, $nframes frames"
if [ "$at_truncate" -ge 400 ]; then skipped "the player finished before the truncate (too fast here)"
elif [ $rc -eq 0 ] && [ "$nframes" -eq 400 ]; then ok "a .gto truncated and replaced while playing: exit 0, 400 frames"
else cp "$tmp/play_err" "$tmp/err"; ko "a .gto truncated and replaced while playing: exit 0, 400 frames"; fi
# the statistics written after the frames come from the data read at the start: the same
# bytes as a run on an untouched copy (a shared mapping read zeros here: "the camera's
# position (0, 0, 0) equals its target", no statistics, and still exit 0)
"$play" "$tmp/c.gto" --headless --width 24 --height 16 --msaa 1 --script "$tmp/sweep.txt" --script-fps 1 \
    --out-pattern "$tmp/frames/g_%04d.png" --stats-json "$tmp/ref_stats.json" >/dev/null 2>"$tmp/err"
sed 's/"file": "[^"]*"//' "$tmp/live_stats.json" >"$tmp/a.json" 2>/dev/null
sed 's/"file": "[^"]*"//' "$tmp/ref_stats.json" >"$tmp/b.json" 2>/dev/null
[ -s "$tmp/a.json" ] && cmp -s "$tmp/a.json" "$tmp/b.json" && ok "its --stats-json equals an untouched run's" || ko "its --stats-json equals an untouched run's"
expect "the truncated file is refused when opened: exit 2" 2 "short.gto" bash -c "head -c 100 '$tmp/c.gto' >'$tmp/short.gto'; '$play' '$tmp/short.gto' --headless -o '$tmp/s.png'"

# ---- 8 out of memory (ulimit -v): exit 7 with a message, never abort() or a crash
if [[ "$build" == *sanitize* ]]; then
    skipped "out of memory under ulimit -v: AddressSanitizer needs terabytes of address space"
else
    python3 - "$tmp/big.gltf" <<'PY'
import base64, json, sys
d = json.load(open('tests/data/quad.gltf'))
raw = base64.b64decode(d['buffers'][0]['uri'].split(',')[1]) + b'\0' * (40 << 20)
d['buffers'][0].update(uri='data:application/octet-stream;base64,' + base64.b64encode(raw).decode(), byteLength=len(raw))
open(sys.argv[1], 'w').write(json.dumps(d))
PY
    n7=0; nbad=0
    # limits in KiB: from where the loader itself cannot map the libraries to where a
    # quality-3 Cornell box bakes (about 230 MB of address space with Embree's threads)
    for kb in 50000 70000 100000 150000 190000 200000 210000 400000; do
        ( ulimit -v $kb; exec "$bake" assets/cornell.gltf -o "$tmp/oom.gto" -q 3 --quiet ) >/dev/null 2>"$tmp/err"; rc=$?
        line=$(head -n 1 "$tmp/err")
        case $rc in
            0) ;;
            # one line of ours; libstdc++ may print its own "terminate called ..." line
            # first when a library gives up under the limit (cli/cli.c, early_crash)
            7) if tail -n 1 "$tmp/err" | grep -q "^wrt-bake: error: .*out of memory" &&
                  { [ "$(wc -l <"$tmp/err")" -eq 1 ] || { [ "$(wc -l <"$tmp/err")" -eq 2 ] && head -n 1 "$tmp/err" | grep -q "^terminate called"; }; }; then
                   n7=$((n7 + 1)); else nbad=$((nbad + 1)); echo "    $kb KiB: exit 7 but '$line'"; fi ;;
            127) echo "    $kb KiB: the dynamic loader cannot map the libraries (before main)" ;;
            *) nbad=$((nbad + 1)); echo "    $kb KiB: exit $rc: $line" ;;
        esac
    done
    [ $nbad -eq 0 ] && [ $n7 -ge 2 ] && ok "bake under ulimit -v: exit 7 with one 'out of memory' line each time ($n7 limits), or 0" || ko "bake under ulimit -v: exit 7 with one 'out of memory' line each time ($n7 limits), or 0"
    ( ulimit -v 150000; exec "$bake" --scan "$tmp/big.gltf" ) >/dev/null 2>"$tmp/err"; rc=$?
    [ $rc -eq 7 ] && grep -q "big.gltf: out of memory while reading glTF\|out of memory allocating" "$tmp/err" && ok "a 56 MB glTF under 150 MB: exit 7 (the C++ reader's bad_alloc caught)" || { echo "    exit $rc"; ko "a 56 MB glTF under 150 MB: exit 7 (the C++ reader's bad_alloc caught)"; }
    ls "$tmp" | grep -q 'oom\.gto\.tmp' && ko "no temporary left after an out-of-memory exit" || ok "no temporary left after an out-of-memory exit"
fi

# ---- spot cones that differ only below float precision: the reader and the runtime apply
# one rule (inner < outer in single precision), so the scene is refused when read instead
# of a bake the player then lights with nothing
sed 's/"innerConeAngle":0.5235988,"outerConeAngle":0.6981317/"innerConeAngle":0.69813170000001,"outerConeAngle":0.69813170000002/' \
    assets/maze.gltf >"$tmp/cones.gltf"
grep -q '0.69813170000002' "$tmp/cones.gltf" && expect "spot cones equal in single precision: exit 2" 2 \
    "cone angles inner 0.698131.* are equal in single precision" "$bake" "$tmp/cones.gltf" -o "$tmp/cones.gto" -q 1 ||
    ko "spot cones equal in single precision: the test scene"
[ ! -e "$tmp/cones.gto" ] && ok "no file from the refused scene" || ko "no file from the refused scene"

# ---- 9 the second pass (session 3): file size limits, names on stderr, coincident
# elements, a scene too small for the method
# ulimit -f: the write fails (EFBIG) instead of SIGXFSZ killing the program mid-write
# with its temporary left and no message; OpenImageIO's PNG writer ignored the failed
# write and a cut PNG was renamed over the target with exit 0
mkdir -p "$tmp/fsz"
fsz() {
    local name=$1 blocks=$2; shift 2
    ( ulimit -f "$blocks"; exec "$@" ) >/dev/null 2>"$tmp/err"; local rc=$?
    if [ $rc -eq 3 ] && grep -q "File too large" "$tmp/err"; then ok "$name under ulimit -f $blocks: exit 3, 'File too large'"
    else echo "    exit $rc"; ko "$name under ulimit -f $blocks: exit 3, 'File too large'"; fi
}
# (cornell q1 is 100 KB since the drop rule: 50 blocks stay well under it)
fsz "wrt-bake -o" 50 "$bake" assets/cornell.gltf -q 1 -o "$tmp/fsz/c.gto" --quiet
fsz "wrt-play -o PNG" 10 "$play" "$tmp/c.gto" --headless --width 512 --height 512 -o "$tmp/fsz/p.png"
fsz "wrt-play -o EXR" 10 "$play" "$tmp/c.gto" --headless --width 512 --height 512 -o "$tmp/fsz/p.exr"
fsz "wrt-scenegen -o" 1 "$build/wrt-scenegen" maze --res 8 -o "$tmp/fsz/m.gltf"
fsz "wrt-ref -o" 1 "$build/wrt-ref" assets/cornell.gltf --width 256 --height 256 --spp 1 -o "$tmp/fsz/r"
[ -z "$(ls -A "$tmp/fsz")" ] && ok "nothing left in the output folder after the refused writes" || { ls "$tmp/fsz"; ko "nothing left in the output folder after the refused writes"; }

# names from the file on stderr: escape codes, newlines and invalid UTF-8 shown as \xNN
python3 - "$S" <<'PY2'
import json, sys
d = json.load(open('tests/data/quad.gltf'))
d['extensionsUsed'] = ['KHR_lights_punctual']
d['extensions'] = {'KHR_lights_punctual': {'lights': [{'type': 'point', 'intensity': 3.0,
                                                       'name': 'red \x1b[31m\nFAKE: ok \x9b2J'}]}}
d['nodes'].append({'extensions': {'KHR_lights_punctual': {'light': 0}}, 'translation': [1e30, 0.5, 1]})
d['scenes'][0]['nodes'].append(1)
open(sys.argv[1] + '/ctl_name.gltf', 'w').write(json.dumps(d))
PY2
expect "a light named with ESC, a newline and CSI: exit 2" 2 "light 'red \\\\x1b\[31m\\\\x0aFAKE: ok \\\\xc2\\\\x9b2J'" "$bake" --scan "$S/ctl_name.gltf"
noctl "its message holds no raw control character" "$tmp/err"
[ "$(wc -l <"$tmp/err")" -eq 1 ] && ok "its message is one line (the newline in the name escaped)" || ko "its message is one line (the newline in the name escaped)"

# coincident duplicates: the Cornell box's floor instanced twice at one place is warned
# about, naming both elements; a back-to-back pair (opposite normals) is not a duplicate
python3 - "$S" <<'PY2'
import json, sys
d = json.load(open('assets/cornell.gltf'))
floor = next(i for i, n in enumerate(d['nodes']) if n.get('mesh') == 0)
d['nodes'].append(dict(d['nodes'][floor], name='copy'))
d['scenes'][0]['nodes'].append(len(d['nodes']) - 1)
open(sys.argv[1] + '/dup.gltf', 'w').write(json.dumps(d))
q = json.load(open('tests/data/quad.gltf'))
q['nodes'].append({'mesh': 0, 'rotation': [1, 0, 0, 0], 'translation': [0, 1, 0]})  # turned over onto the same square
q['scenes'][0]['nodes'].append(1)
open(sys.argv[1] + '/backtoback.gltf', 'w').write(json.dumps(q))
PY2
expect "the floor twice: a bake warns, exit 0" 0 "elements 0 \(mesh 0 'floor' primitive 0 triangles 0 and 1, node 0\) and [0-9]+ \(mesh 0 'floor' .*node [0-9]+\) occupy the same place facing the same way" \
    "$bake" "$S/dup.gltf" -q 1 -o "$tmp/dup.gto" --quiet
"$bake" --scan "$S/dup.gltf" --json >"$tmp/dup.json" 2>"$tmp/err"
python3 -c "import json,sys; sys.exit(0 if json.load(open(sys.argv[1]))['coincident_pairs'] == 1 else 1)" "$tmp/dup.json" &&
    ok "--scan --json counts 1 coincident pair" || ko "--scan --json counts 1 coincident pair"
"$bake" --scan assets/cornell.gltf --json >"$tmp/c.json" 2>"$tmp/err"
python3 -c "import json,sys; sys.exit(0 if json.load(open(sys.argv[1]))['coincident_pairs'] == 0 else 1)" "$tmp/c.json" &&
    ok "the Cornell box has none" || ko "the Cornell box has none"
"$bake" "$S/backtoback.gltf" -q 1 -o "$tmp/b2b.gto" --quiet >/dev/null 2>"$tmp/err"
grep -q "same place" "$tmp/err" && ko "two faces back to back are not duplicates" || ok "two faces back to back are not duplicates"

# a scene smaller than the method works at: refused where it is read (it used to bake,
# then its 1e-60 m^2 areas were 0 in the .gto and the write refused it, exit 3)
python3 -c "
import json,sys; d=json.load(open('tests/data/quad.gltf')); d['nodes'][0]['scale']=[1e-30]*3
open(sys.argv[1],'w').write(json.dumps(d))" "$S/tiny.gltf"
expect "a scene 1.4e-30 m across: exit 2" 2 "tiny.gltf: the scene is 1.41421e-30 m across .*below the 1e-06 m" "$bake" "$S/tiny.gltf" -q 1 -o "$tmp/tiny.gto"

# a camera's field of view so narrow that the projection loses the pixels in single
# precision (1e-10 rad: half the picture black, exit 0): refused where it is read
python3 -c "
import json,sys; d=json.load(open('assets/cornell.gltf')); d['cameras'][0]['perspective']['yfov']=1e-10
open(sys.argv[1],'w').write(json.dumps(d))" "$S/yfov.gltf"
expect "a camera yfov of 1e-10 rad: exit 2" 2 "camera of node [0-9]+: yfov 1e-10 \(radians, \[0.0001, pi\)" "$bake" --scan "$S/yfov.gltf"

# an output that is an input of the same run (wrt-play --stats-json naming the .gto it
# plays replaced the bake with JSON, exit 0): refused by device and inode, so also
# through a hard link, the input's bytes unchanged (common/outfile.c wrt_output_protect)
cp "$tmp/c.gto" "$tmp/in.gto"; ln -f "$tmp/in.gto" "$tmp/in_link.json"
expect "wrt-play --stats-json naming its own .gto: exit 3" 3 "in.gto: is .*in.gto, an input of this run: not replaced" \
    "$play" "$tmp/in.gto" --headless --width 8 --height 8 --stats-json "$tmp/in.gto"
expect "the same through a hard link: exit 3" 3 "in_link.json: is .*in.gto, an input of this run" \
    "$play" "$tmp/in.gto" --headless --width 8 --height 8 --stats-json "$tmp/in_link.json"
cmp -s "$tmp/in.gto" "$tmp/c.gto" && ok "the .gto is unchanged" || ko "the .gto is unchanged"
# a script that is not text: /dev/zero gave an endless run of empty lines (a hang)
expect "--script /dev/zero: exit 2" 2 "/dev/zero:1: a line longer than 4095 bytes or holding a NUL byte" \
    timeout 30 "$play" "$tmp/c.gto" --headless --width 8 --height 8 --script /dev/zero --out-pattern "$tmp/z%d.png"
printf '0 light_pos 0 1 0\n1 \033[31mkey\n' >"$tmp/esc.txt"
expect "a script's unknown key with an escape code is shown escaped" 2 "esc.txt:2: unknown key '\\\\x1b\[31mkey'" \
    "$play" "$tmp/c.gto" --headless --width 8 --height 8 --script "$tmp/esc.txt" --out-pattern "$tmp/z%d.png"

# the programs that link OpenImageIO under a memory limit: its dependencies' static
# constructors threw std::system_error (abort, 134) or crashed (139) before main; now
# every limit ends in 0, 7 with one "out of memory" line, or the dynamic loader's own
# refusal (127) before any code of ours runs
if [[ "$build" == *sanitize* ]]; then
    skipped "OpenImageIO programs under ulimit -v: AddressSanitizer needs terabytes of address space"
else
    nbad=0; n7=0
    for kb in 380000 400000 420000 440000 450000 460000 470000 480000 490000 500000 520000; do
        for prog in wrt-play wrt-ref wrt-compare; do
            ( ulimit -v $kb; exec "$build/$prog" --version ) >/dev/null 2>"$tmp/err"; rc=$?
            case $rc in
                0|127) ;;
                7) if grep -q "out of memory" "$tmp/err" && [ "$(wc -l <"$tmp/err")" -eq 1 ]; then n7=$((n7 + 1)); else nbad=$((nbad + 1)); fi ;;
                *) nbad=$((nbad + 1)); echo "    $prog at $kb KiB: exit $rc" ;;
            esac
        done
    done
    echo "    $n7 of 33 runs ended in exit 7"
    [ $nbad -eq 0 ] && ok "wrt-play, wrt-ref, wrt-compare under ulimit -v 380-520 MB: exit 0, 7 (one line) or 127, never a crash" ||
        ko "wrt-play, wrt-ref, wrt-compare under ulimit -v 380-520 MB: exit 0, 7 (one line) or 127, never a crash"
fi

# ---- third pass (session 4): a fresh attack's faults, one check each
python3 - "$S" <<'PY'
import json, sys
out = sys.argv[1]
d0 = json.load(open('tests/data/quad.gltf'))
def variant(name, f):
    d = json.loads(json.dumps(d0)); f(d); open(f"{out}/{name}", 'w').write(json.dumps(d))
def emissive(d):
    d['materials'] = [{'emissiveFactor': [1, 1, 1],
                       'extensions': {'KHR_materials_emissive_strength': {'emissiveStrength': 3e38}}}]
    d['extensionsUsed'] = ['KHR_materials_emissive_strength']
    for m in d['meshes']:
        for p in m['primitives']: p['material'] = 0
variant('emit_huge.gltf', emissive)
variant('mat_proj.gltf', lambda d: d['nodes'][0].update(matrix=[1,0,0,0.5, 0,1,0,0, 0,0,1,0, 0,0,0,1]))
variant('mat_w0.gltf', lambda d: d['nodes'][0].update(matrix=[1,0,0,0, 0,1,0,0, 0,0,1,0, 0,0,0,0]))
variant('mime.gltf', lambda d: d['buffers'][0].update(uri=d['buffers'][0]['uri'].replace('application/octet-stream', 'text/html')))
variant('len_lie.gltf', lambda d: d['buffers'][0].update(byteLength=10**12))
c = json.load(open('assets/cornell.gltf'))   # its short box (node 5) has NORMALs
c['nodes'][5]['scale'] = [1, 0, 1]
open(f"{out}/flat.gltf", 'w').write(json.dumps(c))
PY
# an emissiveStrength of 3e38 (below FLT_MAX): the emitter's power was inf, the indirect light NaN, exit 0
expect "emissiveStrength 3e38: exit 2" 2 "emissiveStrength: 3e\+38 is outside \[0, 1e\+12\]" "$bake" --scan "$S/emit_huge.gltf"
# a node matrix with a projective last row: its last row was ignored without a word
expect "a projective node matrix: exit 2" 2 "nodes\[0\].matrix: last row \(0.5, 0, 0, 1\) is not \(0, 0, 0, 1\)" \
    "$bake" --scan "$S/mat_proj.gltf"
expect "a node matrix whose w is 0: exit 2" 2 "last row \(0, 0, 0, 0\) is not \(0, 0, 0, 1\)" "$bake" --scan "$S/mat_w0.gltf"
# a buffer's data uri of another media type, or a byteLength the uri does not hold: tinygltf
# said "File not found" or "Failed to decode 'uri'", then 600 bytes of base64
expect "a data uri of type text/html: exit 2, named" 2 "buffers\\[0\\].uri: a data uri of type 'text/html;base64'" \
    "$bake" --scan "$S/mime.gltf"
expect "byteLength 1e12 for a short data uri: exit 2, both lengths" 2 "buffers\\[0\\].byteLength: 1000000000000, but its data uri holds [0-9]+ bytes" \
    "$bake" --scan "$S/len_lie.gltf"
# a node scaled by 0 on an axis: the message blamed the (unit) NORMAL, not the transform
expect "a node scaled flat: exit 2, the node named" 2 "nodes\\[5\\]: its world transform has zero scale \\(determinant 0\\): it flattens mesh 5" \
    "$bake" --scan "$S/flat.gltf"
# wrt-ref --points /dev/zero read NUL lines forever (a hang)
expect "wrt-ref --points /dev/zero: exit 2" 2 "/dev/zero:1: a line longer than 510 bytes or holding a NUL byte" \
    timeout 30 "$build/wrt-ref" assets/cornell.gltf --no-image --points /dev/zero
# a cone whose angles differ only below float precision: passed the option check, then the
# library refused it as "light 0" with exit 2
expect "--light-cone 0.5,0.50000001: exit 1" 1 "--light-cone: '0.5,0.50000001' .*distinct as 32-bit floats" \
    "$play" "$tmp/c.gto" --headless --width 8 --height 8 -o "$tmp/cone.png" --light-dir 0,-1,0 --light-cone 0.5,0.50000001
# wrt-scenegen icosphere --res 20 made 20 x 4^6 triangles without a word
expect "icosphere --res 20: exit 1" 1 "--res 20: the icosphere takes --res 1..6" \
    "$build/wrt-scenegen" icosphere --res 20 -o "$tmp/ico.gltf"
[ ! -e "$tmp/ico.gltf" ] && ok "no icosphere written" || ko "no icosphere written"
# wrt-scenegen -o x.glb wrote glTF JSON under the binary form's name, exit 0
expect "wrt-scenegen -o x.glb: exit 1" 1 "x.glb: wrt-scenegen writes glTF JSON \\(.gltf\\), not binary glTF" \
    "$build/wrt-scenegen" cornell -o "$tmp/x.glb"
# a .gto with 1 GB appended (sparse): wrt-play read it whole (20 GB resident at 20 GB, the
# kernel's kill) before the reader refused the trailing data; now refused from the header
cp "$tmp/c.gto" "$tmp/long.gto"; truncate -s 1G "$tmp/long.gto"
expect "a bake with 1 GB appended: exit 2 before reading it" 2 "long.gto: trailing data: expected [0-9]+ bytes, found 1073741824 \(not read\)" \
    "$play" "$tmp/long.gto" --headless --width 8 --height 8 -o "$tmp/long.png"
rm -f "$tmp/long.gto"
# a stack limit of 64 KB: the bake ended in SIGSEGV (139, no message)
if [[ "$build" == *sanitize* ]]; then
    skipped "ulimit -s 64: AddressSanitizer's own start needs more stack"
else
    expect "ulimit -s 64: exit 7 naming the limit" 7 "the stack limit \(ulimit -s\) is 64 KB, below the 512 KB" \
        bash -c 'ulimit -s 64; exec "$0" "$@"' "$bake" assets/cornell.gltf -q 1 -o "$tmp/stack.gto"
fi

summary
