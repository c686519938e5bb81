/* libFuzzer target: the glTF loader of scene/scene.cpp (tinygltf behind the C API) on
   arbitrary bytes, .gltf or .glb. A load either fails with one line or gives a scene that
   passes scene_validate; nothing may crash, leak or read out of bounds. External URIs resolve
   in a folder that does not exist. */
#include "scene.h"

#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <cstring>

extern "C" int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
    scene s;
    char err[256];
    if (scene_load_gltf_memory(data, size, "/nonexistent-fuzz-dir", &s, err, sizeof err) == 0) {
        if (scene_validate(&s, err, sizeof err) != 0) std::abort();
        scene_free(&s);
    } else if (!std::memchr(err, 0, sizeof err) || err[0] == 0 || std::strchr(err, '\n')) {
        std::abort(); /* the error is one non-empty line */
    }
    return 0;
}
