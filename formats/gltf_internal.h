/* gltf_internal.h: what the two halves of the glTF reader share (C++ only, internal):
 * gltf_shim.cpp (tinygltf, the accessors, the nodes, the C boundary) and gltf_strict.cpp
 * (the checks on the raw file before tinygltf sees it: GLB framing, JSON depth, the
 * strict schema/KHR_lights_punctual pass). Errors are thrown as shim_error and turned
 * into wrt_fail at the boundary in gltf_shim.cpp. Depends on gltf_shim.h (wrt_status). */
#ifndef WRT_GLTF_INTERNAL_H
#define WRT_GLTF_INTERNAL_H

#include <cstddef>
#include <string>

#include "gltf_shim.h"

/* An error with its status; thrown inside the shim, turned into wrt_fail at the boundary. */
struct shim_error {
    wrt_status status;
    std::string msg;
};

/* A shim_error with a printf-formatted message (gltf_shim.cpp). */
__attribute__((format(printf, 2, 3))) shim_error make_error(wrt_status s, const char *fmt, ...);

/* gltf_strict.cpp: each throws shim_error on what it refuses. */
void check_glb(const unsigned char *b, size_t size, const char *label);
void check_json_depth(const char *t, size_t n, const char *label);
/* Parses the JSON text and runs the reference checks and the strict pass on it (malformed
 * JSON is left to tinygltf's parser error): its warnings and its ignored fields' text. */
void strict_pass(const char *text, size_t text_len, const char *label, int allow_outside,
                 std::string *strict_warnings, std::string *ignored);

#endif
