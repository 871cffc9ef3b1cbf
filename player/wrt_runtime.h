/* wrt_runtime.h: the one thing wrt-play's renderer (player/render.c) takes from a runtime
 * beyond include/wrt.h: the file the runtime opened and validated, to build its draw
 * geometry from (quads, materials and whatever sections the renderer reads). Internal to
 * the programs: not exported by libwrt (no WRT_API), so that the player opens and
 * validates a .gto once, through wrt_runtime_open_path, and never reads it itself. */
#ifndef WRT_PLAYER_WRT_RUNTIME_H
#define WRT_PLAYER_WRT_RUNTIME_H

#include "../formats/gto.h"
#include "../include/wrt.h"

/* The runtime's validated file, valid until wrt_runtime_close; NULL for a dead handle. */
const wrt_gto *wrt_runtime_gto_of(const wrt_runtime *rt);

#endif
