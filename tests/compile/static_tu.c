/* GIMANY_STATIC: every function private to this translation unit, no unused-function
   warnings for the ones a host does not call; built as C99 and as C++11. */
#define GIMANY_STATIC
#define GIMANY_IMPLEMENTATION
#include "gimany.h"
#include <stdio.h>

int main(void) {
    if (gim_van_der_corput(1) != 0.5) return 1;
    printf("GIMANY_STATIC build: ok\n");
    return 0;
}
