// Reading the half-resolution level map, and the block a pixel belongs to.
uniform usampler2D u_levels;

int level_at(ivec2 p) {
    return int(texelFetch(u_levels, p >> 1, 0).r);
}

// The pixel whose G-buffer sample stands for the whole block at ``origin`` of size 2^s.
ivec2 block_sample(ivec2 origin, int s, ivec2 size) {
    return min(origin + ((1 << s) >> 1), size - 1);
}
