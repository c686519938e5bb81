/* C99, two translation units: this one holds the implementation. */
#define GIMANY_IMPLEMENTATION
#include "gimany.h"
