/* image.h: image files for wrt (EXR holding linear float RGB radiance, PNG holding 8-bit
 * display values), written and read through OpenImageIO behind this C interface. The
 * implementation (image.cpp) is a thin C++ shim that catches every exception and exposes
 * no C++ type. Used by the player (frames, screenshots), the reference renderer and the
 * tests. Depends on wrt_common.h and OpenImageIO. Thread-safe (no shared state). */
#ifndef WRT_IMAGE_H
#define WRT_IMAGE_H

#include <stdint.h>
#include "../common/wrt_common.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Pixels are stored row after row, the top row first, 3 channels (RGB) per pixel. */

/* Writes linear float RGB to an OpenEXR file (half is not used: full 32-bit float).
 * Atomic: writes PATH.tmpXXXXXX.exr and renames it over `path`.
 * Errors: WRT_ERR_INVALID_ARG (bad size), WRT_ERR_IO. */
wrt_status wrt_image_write_exr(const char *path, const float *rgb, int width, int height);

/* Writes 8-bit RGB (already tone-mapped and encoded) to a PNG (or any 8-bit format
 * OpenImageIO knows by the extension). Atomic as above. */
wrt_status wrt_image_write_rgb8(const char *path, const uint8_t *rgb, int width, int height);

/* Reads any image OpenImageIO reads into float RGB (channels beyond 3 dropped, a grey
 * image copied to all three; 8-bit values become value/255, no decoding of sRGB).
 * *rgb is allocated with malloc; the caller frees it with free(). */
wrt_status wrt_image_read(const char *path, float **rgb, int *width, int *height);

/* True if `path` ends in ".exr" (case-insensitive): the caller picks linear or display
 * output from it. */
int wrt_image_is_exr(const char *path);

#ifdef __cplusplus
}
#endif

#endif
