// The implementation compiled as C++11 (with the GL runtime), in its own translation unit.
#define GIMANY_IMPLEMENTATION
#include "gimany.h"
