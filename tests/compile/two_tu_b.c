/* C99, two translation units: this one sees only declarations. */
#include "gimany.h"
#include <stdio.h>

int main(void) {
    float pts[4];
    if (gim_hammersley_points(pts, 2, 2, NULL) != GIM_OK) return 1;
    if (pts[0] != 0.0f || pts[2] != 0.5f || pts[3] != 0.5f) return 1;
    printf("C two-TU build: %s ok\n", GIMANY_VERSION_STRING);
    return 0;
}
