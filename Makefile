# gimany.h - build, test, bench. `make test` and `make demo` install what they need (tools/install-deps.sh).
.PHONY: all test test-cpu test-gl test-cxx check-shaders shaders bench bench-full bench-gpu fuzz fuzz-short demo deps clean reference
.DEFAULT_GOAL := test

CC      ?= cc
WARN    := -Wall -Wextra -pedantic -Werror -Wshadow -Wstrict-prototypes -Wmissing-prototypes
CSTD    := -std=c99
# scene/ (the scene layer: scene.h, scene_gimany.h, street.h, room.h, lamps.h) and tests/support
# (gltest.h, testutil.h, framefix.h, ...). scene/ comes first: '#include "../tools/compare.c"'
# (bench_frame.c, cli_compare.c, gltest_reference.c) resolves through it to tools/compare.c.
INC     := -Iscene -Itests/support -I.
SAN     := -fsanitize=address,undefined -fno-sanitize-recover=all -fno-omit-frame-pointer
B       := build
DEPS    := tools/install-deps.sh

HDRS        := gimany.h shaders_embedded.h $(wildcard tests/support/*.h) scene/street.h scene/room.h scene/lamps.h
CPU_TESTS   := $(basename $(notdir $(wildcard tests/unit/test_*.c)))
GL_TESTS    := $(basename $(notdir $(wildcard tests/gl/gltest_*.c)))
BENCHES     := $(filter-out bench_gpu,$(basename $(notdir $(wildcard bench/src/bench_*.c bench/src/bench_*.cpp))))
FUZZERS     := $(basename $(notdir $(wildcard tests/fuzz/fuzz_*.c)))
FUZZERS     += fuzz_reference_gltf   # C++: the glTF loader of scene/scene.cpp, rule in 'ground truth'
SHADERS     := $(sort $(wildcard shaders/*.comp shaders/*.vert shaders/*.frag shaders/*.geom))
FUZZ_SECONDS ?= 300
FUZZ_SHORT  ?= 15

deps:
	@$(DEPS) build test gl shaders fuzz examples reference

# --- shaders ------------------------------------------------------------------------------
# shaders/*.glsl are not programs: embed_shaders puts them where a shader says #include "NAME"
$(B)/embed-shaders: tools/embed_shaders.c 
	@mkdir -p $(@D)
	$(CC) $(CSTD) $(WARN) -O2 $< -o $@

shaders: $(B)/embed-shaders
	$(B)/embed-shaders shaders_embedded.h $(SHADERS)

# The committed header must be what `make shaders` makes, and every shader must validate.
check-shaders: $(B)/embed-shaders
	@$(B)/embed-shaders $(B)/shaders_embedded.h $(SHADERS)
	@cmp -s $(B)/shaders_embedded.h shaders_embedded.h || { echo "shaders_embedded.h is stale: run 'make shaders' and commit it"; exit 1; }
	@for s in $(SHADERS); do EMBED=$(B)/embed-shaders tools/validate-shader.sh $$s || exit 1; done
	@echo "shaders: $(words $(SHADERS)) validated, shaders_embedded.h up to date"

# --- tests --------------------------------------------------------------------------------
# CPU tests: no GL at all, gcc with ASan+UBSan and clang -O2 with UBSan.
$(B)/asan/%: tests/unit/%.c $(HDRS) 
	@mkdir -p $(@D)
	gcc $(CSTD) $(WARN) $(INC) -O1 -g $(SAN) -DGIMANY_NO_GL $< -o $@ -lcmocka -lm
$(B)/clang/%: tests/unit/%.c $(HDRS) 
	@mkdir -p $(@D)
	clang $(CSTD) $(WARN) $(INC) -O2 -g -fsanitize=undefined -fno-sanitize-recover=all -DGIMANY_NO_GL $< -o $@ -lcmocka -lm
# The same CPU tests without sanitizers, run under valgrind (no leaks, no invalid reads).
$(B)/plain/%: tests/unit/%.c $(HDRS)
	@mkdir -p $(@D)
	gcc $(CSTD) $(WARN) $(INC) -O1 -g -DGIMANY_NO_GL $< -o $@ -lcmocka -lm
# GL tests: headless EGL on Mesa llvmpipe, ASan+UBSan.
$(B)/gl/%: tests/gl/%.c $(HDRS) 
	@mkdir -p $(@D)
	gcc $(CSTD) $(WARN) $(INC) -O1 -g $(SAN) $< -o $@ -lcmocka -lEGL -lGL -lm
# The whole-frame test loads its scenes through the scene layer scene/ (C++ inside).
$(B)/gl/gltest_frame $(B)/gl/gltest_vplframe $(B)/gl/gltest_hoststate $(B)/gl/gltest_refuse $(B)/gl/gltest_queries $(B)/gl/gltest_temporal: $(B)/gl/%: tests/gl/%.c $(B)/ref/asan/scene.o scene/scene.h scene/scene_gimany.h $(HDRS)
	@mkdir -p $(@D)
	gcc $(CSTD) $(WARN) $(INC) -O1 -g $(SAN) $< $(B)/ref/asan/scene.o -o $@ -lcmocka -lEGL -lGL -lm -lstdc++
# Every method against the Embree reference, rendered in-process: the scene layer and the
# renderer at -O2 without sanitizers (the reference's own ASan test is test_reference; here it
# would triple the references' time in a clean build).
$(B)/gl/gltest_reference: tests/gl/gltest_reference.c $(B)/ref/asan/scene.o $(B)/ref/reference.o scene/scene.h scene/scene_gimany.h tools/reference/reference.h tools/compare.c tools/compare.h $(HDRS)
	@mkdir -p $(@D)
	gcc $(CSTD) $(WARN) $(INC) -Itools -Itools/reference -O1 -g $(SAN) $< $(B)/ref/asan/scene.o $(B)/ref/reference.o -o $@ -lcmocka -lEGL -lGL -lembree3 -lm -lstdc++ -pthread
# C++11 with g++ and clang++, and two translation units (implementation in one).
$(B)/cxx/two_tu_gcc: tests/compile/cxx_impl.cpp tests/compile/cxx_user.cpp $(HDRS) 
	@mkdir -p $(@D)
	g++ -std=c++11 $(filter-out -Wstrict-prototypes -Wmissing-prototypes,$(WARN)) $(INC) -O1 $(SAN) tests/compile/cxx_impl.cpp tests/compile/cxx_user.cpp -o $@ -lEGL -lGL -lm
$(B)/cxx/two_tu_clang: tests/compile/cxx_impl.cpp tests/compile/cxx_user.cpp $(HDRS) 
	@mkdir -p $(@D)
	clang++ -std=c++11 $(filter-out -Wstrict-prototypes -Wmissing-prototypes,$(WARN)) $(INC) -O2 tests/compile/cxx_impl.cpp tests/compile/cxx_user.cpp -o $@ -lEGL -lGL -lm
$(B)/cxx/two_tu_c: tests/compile/two_tu_a.c tests/compile/two_tu_b.c $(HDRS) 
	@mkdir -p $(@D)
	clang $(CSTD) $(WARN) $(INC) -O1 -DGIMANY_NO_GL tests/compile/two_tu_a.c tests/compile/two_tu_b.c -o $@ -lm

CPU_BINS := $(addprefix $(B)/asan/,$(CPU_TESTS)) $(addprefix $(B)/clang/,$(CPU_TESTS))
# test_physics (FULL LightSkin on closed-form scenes: ~10^8 VAL-cache terms) runs under ASan and
# UBSan only: valgrind would take it past ten minutes.
VG_BINS  := $(addprefix $(B)/plain/,$(filter-out test_physics,$(CPU_TESTS)))
GL_BINS  := $(addprefix $(B)/gl/,$(GL_TESTS))
$(B)/cxx/static_c: tests/compile/static_tu.c $(HDRS)
	@mkdir -p $(@D)
	gcc $(CSTD) $(WARN) $(INC) -O1 $< -o $@ -lm
$(B)/cxx/static_cxx: tests/compile/static_tu.c $(HDRS)
	@mkdir -p $(@D)
	clang++ -x c++ -std=c++11 $(filter-out -Wstrict-prototypes -Wmissing-prototypes,$(WARN)) $(INC) -O1 $< -o $@ -lm

# Command-line tests of the examples: they run build/gimany-demo, build/gimany-viewer,
# build/gimany-host-buffers and build/gimany-minimal
# (the GLFW ones under Xvfb) and read back what they wrote.
CLI_CC := gcc $(CSTD) $(WARN) -Iscene -Itests/support -isystem /usr/include/stb -O1 -g $(SAN)
$(B)/cli/cli_demo: tests/cli/cli_demo.c tests/support/cliutil.h scene/scene.h $(B)/ref/asan/scene.o $(B)/gimany-demo
	@mkdir -p $(@D)
	$(CLI_CC) -DDEMO_BIN='"$(B)/gimany-demo"' $< $(B)/ref/asan/scene.o -o $@ -lcmocka -lm -lstdc++
$(B)/cli/cli_viewer: tests/cli/cli_viewer.c tests/support/cliutil.h $(B)/gimany-viewer $(B)/gimany-demo
	@mkdir -p $(@D)
	$(CLI_CC) -DVIEWER_BIN='"$(B)/gimany-viewer"' -DDEMO_BIN='"$(B)/gimany-demo"' $< -o $@ -lcmocka -lm
$(B)/cli/cli_host_buffers: tests/cli/cli_host_buffers.c tests/support/cliutil.h $(B)/gimany-host-buffers
	@mkdir -p $(@D)
	$(CLI_CC) -DHOST_BIN='"$(B)/gimany-host-buffers"' $< -o $@ -lcmocka -lm
$(B)/cli/cli_minimal: tests/cli/cli_minimal.c tests/support/cliutil.h $(B)/gimany-minimal
	@mkdir -p $(@D)
	$(CLI_CC) -DMINIMAL_BIN='"$(B)/gimany-minimal"' $< -o $@ -lcmocka -lm
CLI_BINS := $(B)/cli/cli_demo $(B)/cli/cli_viewer $(B)/cli/cli_compare $(B)/cli/cli_host_buffers $(B)/cli/cli_minimal

# The host-state tests again on a context that says 4.3, as NVIDIA's does when 4.3 is asked for
# (Mesa's MESA_GL_VERSION_OVERRIDE): glClipControl and glGetTextureParameteriv then come from
# their extensions (GL_ARB_clip_control, GL_ARB_direct_state_access), not from the version.
GL43_TESTS := gltest_hoststate gltest_runtime gltest_external gltest_refuse
GL43_BINS  := $(addprefix $(B)/gl43/,$(GL43_TESTS))
$(B)/gl43/%: $(B)/gl/%
	@mkdir -p $(@D)
	printf '#!/bin/sh\nMESA_GL_VERSION_OVERRIDE=4.3 exec $(CURDIR)/$< "$$@"\n' > $@
	chmod +x $@

CXX_BINS := $(B)/cxx/two_tu_gcc $(B)/cxx/two_tu_clang $(B)/cxx/two_tu_c $(B)/cxx/static_c $(B)/cxx/static_cxx
# the header's own compile checks also refuse implicit sign changes (tests and tools need not)
$(CXX_BINS): WARN += -Wsign-conversion
REF_BINS := $(B)/ref/test_reference $(B)/ref/test_loader

test: deps check-shaders
	@$(MAKE) --no-print-directory $(CPU_BINS) $(VG_BINS) $(GL_BINS) $(GL43_BINS) $(CXX_BINS) $(REF_BINS) $(CLI_BINS)
	@$(MAKE) --no-print-directory fuzz-short
	@VALGRIND="$(VG_BINS)" tools/run-tests.sh $(CPU_BINS) $(VG_BINS) $(GL_BINS) $(GL43_BINS) $(CXX_BINS) $(REF_BINS) $(CLI_BINS)

# --- ground truth: tools/reference (Embree) on the shared scene layer scene/scene.* ----------
REF_CXX  := g++ -std=c++11 $(filter-out -Wstrict-prototypes -Wmissing-prototypes,$(WARN)) -Iscene -Itools/reference -isystem /usr/include/stb
REF_HDRS := scene/scene.h tools/reference/reference.h scene/street.h
$(B)/ref/%.o: scene/%.cpp scene/scene.h scene/street.h
	@mkdir -p $(@D)
	$(REF_CXX) -O2 -c $< -o $@
$(B)/ref/%.o: tools/reference/%.cpp $(REF_HDRS)
	@mkdir -p $(@D)
	$(REF_CXX) -O2 -c $< -o $@
$(B)/ref/asan/%.o: scene/%.cpp scene/scene.h scene/street.h
	@mkdir -p $(@D)
	$(REF_CXX) -O1 -g $(SAN) -c $< -o $@
$(B)/ref/asan/%.o: tools/reference/%.cpp $(REF_HDRS)
	@mkdir -p $(@D)
	$(REF_CXX) -O1 -g $(SAN) -c $< -o $@
$(B)/gimany-reference: $(B)/ref/scene.o $(B)/ref/reference.o $(B)/ref/main.o
	$(REF_CXX) $^ -o $@ -lembree3 -pthread
# Tests (ASan+UBSan) of the renderer against closed forms, of the loader and of the CLI; the
# headers must also compile as C99.
$(B)/ref/test_reference: tests/unit/test_reference.cpp $(B)/ref/asan/scene.o $(B)/ref/asan/reference.o $(B)/gimany-reference $(REF_HDRS)
	gcc $(CSTD) $(WARN) -fsyntax-only -Iscene -x c scene/scene.h tools/reference/reference.h
	$(REF_CXX) -O1 -g $(SAN) -DREF_BIN='"$(B)/gimany-reference"' $< $(B)/ref/asan/scene.o $(B)/ref/asan/reference.o -o $@ -lcmocka -lembree3 -pthread

# The glTF loader against hostile files (deep JSON, special files, image bombs, instancing).
$(B)/ref/test_loader: tests/unit/test_loader.cpp $(B)/ref/asan/scene.o scene/scene.h
	$(REF_CXX) -O1 -g $(SAN) $< $(B)/ref/asan/scene.o -o $@ -lcmocka -lz

# gimany-compare (tools/compare.c): error metrics of a method's image against a reference.
$(B)/gimany-compare: tools/compare.c tools/compare.h $(B)/ref/scene.o scene/scene.h
	gcc $(CSTD) $(WARN) -Iscene -Itools -isystem /usr/include/stb -O2 $< $(B)/ref/scene.o -o $@ -lm -lstdc++
$(B)/cli/cli_compare: tests/cli/cli_compare.c tools/compare.c tools/compare.h $(B)/ref/asan/scene.o $(B)/gimany-compare
	@mkdir -p $(@D)
	gcc $(CSTD) $(WARN) $(INC) -Itools -O1 -g $(SAN) -DCOMPARE_BIN='"$(B)/gimany-compare"' $< $(B)/ref/asan/scene.o -o $@ -lcmocka -lm -lstdc++

$(B)/fuzz/fuzz_reference_gltf: tests/fuzz/fuzz_reference_gltf.cpp scene/scene.cpp scene/scene.h scene/street.h
	@mkdir -p $(@D)
	clang++ -std=c++11 -Iscene -isystem /usr/include/stb -g -O1 -fsanitize=fuzzer,address,undefined -fno-sanitize-recover=all $< scene/scene.cpp -o $@

reference:
	@$(DEPS) build examples reference
	@$(MAKE) --no-print-directory $(B)/gimany-reference

# --- benchmarks ---------------------------------------------------------------------------
$(B)/bench/%: bench/src/%.c bench/src/benchutil.h $(HDRS) 
	@mkdir -p $(@D)
	gcc $(CSTD) $(WARN) $(INC) -O2 -march=native -DNDEBUG $< -o $@ -lEGL -lGL -lm

$(B)/bench/%: bench/src/%.cpp bench/src/benchutil.h $(HDRS) 
	@mkdir -p $(@D)
	g++ -std=c++11 -O2 -march=native -DNDEBUG $(INC) -I/usr/include/stb $< -o $@ -lm

# The frame benchmark loads the street through the scene layer (scene/).
$(B)/bench/bench_frame: bench/src/bench_frame.c bench/src/benchutil.h $(B)/ref/scene.o scene/scene.h scene/scene_gimany.h tools/compare.c $(HDRS)
	@mkdir -p $(@D)
	gcc $(CSTD) $(WARN) $(INC) -Itools -O2 -march=native -DNDEBUG $< $(B)/ref/scene.o -o $@ -lEGL -lGL -lm -lstdc++

# Absolute times on a real GPU (1920x1080, RSM 2048^2, 8192 VALs): refuses to run without a
# hardware EGL device; `make bench` runs it with --small on llvmpipe so the code path stays alive.
$(B)/bench/bench_gpu: bench/src/bench_gpu.c bench/src/benchutil.h $(B)/ref/scene.o scene/scene.h scene/scene_gimany.h $(HDRS)
	@mkdir -p $(@D)
	gcc $(CSTD) $(WARN) $(INC) -O2 -march=native -DNDEBUG $< $(B)/ref/scene.o -o $@ -lEGL -lGL -lm -lstdc++

# The ISM benchmark loads the Cornell box through the scene layer (CPU twins only).
$(B)/bench/bench_ism: bench/src/bench_ism.c $(B)/ref/scene.o scene/scene.h $(HDRS)
	@mkdir -p $(@D)
	gcc $(CSTD) $(WARN) $(INC) -O2 -march=native -DNDEBUG $< $(B)/ref/scene.o -o $@ -lm -lstdc++

bench: deps
	@$(DEPS) examples reference plots
	@$(MAKE) --no-print-directory $(addprefix $(B)/bench/,$(BENCHES)) $(B)/gimany-reference
	@for b in $(BENCHES); do echo "== $$b"; $(B)/bench/$$b || exit 1; done
	@$(MAKE) --no-print-directory $(B)/bench/bench_gpu && $(B)/bench/bench_gpu --small > /dev/null
	@tools/bench-plots.sh bench

# every method at game sizes on a real GPU: the table between docs/benchmarks.md's bench:gpu markers
bench-gpu: deps
	@$(DEPS) examples
	@$(MAKE) --no-print-directory $(B)/bench/bench_gpu
	@mkdir -p bench/gpu && $(B)/bench/bench_gpu --out bench/gpu/table.md
	@tools/bench-table.sh gpu bench/gpu/table.md

# bench_frame's full sweep (RSM 128^2..2048^2, 320x180; about half an hour on 2 llvmpipe cores)
bench-full: deps
	@$(DEPS) examples reference plots
	@$(MAKE) --no-print-directory $(B)/bench/bench_frame $(B)/gimany-reference
	$(B)/bench/bench_frame full
	@tools/bench-plots.sh bench/full

# --- fuzzing (libFuzzer) ------------------------------------------------------------------
$(B)/fuzz/%: tests/fuzz/%.c $(HDRS) 
	@mkdir -p $(@D)
	clang $(CSTD) $(INC) -g -O1 -fsanitize=fuzzer,address,undefined -fno-sanitize-recover=all -DGIMANY_NO_GL $< -o $@ -lm

# Each target replays its committed corpus (tests/fuzz/corpus/NAME) and fuzzes for a bounded time.
fuzz-short: $(addprefix $(B)/fuzz/,$(FUZZERS))
	@for f in $(FUZZERS); do tools/run-fuzzer.sh $(B)/fuzz/$$f $(FUZZ_SHORT) || exit 1; done

fuzz: deps $(addprefix $(B)/fuzz/,$(FUZZERS))
	@for f in $(FUZZERS); do tools/run-fuzzer.sh $(B)/fuzz/$$f $(FUZZ_SECONDS) || exit 1; done

# --- main job -----------------------------------------------------------------------------
# build/gimany-demo (headless, EGL) and build/gimany-viewer (GLFW window) on the scene layer.
EX_HDRS := gimany.h shaders_embedded.h scene/scene.h scene/scene_gimany.h examples/display.h examples/options.h
EX_CC   := gcc $(CSTD) $(WARN) -Iexamples -Iscene -I. -isystem /usr/include/stb -O2
$(B)/gimany-demo: examples/demo.c examples/egl_headless.h $(EX_HDRS) $(B)/ref/scene.o
	$(EX_CC) $< $(B)/ref/scene.o -o $@ -lEGL -lGL -lm -lstdc++
$(B)/gimany-viewer: examples/viewer.c $(EX_HDRS) $(B)/ref/scene.o
	$(EX_CC) $< $(B)/ref/scene.o -o $@ -lglfw -lGL -lm -lstdc++
# gimany driven from a host's own GL buffers, lights buffer and G-buffer (no scene layer)
$(B)/gimany-host-buffers: examples/host_buffers.c gimany.h shaders_embedded.h
	@mkdir -p $(@D)
	$(EX_CC) $< -o $@ -lglfw -lGL -lm
# the smallest host: GLFW, a box built in code, gimany.h and shaders_embedded.h only
$(B)/gimany-minimal: examples/minimal.c gimany.h shaders_embedded.h
	@mkdir -p $(@D)
	gcc $(CSTD) $(WARN) -I. -O2 $< -o $@ -lglfw -lGL -lm

demo:
	@$(DEPS) build gl examples
	@$(MAKE) --no-print-directory $(B)/gimany-demo
	$(B)/gimany-demo

clean:
	rm -rf $(B)
