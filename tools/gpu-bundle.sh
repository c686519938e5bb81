#!/bin/sh
# tools/gpu-bundle.sh: builds, here, what tools/gpu-run.sh runs on a machine with a real GPU (an
# x86-64 box whose driver offers an EGL device, nothing to install there): bench_gpu, the demo and
# every GL test without sanitizers (ASan and a vendor GL driver do not mix), into .gl/bin, plus
# the few shared libraries such a machine may lack (cmocka, the X client libraries libGL.so.1
# pulls in) into .gl/lib, and Sponza into .gl/scenes when ../shared/scenes has it. Generic x86-64
# code (no -march=native): the other machine's CPU is not this one's.
# Usage: tools/gpu-bundle.sh (from the repository root, after `make deps`)
set -eu
B=build/gpu
O=.gl
mkdir -p "$B" "$O/bin" "$O/lib" "$O/scenes"
WARN="-Wall -Wextra -pedantic -Werror -Wshadow -Wstrict-prototypes -Wmissing-prototypes"
REF_CXX="g++ -std=c++11 -Wall -Wextra -pedantic -Werror -Wshadow -Iscene -Itools/reference -isystem /usr/include/stb"
# stale: the binary is older than its source or anything it includes
stale() { [ ! -e "$1" ] || [ -n "$(find "$2" gimany.h shaders_embedded.h tests/support scene examples -newer "$1" -type f | head -1)" ]; }
stale "$B/scene.o" scene/scene.cpp && $REF_CXX -O2 -c scene/scene.cpp -o "$B/scene.o"
for t in tests/gl/gltest_*.c; do
  n=$(basename "$t" .c)
  [ "$n" = gltest_reference ] && continue   # Embree (42 MB) does not travel
  stale "$O/bin/$n" "$t" || continue
  { gcc -std=c99 $WARN -Iscene -Itests/support -I. -O2 "$t" "$B/scene.o" -o "$O/bin/$n" -lcmocka -lEGL -lGL -lm -lstdc++ &&
    strip "$O/bin/$n"; } &
done
stale "$O/bin/bench_gpu" bench/src && { gcc -std=c99 $WARN -Iscene -Itests/support -I. -O2 -DNDEBUG bench/src/bench_gpu.c \
  "$B/scene.o" -o "$O/bin/bench_gpu" -lEGL -lGL -lm -lstdc++ && strip "$O/bin/bench_gpu"; } &
stale "$O/bin/gimany-demo" examples && { gcc -std=c99 $WARN -Iexamples -Iscene -I. -isystem /usr/include/stb -O2 \
  examples/demo.c "$B/scene.o" -o "$O/bin/gimany-demo" -lEGL -lGL -lm -lstdc++ && strip "$O/bin/gimany-demo"; } &
wait
for l in libcmocka.so.0 libX11.so.6 libxcb.so.1 libXau.so.6 libXdmcp.so.6 libbsd.so.0 libmd.so.0; do
  cp -L "/usr/lib/x86_64-linux-gnu/$l" "$O/lib/" 2>/dev/null || cp -L "/lib/x86_64-linux-gnu/$l" "$O/lib/"
done
if [ -f ../shared/scenes/sponza_lod4/sponza_lod4.glb ]; then cp ../shared/scenes/sponza_lod4/sponza_lod4.glb "$O/scenes/"; fi
du -sh "$O"
