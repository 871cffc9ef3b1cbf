#!/usr/bin/env bash
# tools/check-layers.sh: prints every #include that points up or sideways in the layering
# (nothing when the tree is clean; exit 1 if anything was printed). Layers, lowest first:
#   0 include/        the public header (status codes, the runtime API)
#   1 common/         math, BRDF, BRDF table, threads, scene types
#   2 formats/        glTF loader, .gto reader/writer, images
#   3 precompute/     the bake (library part)      | 3 runtime: player/relight*.[ch], player/gather.*, player/wrt_runtime.[ch]
#   4 verify/         the path tracer and the comparison (the runtime only through include/wrt.h);
#                     precompute/ and the runtime do not see it: only programs (wrt-bake's main.c
#                     for --max-error, wrt-ref, wrt-compare) do
#   4 cli/            the programs' command-line helpers (options, exit codes, progress)
#   5 programs:       */main.c, tools/*_main.c, tools/scenegen*.[ch], tools/fuzz_*.c, player/render.*,
#                     player/platform*, examples/ (each program sees only its own files below 5)
# A file may include files of lower layers, or of its own part; precompute and the runtime
# do not see each other; above layer 3 the runtime is seen only through include/wrt.h,
# with one exception: wrt-play's main.c hands its renderer the file the runtime opened
# and validated (player/wrt_runtime.h, not exported by libwrt), so that the player reads
# and validates a .gto once; the renderer draws from the file's quads, materials and the
# optional sections other parts add, which the API's getters do not all carry yet.
cd "$(dirname "$0")/.." || exit 2
python3 - "$@" <<'PY'
import os, re, sys
def part(p):
    if p.startswith('include/'): return (0, 'include')
    if p.startswith('common/'): return (1, 'common')
    if p.startswith('formats/'): return (2, 'formats')
    if p.startswith('precompute/') and not p.endswith('main.c'): return (3, 'precompute')
    if re.match(r'player/(relight(_[a-z]+)?\.[ch]|gather\.[ch]|wrt_runtime\.[ch])$', p): return (3, 'runtime')
    if p.startswith('verify/'): return (4, 'verification')
    if p.startswith('cli/'): return (4, 'cli')
    if p.startswith('precompute/'): return (5, 'wrt-bake')
    if p.startswith('player/'): return (5, 'wrt-play')
    if p.startswith('examples/'): return (5, 'example')
    if re.match(r'tools/scenegen(_[a-z]+)?\.[ch]$', p): return (5, 'tool:scenegen')
    if p.startswith('tools/'): return (5, 'tool:' + os.path.basename(p))
    return None
bad = 0
for d in ['include', 'common', 'formats', 'precompute', 'player', 'verify', 'cli', 'tools', 'examples']:
    for root, _, files in os.walk(d):
        for f in files:
            if not re.search(r'\.(c|h|cpp)$', f): continue
            src = os.path.join(root, f)
            me = part(src)
            if not me: continue
            for n, line in enumerate(open(src, errors='replace'), 1):
                m = re.match(r'\s*#\s*include\s+"([^"]+)"', line)
                if not m: continue
                inc = m.group(1)
                tgt = os.path.normpath(os.path.join(root, inc))
                if not os.path.exists(tgt): tgt = os.path.normpath(inc)
                if not os.path.exists(tgt): continue
                it = part(tgt)
                if not it: continue
                ok = it[1] == me[1] or it[0] < me[0]
                if it[1] == 'runtime' and me[1] != 'runtime': ok = False  # only through include/wrt.h
                if tgt == 'player/wrt_runtime.h' and src == 'player/main.c': ok = True  # the exception above
                if it[0] == 5 and it[1] != me[1]: ok = False
                if not ok:
                    print(f'{src}:{n}: {me[1]} (layer {me[0]}) includes {tgt} ({it[1]}, layer {it[0]})')
                    bad = 1
sys.exit(bad)
PY
