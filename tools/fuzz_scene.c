/* fuzz_scene.c: libFuzzer target for the scene loader (formats/scene.c and the tinygltf
 * shim). Each input is loaded as given (JSON text, or GLB when it starts with "glTF"),
 * then once more wrapped in a GLB container whose JSON chunk is the input and whose BIN
 * chunk repeats its last bytes, so both readers see every input. External files resolve
 * against a folder that does not exist. Every scene that loads has its JSON summary
 * checked (tests/json_check.h). Built by `make fuzz`; the seeds are tests/data. */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "common/wrt_common.h"
#include "common/text.h"
#include "formats/scene.h"
#include "tests/json_check.h"

#include <stdio.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

/* Every message is safe for a terminal whatever the input's names (common/text.h): no
 * control byte, no C1 control, only valid UTF-8. A crash for the fuzzer if not. */
static void check_safe(const char *what, const char *msg) {
    const unsigned char *p = (const unsigned char *)msg;
    size_t len = strlen(msg);
    char unit[WRT_SAFE_UNIT_MAX];
    for (size_t i = 0, ulen; i < len;) {
        size_t n = wrt_text_safe_unit(p + i, len - i, 0, unit, &ulen);
        if (ulen != n || memcmp(unit, p + i, n) != 0) {
            fprintf(stderr, "fuzz: %s holds an unescaped byte 0x%02x at %zu: %s\n", what, p[i], i, msg);
            abort();
        }
        i += n;
    }
}

static void quiet(void *user, int level, const char *msg) {
    (void)level; (void)user;
    check_safe("a log message", msg);
}

/* A scene that loads is summarized as JSON (the --scan --json writer), which must parse
 * whatever names the input gave it: a crash for the fuzzer if not. */
static void load(const void *p, size_t n, int drop_bad) {
    wrt_load_options opt = {.drop_bad = drop_bad};
    wrt_scene s;
    if (wrt_scene_load_memory(p, n, "/nonexistent-wrt-fuzz", &opt, &s) != WRT_OK) {
        check_safe("the error", wrt_last_error());
        return;
    }
    char *buf = NULL;
    size_t len = 0;
    FILE *f = open_memstream(&buf, &len);
    if (f) {
        wrt_scene_print_summary(&s, 1, f);
        fclose(f);
        if (!json_check(buf, len)) {
            fprintf(stderr, "fuzz_scene: the JSON summary does not parse:\n%s\n", buf);
            abort();
        }
        free(buf);
    }
    wrt_scene_free(&s);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
    wrt_log_set_sink(quiet, NULL);
    load(data, size, size & 1);
    size_t jp = (size + 3) & ~(size_t)3, bl = size < 64 ? size : 64, bp = (bl + 3) & ~(size_t)3;
    size_t total = 20 + jp + (bp ? 8 + bp : 0);
    uint8_t *g = calloc(1, total);
    if (!g) return 0;
    uint32_t h[5] = {0x46546C67u, 2, (uint32_t)total, (uint32_t)jp, 0x4E4F534Au};
    memcpy(g, h, sizeof h);
    memset(g + 20, ' ', jp);
    if (size) memcpy(g + 20, data, size);
    if (bp) {
        uint32_t c[2] = {(uint32_t)bp, 0x004E4942u};
        memcpy(g + 20 + jp, c, 8);
        memcpy(g + 28 + jp, data + size - bl, bl);
    }
    if (jp) load(g, total, !(size & 1));
    free(g);
    return 0;
}
