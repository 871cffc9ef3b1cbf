# wrt: Wavelet Radiance Transport. `make` builds build/wrt-bake, build/wrt-play and the
# tools; `make demo` installs what is missing, builds, bakes and renders the default scene;
# `make test` installs what is missing, builds and runs the test suite.
# Knobs: config=release|debug|sanitize, CC, CXX, JOBS.

config ?= release
CC ?= gcc
CXX ?= g++
BUILD ?= build
SHELL := /bin/bash

WARN := -Wall -Wextra -Wshadow -Wpointer-arith -Wstrict-prototypes -Wmissing-prototypes \
        -Wno-unused-parameter -Wvla -Wformat=2
CWARN := $(WARN) -Werror=implicit-function-declaration
CPPFLAGS += -MMD -MP -I. -D_GNU_SOURCE
CFLAGS_release := -O2 -g -march=x86-64-v2
CFLAGS_debug := -O0 -g3
CFLAGS_sanitize := -O1 -g -fsanitize=address,undefined -fno-omit-frame-pointer
LDFLAGS_sanitize := -fsanitize=address,undefined
CFLAGS += -std=c11 $(CWARN) $(CFLAGS_$(config)) -pthread
CXXFLAGS += -std=c++17 -Wall -Wextra -Wno-unused-parameter $(CFLAGS_$(config)) -pthread \
            -I/usr/include/stb -w
LDFLAGS += $(LDFLAGS_$(config)) -pthread

ifneq ($(config),release)
BUILD := build/$(config)
endif

# Quiet by default; `make V=1` shows the commands.
ifeq ($(V),1)
Q :=
else
Q := @
endif
.SECONDARY:
.SECONDEXPANSION:

LIBS_CORE := -lembree3 -lm
LIBS_IMG := -lOpenImageIO -lOpenImageIO_Util
LIBS_GL := -lglfw -lEGL -lGL

# Sources: every .c/.cpp in a part's folder, except its programs' main files.
CORE_SRC := $(wildcard common/*.c) $(wildcard formats/*.c) $(wildcard formats/*.cpp) $(wildcard cli/*.c)
BAKE_SRC := $(filter-out precompute/main.c,$(wildcard precompute/*.c))
# wrt-play's own files (its main, its command line, its scripted runs) are the program, not the display part.
PLAY_MAIN := player/main.c player/options.c player/headless.c
PLAY_SRC := $(filter-out $(PLAY_MAIN),$(wildcard player/*.c) $(wildcard player/*.cpp))
# The verification (the path tracer and the comparison): above the bake and the runtime,
# used only by programs (wrt-ref, wrt-compare, and wrt-bake's --max-error in its main.c).
VERIFY_SRC := $(wildcard verify/*.c)
RUNTIME_SRC := $(sort $(wildcard player/relight*.c)) player/gather.c player/wrt_runtime.c

obj = $(patsubst %.cpp,$(BUILD)/obj/%.o,$(patsubst %.c,$(BUILD)/obj/%.o,$(1)))
CORE_OBJ := $(call obj,$(CORE_SRC))
BAKE_OBJ := $(call obj,$(BAKE_SRC))
PLAY_OBJ := $(call obj,$(PLAY_SRC))
VERIFY_OBJ := $(call obj,$(VERIFY_SRC))
REF_OBJ := $(call obj,verify/reference.c)
RUNTIME_OBJ := $(call obj,$(RUNTIME_SRC))
ALL_LIB_OBJ := $(PLAY_OBJ) $(BAKE_OBJ) $(VERIFY_OBJ) $(CORE_OBJ)

# The runtime library (include/wrt.h): the base, the .gto reader and the relighting core;
# no loader, no image I/O, no OpenGL.
# Its objects are compiled with hidden visibility, one section per function and datum:
# only the API (WRT_API in include/wrt.h, listed by tools/api-symbols.sh) is exported, and what the API
# cannot reach (the .gto writer, its signal handlers, the aborting wrt_xmalloc) is
# dropped by --gc-sections. libwrt.a is one object, partially linked from the same
# objects with the API as roots and every other symbol made local (tools/link-static-lib.sh):
# nothing of wrt but the API can clash with an embedder's symbols (tests/exports.sh
# checks both libraries).
LIB_SRC := $(wildcard common/*.c) formats/gto_read.c formats/gto_check.c formats/gto_texture.c formats/gto_opcode.c formats/gto_kcode.c $(RUNTIME_SRC)
LIB_OBJ := $(call obj,$(LIB_SRC))
PIC_OBJ := $(patsubst %.c,$(BUILD)/pic/%.o,$(LIB_SRC))
LIBWRT := $(BUILD)/libwrt.a $(BUILD)/libwrt.so
PIC_FLAGS := -fPIC -fvisibility=hidden -ffunction-sections -fdata-sections

PROGRAMS := $(BUILD)/wrt-bake $(BUILD)/wrt-play $(BUILD)/wrt-ref $(BUILD)/wrt-scenegen $(BUILD)/wrt-compare
TEST_SRC := $(wildcard tests/test_*.c)
TESTS := $(patsubst tests/%.c,$(BUILD)/tests/%,$(TEST_SRC))

.PHONY: all deps demo test tests stress study fuzz fuzz-fast clean assets bench bench-scale timings mutate install
all: $(PROGRAMS) $(TESTS) $(LIBWRT) $(BUILD)/examples/relight $(BUILD)/examples/engine $(BUILD)/tests/runtime_instances \
     $(BUILD)/tests/runtime_api $(BUILD)/tests/runtime_core $(BUILD)/tests/runtime_budget $(BUILD)/tools/codec_study \
     $(BUILD)/tools/light_bw $(BUILD)/tools/op_kinds $(BUILD)/tools/gto_same $(BUILD)/tools/image_err

deps:
	@bash tools/install-deps.sh

# wrt-bake-mpi (docs/mpi.md): wrt-bake divided among MPI ranks, built when Open MPI's
# mpicc is found (Debian: libopenmpi-dev openmpi-bin, installed by `make deps`); wrt-bake
# itself needs no MPI.
MPICC ?= mpicc
HAVE_MPI := $(shell command -v $(MPICC) >/dev/null 2>&1 && echo 1)
ifeq ($(HAVE_MPI),1)
MPI_PROGRAM := $(BUILD)/wrt-bake-mpi
MPI_CFLAGS := $(shell $(MPICC) --showme:compile)
MPI_LIBS := $(shell $(MPICC) --showme:link)
endif
all: $(MPI_PROGRAM)

# A plain `make` on a machine without the packages names them and the command that
# installs them, before any compiler error (checked once per build directory).
$(BUILD)/.deps-checked: tools/check-deps.sh
	@bash tools/check-deps.sh $(CXX)
	@mkdir -p $(dir $@) && touch $@

$(BUILD)/obj/%.o: %.c | $(BUILD)/.deps-checked
	@mkdir -p $(dir $@)
	@$(if $(Q),echo "  CC      $<")
	$(Q)$(CC) $(CPPFLAGS) $(CFLAGS) -c $< -o $@

# (Makefile: a change of PIC_FLAGS must rebuild the library's objects.)
$(BUILD)/pic/%.o: %.c Makefile | $(BUILD)/.deps-checked
	@mkdir -p $(dir $@)
	@$(if $(Q),echo "  CC      $< (PIC)")
	$(Q)$(CC) $(CPPFLAGS) $(CFLAGS) $(PIC_FLAGS) -c $< -o $@

$(BUILD)/libwrt.a: $(PIC_OBJ) include/wrt.h tools/link-static-lib.sh
	@$(if $(Q),echo "  AR      $@")
	$(Q)bash tools/link-static-lib.sh $@ include/wrt.h $(PIC_OBJ)

$(BUILD)/libwrt.so: $(PIC_OBJ)
	@$(if $(Q),echo "  LINK    $@")
	$(Q)$(CC) -shared -Wl,-soname,libwrt.so.1 -Wl,--gc-sections $(LDFLAGS) $^ -o $@ $(LIBS_CORE)

# The examples, built against the library as an embedder would.
$(BUILD)/examples/%: examples/%.c $(BUILD)/libwrt.a include/wrt.h
	@mkdir -p $(dir $@)
	@$(if $(Q),echo "  CC      $<")
	$(Q)$(CC) -std=c11 $(CWARN) $(CFLAGS_$(config)) -Iinclude $< -o $@ $(BUILD)/libwrt.a $(LDFLAGS) $(LIBS_CORE)

# The runtime's instances test: the public header and libwrt.a, nothing else.
$(BUILD)/tests/runtime_instances: tests/runtime_instances.c $(BUILD)/libwrt.a include/wrt.h
	@mkdir -p $(dir $@)
	@$(if $(Q),echo "  CC      $<")
	$(Q)$(CC) -std=c11 $(CWARN) $(CFLAGS_$(config)) -D_GNU_SOURCE -Iinclude $< -o $@ $(BUILD)/libwrt.a $(LDFLAGS) $(LIBS_CORE)

# The public API's tests: runtime_api through the header and libwrt.a alone;
# runtime_core the same calls beside the relighting core they wrap (tests/runtime.sh).
$(BUILD)/tests/runtime_api $(BUILD)/tests/runtime_budget: $(BUILD)/tests/%: tests/%.c $(BUILD)/libwrt.a include/wrt.h
	@mkdir -p $(dir $@)
	@$(if $(Q),echo "  CC      $<")
	$(Q)$(CC) -std=c11 $(CWARN) $(CFLAGS_$(config)) -D_GNU_SOURCE -Iinclude $< -o $@ $(BUILD)/libwrt.a $(LDFLAGS) $(LIBS_CORE)
TEST_PARTS_runtime_core := runtime formats common

# make install PREFIX=DIR: the header, both libraries, wrt.pc and wrt-so.pc (pkg-config:
# wrt.pc gives libwrt.a with --static, libwrt.so without; tools/wrt.pc.in says how).
PREFIX ?= /usr/local
WRT_VERSION_TEXT = $$(sed -n 's/^\#define WRT_VERSION_STRING "\(.*\)"/\1/p' include/wrt.h)
install: $(LIBWRT)
	install -d $(DESTDIR)$(PREFIX)/include $(DESTDIR)$(PREFIX)/lib/pkgconfig
	install -m 644 include/wrt.h $(DESTDIR)$(PREFIX)/include/wrt.h
	install -m 644 $(BUILD)/libwrt.a $(DESTDIR)$(PREFIX)/lib/libwrt.a
	install -m 755 $(BUILD)/libwrt.so $(DESTDIR)$(PREFIX)/lib/libwrt.so.1
	ln -sf libwrt.so.1 $(DESTDIR)$(PREFIX)/lib/libwrt.so
	sed -e 's|@PREFIX@|$(PREFIX)|' -e 's|@VERSION@|'"$(WRT_VERSION_TEXT)"'|' \
	    tools/wrt.pc.in > $(DESTDIR)$(PREFIX)/lib/pkgconfig/wrt.pc
	sed -e 's|@PREFIX@|$(PREFIX)|' -e 's|@VERSION@|'"$(WRT_VERSION_TEXT)"'|' \
	    tools/wrt-so.pc.in > $(DESTDIR)$(PREFIX)/lib/pkgconfig/wrt-so.pc

$(BUILD)/obj/%.o: %.cpp | $(BUILD)/.deps-checked
	@mkdir -p $(dir $@)
	@$(if $(Q),echo "  CXX     $<")
	$(Q)$(CXX) $(CPPFLAGS) $(CXXFLAGS) -c $< -o $@

# wrt-bake: the bake library, and for --max-error (its main.c only) the verification
# with the runtime it measures. It writes no image: it links without OpenImageIO, whose
# libraries' constructors (log4cplus's thread, OIIO's string table) abort before main
# under a memory limit.
BAKE_CORE_OBJ := $(filter-out $(call obj,formats/image.cpp),$(CORE_OBJ))
$(BUILD)/wrt-bake: $(call obj,precompute/main.c) $(BAKE_OBJ) $(VERIFY_OBJ) $(RUNTIME_OBJ) $(BAKE_CORE_OBJ)
	@$(if $(Q),echo "  LINK    $@")
	$(Q)$(CXX) $(LDFLAGS) $^ -o $@ $(LIBS_CORE)

# wrt-bake-mpi: wrt-bake's main.c without its main (the same command line, bake_cli.h)
# and mpi/main_mpi.c's, which gives the bake its ranks.
$(BUILD)/obj-mpi/precompute/main.o: precompute/main.c | $(BUILD)/.deps-checked
	@mkdir -p $(dir $@)
	@$(if $(Q),echo "  CC      $< (no main)")
	$(Q)$(CC) $(CPPFLAGS) $(CFLAGS) -DWRT_BAKE_CLI_NO_MAIN -c $< -o $@

$(BUILD)/obj/mpi/main_mpi.o: mpi/main_mpi.c | $(BUILD)/.deps-checked
	@mkdir -p $(dir $@)
	@$(if $(Q),echo "  MPICC   $<")
	$(Q)$(CC) $(CPPFLAGS) $(CFLAGS) $(MPI_CFLAGS) -c $< -o $@

$(BUILD)/wrt-bake-mpi: $(BUILD)/obj/mpi/main_mpi.o $(BUILD)/obj-mpi/precompute/main.o $(BAKE_OBJ) $(VERIFY_OBJ) $(RUNTIME_OBJ) $(BAKE_CORE_OBJ)
	@$(if $(Q),echo "  LINK    $@")
	$(Q)$(CXX) $(LDFLAGS) $^ -o $@ $(MPI_LIBS) $(LIBS_CORE)

$(BUILD)/wrt-play: $(call obj,$(PLAY_MAIN)) $(PLAY_OBJ) $(CORE_OBJ)
	@$(if $(Q),echo "  LINK    $@")
	$(Q)$(CXX) $(LDFLAGS) $^ -o $@ $(LIBS_GL) $(LIBS_IMG) $(LIBS_CORE)

$(BUILD)/wrt-ref: $(call obj,tools/ref_main.c) $(REF_OBJ) $(CORE_OBJ)
	@$(if $(Q),echo "  LINK    $@")
	$(Q)$(CXX) $(LDFLAGS) $^ -o $@ $(LIBS_IMG) $(LIBS_CORE)

$(BUILD)/wrt-compare: $(call obj,tools/compare_main.c) $(VERIFY_OBJ) $(RUNTIME_OBJ) $(CORE_OBJ)
	@$(if $(Q),echo "  LINK    $@")
	$(Q)$(CXX) $(LDFLAGS) $^ -o $@ $(LIBS_IMG) $(LIBS_CORE)

# A light change against the memory bandwidth (issue 23, docs/bench.md): not installed.
$(BUILD)/tools/light_bw: tools/light_bw.c $(BUILD)/libwrt.a include/wrt.h
	@mkdir -p $(dir $@)
	@$(if $(Q),echo "  CC      $<")
	$(Q)$(CC) -std=c11 $(CWARN) $(CFLAGS_$(config)) -D_GNU_SOURCE -Iinclude $< -o $@ $(BUILD)/libwrt.a $(LDFLAGS) $(LIBS_CORE)

# The compact-entry study (issue 23, docs/bench.md "Compact entries"): not installed.
$(BUILD)/tools/codec_study: $(call obj,tools/codec_study.c) $(BAKE_OBJ) $(BAKE_CORE_OBJ)
	@mkdir -p $(dir $@)
	@$(if $(Q),echo "  LINK    $@")
	$(Q)$(CXX) $(LDFLAGS) $^ -o $@ $(LIBS_CORE)

# The stored operator's entries by kind (issue 22, docs/bench.md): not installed.
$(BUILD)/tools/op_kinds: $(call obj,tools/op_kinds.c) $(BAKE_OBJ) $(BAKE_CORE_OBJ)
	@mkdir -p $(dir $@)
	@$(if $(Q),echo "  LINK    $@")
	$(Q)$(CXX) $(LDFLAGS) $^ -o $@ $(LIBS_CORE)

# Whether two .gto files hold the same decoded operator (format 3.0's check): not installed.
$(BUILD)/tools/gto_same: $(call obj,tools/gto_same.c) $(BAKE_OBJ) $(BAKE_CORE_OBJ)
	@mkdir -p $(dir $@)
	@$(if $(Q),echo "  LINK    $@")
	$(Q)$(CXX) $(LDFLAGS) $^ -o $@ $(LIBS_CORE)

# The image error of a picture against the path tracer's (docs/triangles.md): not installed.
$(BUILD)/tools/image_err: $(call obj,tools/image_err.c) $(CORE_OBJ)
	@mkdir -p $(dir $@)
	@$(if $(Q),echo "  LINK    $@")
	$(Q)$(CXX) $(LDFLAGS) $^ -o $@ $(LIBS_IMG) $(LIBS_CORE)

$(BUILD)/wrt-scenegen: $(call obj,tools/scenegen.c tools/scenegen_gltf.c tools/scenegen_atrium.c) $(CORE_OBJ)
	@$(if $(Q),echo "  LINK    $@")
	$(Q)$(CXX) $(LDFLAGS) $^ -o $@ $(LIBS_IMG) $(LIBS_CORE)

# Tests link only what they test: each names the parts it needs (archives, so only the
# objects it reaches are linked), lowest last; a test not listed gets every part.
PART_common := $(wildcard common/*.c)
PART_formats := $(wildcard formats/*.c) $(wildcard formats/*.cpp)
PART_cli := $(wildcard cli/*.c)
PART_bake := $(BAKE_SRC)
PART_runtime := $(RUNTIME_SRC)
PART_display := $(filter-out $(PLAY_MAIN) $(PART_runtime),$(wildcard player/*.c))
PART_verify := $(VERIFY_SRC)
ALL_PARTS := display cli verify bake runtime formats common
TEST_PARTS_test_brdf := common
TEST_PARTS_test_text := common
TEST_PARTS_test_gto := formats common
TEST_PARTS_test_gto_compact := formats common
TEST_PARTS_test_gto_kcode := formats common
TEST_PARTS_test_image := formats common
TEST_PARTS_test_scene := formats common
TEST_PARTS_test_bake := bake formats common
TEST_PARTS_test_drop := bake formats common
TEST_PARTS_test_cluster := bake formats common
TEST_PARTS_test_sparse := bake formats common
TEST_PARTS_test_dist := bake formats common
TEST_PARTS_test_relight := runtime formats common
TEST_PARTS_test_gather := runtime formats common
TEST_PARTS_test_reconstruct := bake runtime formats common
TEST_PARTS_test_reference := verify formats common
TEST_PARTS_test_accuracy := verify bake runtime formats common
TEST_PARTS_test_stress := verify bake runtime formats common
TEST_PARTS_test_triangles := verify bake runtime formats common
TEST_PARTS_test_cover := bake formats common
TEST_PARTS_test_emit := verify bake runtime formats common
TEST_PARTS_test_texture := verify bake runtime formats common
TEST_PARTS_test_render := display cli formats common
TEST_PARTS_test_play := display cli runtime formats common
test_parts = $(or $(TEST_PARTS_$(1)),$(ALL_PARTS))

$(BUILD)/parts/%.a: $$(call obj,$$(PART_$$*))
	@mkdir -p $(dir $@)
	$(Q)rm -f $@ && ar rcs $@ $^

$(BUILD)/tests/%: $(BUILD)/obj/tests/%.o $$(foreach p,$$(call test_parts,$$*),$(BUILD)/parts/$$(p).a)
	@mkdir -p $(dir $@)
	@$(if $(Q),echo "  LINK    $@")
	$(Q)$(CXX) $(LDFLAGS) $^ -o $@ $(if $(filter display,$(call test_parts,$*)),$(LIBS_GL)) $(LIBS_IMG) $(LIBS_CORE)

# The fuzz targets (libFuzzer, clang): the glTF loader (fuzz_scene) and the .gto reader
# (fuzz_gto). `make fuzz` builds both and runs each for FUZZ_SECONDS (default 60) from
# the committed seeds, copied into FUZZ_DIR/corpus-* (which grow as they run).
# FUZZ_SAN picks the sanitizers (default AddressSanitizer + UBSan, which finds the most);
# `make fuzz-fast` builds with UBSan only into build/fuzz-fast, several times more
# executions per second, for long runs (the same corpora can be shared with -merge).
FUZZ_SECONDS ?= 60
FUZZ_DIR ?= build/fuzz
FUZZ_SCENE_C := tools/fuzz_scene.c common/wrt_common.c common/text.c formats/scene.c formats/scene_report.c formats/scene_dups.c formats/scene_normals.c common/texture.c
FUZZ_GTO_C := tools/fuzz_gto.c common/wrt_common.c common/text.c common/texture.c common/cluster_tree.c formats/gto_read.c formats/gto_check.c formats/gto_texture.c formats/gto_opcode.c formats/gto_kcode.c
FUZZ_SAN ?= -fsanitize=address,undefined -fno-sanitize-recover=all
FUZZ_CC = clang -std=c11 -g -O1 -fsanitize=fuzzer-no-link $(FUZZ_SAN) -I. -D_GNU_SOURCE
fuzz: $(FUZZ_DIR)/fuzz_scene $(FUZZ_DIR)/fuzz_gto
	@mkdir -p $(FUZZ_DIR)/corpus-scene $(FUZZ_DIR)/corpus-gto
	cp -n assets/*.gltf tests/data/*.gltf tests/data/*.glb $(FUZZ_DIR)/corpus-scene/ 2>/dev/null || true
	cp -n tests/data/gto/*.gto tests/data/fuzz_gto/* $(FUZZ_DIR)/corpus-gto/ 2>/dev/null || true
	$(FUZZ_DIR)/fuzz_scene -max_total_time=$(FUZZ_SECONDS) -max_len=65536 -rss_limit_mb=2048 $(FUZZ_DIR)/corpus-scene 2>&1 | tail -n 3
	$(FUZZ_DIR)/fuzz_gto -max_total_time=$(FUZZ_SECONDS) -max_len=65536 -rss_limit_mb=2048 $(FUZZ_DIR)/corpus-gto 2>&1 | tail -n 3
fuzz-fast:
	@$(MAKE) --no-print-directory fuzz FUZZ_DIR=build/fuzz-fast FUZZ_SAN='-fsanitize=undefined -fno-sanitize-recover=all'

$(FUZZ_DIR)/fuzz_scene: $(FUZZ_SCENE_C) formats/gltf_shim.cpp formats/gltf_strict.cpp $(wildcard formats/*.h common/*.h)
	@mkdir -p $(FUZZ_DIR)/obj-scene
	for f in $(FUZZ_SCENE_C); do $(FUZZ_CC) -c $$f -o $(FUZZ_DIR)/obj-scene/$$(basename $$f .c).o || exit 1; done
	clang++ -std=c++17 -g -O1 -fsanitize=fuzzer-no-link $(FUZZ_SAN) -I. -I/usr/include/stb -w -D_GNU_SOURCE \
	  -c formats/gltf_shim.cpp -o $(FUZZ_DIR)/obj-scene/gltf_shim.o
	clang++ -std=c++17 -g -O1 -fsanitize=fuzzer-no-link $(FUZZ_SAN) -I. -w -D_GNU_SOURCE \
	  -c formats/gltf_strict.cpp -o $(FUZZ_DIR)/obj-scene/gltf_strict.o
	clang++ -fsanitize=fuzzer $(FUZZ_SAN) $(FUZZ_DIR)/obj-scene/*.o -o $@ -lm

$(FUZZ_DIR)/fuzz_gto: $(FUZZ_GTO_C) $(wildcard formats/*.h common/*.h)
	@mkdir -p $(FUZZ_DIR)/obj-gto
	for f in $(FUZZ_GTO_C); do $(FUZZ_CC) -c $$f -o $(FUZZ_DIR)/obj-gto/$$(basename $$f .c).o || exit 1; done
	clang -fsanitize=fuzzer $(FUZZ_SAN) $(FUZZ_DIR)/obj-gto/*.o -o $@ -lm -pthread

assets: $(BUILD)/wrt-scenegen
	$(BUILD)/wrt-scenegen --all assets

test: deps
	@$(MAKE) --no-print-directory all
	@bash tests/run.sh $(BUILD)

stress: deps
	@$(MAKE) --no-print-directory all
	@WRT_STRESS_FULL=1 bash tests/run.sh $(BUILD) stress

# The mutation run (tests/mutate.sh): deliberate faults in the core numerics, one at a
# time, built into $(BUILD)/mutate; prints "N caught, N survived". MUTATIONS="id ..." selects.
mutate: deps
	@bash tests/mutate.sh --build $(BUILD) $(if $(MUTATE_MIN_SCORE),--min-score $(MUTATE_MIN_SCORE)) $(MUTATIONS)

DEMO_SCENE ?= assets/cornell.gltf
demo: deps
	@$(MAKE) --no-print-directory all
	$(BUILD)/wrt-bake --scan $(DEMO_SCENE)
	$(BUILD)/wrt-bake $(DEMO_SCENE) -o $(BUILD)/demo.gto
	$(BUILD)/wrt-play $(BUILD)/demo.gto --headless --out $(BUILD)/demo.png
	@echo "demo: wrote $(BUILD)/demo.gto and $(BUILD)/demo.png"

study: deps
	@$(MAKE) --no-print-directory all
	bash tools/study.sh $(STUDY_ARGS)

bench: all
	bash tools/bench.sh
	bash tools/readme_times.sh $(BUILD)

# Issue 22's scale benchmark (docs/bench.md, "Scale"): the atrium and the mazes, time,
# memory, bytes and light change against elements, slopes and plot in bench-scale/.
# Knobs through the environment: DETAILS, MAZES, QUALITY, CAP_MB, BAKE_OPTS, LABEL.
bench-scale: all
	nice -n 10 bash tools/bench_scale.sh $(BUILD) bench-scale

# The README's timings (its "Timings" table) measured again: CPU within a factor 2.
timings: all
	bash tools/readme_times.sh $(BUILD)

clean:
	rm -rf build

-include $(shell find $(BUILD) -name '*.d' 2>/dev/null)
