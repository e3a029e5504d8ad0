// Where a world point falls in a grid of cells whose slabs are stacked along z in one 3D
// texture (the even light by place, render/ambient_field.py; the sky's share by place,
// render/sky.py): the texture coordinate of P in slab ``k`` of ``slabs``, clamped to the
// slab's cell centres so that a trilinear read never reaches into the next slab (slab k + 1
// is 1 / slabs further along z).
vec3 slab_coord(vec3 P, vec4 origin_cell, ivec3 cells, float k, float slabs) {
    vec3 dims = vec3(cells);
    vec3 g = clamp((P - origin_cell.xyz) / origin_cell.w, vec3(0.5), dims - 0.5);
    return vec3(g.xy / dims.xy, (g.z + k * dims.z) / (slabs * dims.z));
}
