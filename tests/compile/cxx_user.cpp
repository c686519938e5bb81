// A second C++ translation unit that only includes the declarations and calls into the first.
#include "gimany.h"
#include <cstdio>

int main() {
    float pts[8];
    if (gim_halton_points(pts, 4, 2, 0, NULL) != GIM_OK) return 1;
    if (pts[2] != 0.5f || pts[3] != 1.0f / 3.0f) return 1;
    if (gim_radical_inverse(3, 4) != 4.0 / 9.0) return 1;
    std::printf("C++ two-TU build: %s ok\n", GIMANY_VERSION_STRING);
    return 0;
}
