/* Byte-level helpers shared by the .gto damage tests (test_gto_compact, test_gto_kcode):
 * read a written file whole, read and write its little-endian fields, find a section's
 * table entry and make every checksum right again, as a forger would. */
#ifndef WRT_TESTS_GTO_BYTES_H
#define WRT_TESTS_GTO_BYTES_H

#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "formats/gto.h"

/* The whole file at `path` (malloc'd; *len its length), or NULL with *len 0. */
static inline uint8_t *read_all(const char *path, size_t *len) {
    FILE *f = fopen(path, "rb");
    if (!f) { *len = 0; return NULL; }
    fseek(f, 0, SEEK_END);
    long n = ftell(f);
    fseek(f, 0, SEEK_SET);
    uint8_t *b = malloc(n > 0 ? (size_t)n : 1);
    *len = n > 0 ? fread(b, 1, (size_t)n, f) : 0;
    fclose(f);
    return b;
}

static inline uint64_t rd64(const uint8_t *b, size_t o) { uint64_t x; memcpy(&x, b + o, 8); return x; }
static inline uint32_t rd32(const uint8_t *b, size_t o) { uint32_t x; memcpy(&x, b + o, 4); return x; }
static inline void wr64(uint8_t *b, size_t o, uint64_t x) { memcpy(b + o, &x, 8); }

/* The table entry of section `id` (header 64 bytes, entries of 48: id, elem_size, offset
 * at 8, size at 16, count at 24, checksum at 32), or 0. */
static inline size_t entry_of(const uint8_t *b, uint32_t id) {
    uint32_t ns = rd32(b, 28);
    for (uint32_t i = 0; i < ns; i++)
        if (rd32(b, 64 + 48 * (size_t)i) == id) return 64 + 48 * (size_t)i;
    return 0;
}

/* Every section checksum and the header's made right, as a forger would. */
static inline void forge(uint8_t *b) {
    uint32_t ns = rd32(b, 28);
    for (uint32_t i = 0; i < ns; i++) {
        size_t e = 64 + 48 * (size_t)i;
        wr64(b, e + 32, wrt_gto_checksum(b + rd64(b, e + 8), (size_t)rd64(b, e + 16)));
    }
    wr64(b, 40, 0);
    wr64(b, 40, wrt_gto_checksum(b, 64 + 48 * (size_t)ns));
}

#endif
