/* scene_internal.h: declarations shared by the two halves of the glTF scene builder,
 * scene.c (loading, pairing) and scene_report.c (the summary): the name of a problem
 * kind, used by scene.c's messages and the summary alike. Not part of any API. */
#ifndef WRT_SCENE_INTERNAL_H
#define WRT_SCENE_INTERNAL_H

/* The short name of a WRT_PROBLEM_* kind ("unpaired", "non-planar", ...). */
const char *wrt_scene_problem_name(int kind);

#endif
