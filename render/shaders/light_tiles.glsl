// Shared by the light culling and the shading: the per-tile light lists' layout.
#ifndef MAX_LIGHTS
#define MAX_LIGHTS 1024
#endif
#define LIGHT_TILE 16
#define MAX_PER_TILE 128
#define ALL_LIGHTS 65535u
