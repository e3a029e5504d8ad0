// Shared by the light culling and the shading: the per-tile light lists' layout.
// LIGHT_TILE (tile edge in pixels), MAX_PER_TILE (list length) and ALL_LIGHTS (the count of a
// tile whose list overflowed) are injected by the shader loader from render/constants.py.
