// The photon-map gather core: irradiance E at a point P with unit normal N from the photons
// within radius r (paper 3.1, 3.2). #include it; it declares its own SSBOs and u_pm_* uniforms
// so it can sit beside deferred.glsl in a lighting shader.
//
// A photon counts when |x_p - P|^2 < r^2 and dot(N, dir_p) < 0 (dir_p = its travel direction:
// it arrived from the side N faces). E = sum(power) / (pi r^2), or with HEAP the k nearest of
// the counted photons over pi r_k^2 once k were found (the paper's radius shrink).
//
// Structure (one of):
//   GRID    hash grid: cells of edge u_pm_cell, GRID_REACH (1 or 2) cells around the query
//           cell, visited as (2R+1)^2 contiguous runs of 2R+1 cells along x.
//   KDTREE  left-balanced kd-tree in an array (children 2i+1, 2i+2; split axis in `extra`).
// Options:
//   HEAP    k-nearest max-heap of HEAP_K (1..64) entries.
//   SHARED  (compute, GRID, 64 invocations per group) Algorithm 1: when every active query of
//           the group falls in one cell, the group streams that cell's runs through shared
//           memory in chunks of 64 photons. Use gather_irradiance_shared() from uniform control
//           flow (every invocation of the group must call it).
//   COUNT   atomics on the counters buffer (binding 2): visited / within photons.
//   PM_SSBO read the records / start array from the SSBOs (bindings 0, 1) instead of the
//           textures u_pm_records / u_pm_starts (see below).
// Uniforms: u_pm_count, u_pm_radius2, u_pm_norm, GRID: u_pm_origin, u_pm_cell, u_pm_dims
// (GpuPhotonMap.bind sets them all).
#include "common.glsl"

#if defined(GRID) == defined(KDTREE)
#error "photon_gather.glsl: define exactly one of GRID and KDTREE"
#endif
#ifndef GRID_REACH
#define GRID_REACH 1
#endif
#if defined(HEAP)
#ifndef HEAP_K
#define HEAP_K 32
#endif
#if HEAP_K < 1 || HEAP_K > PM_MAX_K
#error "photon_gather.glsl: HEAP_K must be 1..PM_MAX_K"
#endif
#endif

// The 32-byte records, read as two uvec4 each: (position bits, direction) at 2i and (power bits,
// extra) at 2i + 1. Unsigned so the direction bits never pass through a float (a denormal could
// be flushed). Where they are read from:
//   default  an RGBA32UI texture PM_TEX_WIDTH texels wide (unit u_pm_records): llvmpipe turns
//            texel fetches into vector gathers, but SSBO loads into a per-lane loop per
//            component, ~9x slower in this loop.
//   PM_SSBO  the SSBO at binding 0 (same bytes).
// The power half is only fetched for photons that count.
// PM_TEX_SHIFT (injected, render/constants.py): textures are 1 << PM_TEX_SHIFT texels wide.
#define PM_TEXEL(j) ivec2(int(j) & ((1 << PM_TEX_SHIFT) - 1), int(j) >> PM_TEX_SHIFT)
layout(std430, binding = 0) readonly buffer PhotonRecords { uvec4 pm_records[]; };
// GRID: prefix sum over cells (X*Y*Z + 1 entries): a cell's photons are [start[h], start[h+1]).
layout(std430, binding = 1) readonly buffer PhotonStarts { uint pm_start[]; };
#ifdef PM_SSBO
#define PM_REC(j) pm_records[j]
#define PM_START(h) pm_start[h]
#else
uniform usampler2D u_pm_records;  // RGBA32UI, the records
uniform usampler2D u_pm_starts;   // R32UI, the prefix sum
#define PM_REC(j) texelFetch(u_pm_records, PM_TEXEL(j), 0)
#define PM_START(h) texelFetch(u_pm_starts, PM_TEXEL(h), 0).r
#endif
// Counters, pairs of (low, high) words: gathered, reused pixels, visited, within photons.
layout(std430, binding = 2) buffer PhotonCounters { uint pm_counters[8]; };

uniform uint u_pm_count;      // photons in pm_records
uniform float u_pm_radius2;   // r^2
uniform float u_pm_norm;      // 1 / (pi r^2)
uniform vec3 u_pm_origin;     // GRID: the corner of cell (0, 0, 0)
uniform float u_pm_cell;      // GRID: cell edge
uniform ivec3 u_pm_dims;      // GRID: cells per axis, padding included (0: no grid)

// 64-bit counters from 32-bit atomics: the add that wraps the low word carries into the high.
void pm_count(int slot, uint n) {
    if (n == 0u) return;
    uint old = atomicAdd(pm_counters[2 * slot], n);
    if (old > 0xFFFFFFFFu - n) atomicAdd(pm_counters[2 * slot + 1], 1u);
}

// Exactly app.photon_map.decode_directions up to the (sign-irrelevant) normalisation.
vec3 pm_direction(uint bits) {
    vec2 e = unpackSnorm2x16(bits);
    float z = 1.0 - abs(e.x) - abs(e.y);
    float t = max(-z, 0.0);
    e += mix(vec2(t), vec2(-t), greaterThanEqual(e, vec2(0.0)));
    return vec3(e, z);
}

// Per-query state of one estimate.
struct PmQuery {
    vec3 P;
    vec3 N;
    vec3 sum;
    uint visited;
    uint within;
};

PmQuery pm_query(vec3 P, vec3 N) {
    return PmQuery(P, N, vec3(0.0), 0u, 0u);
}

bool pm_valid(vec3 P, vec3 N) {
    // A NaN / inf position or normal gathers nothing (as in app.lab.photon_ref), and comparisons
    // with NaN would slip through the range checks below.
    return !(any(isnan(P)) || any(isinf(P)) || any(isnan(N)) || any(isinf(N)));
}

#ifdef HEAP
// Max-heap on squared distance, (power, d2) per entry; entry 0 is the farthest kept photon.
vec4 pm_heap[HEAP_K];
int pm_heap_n;

void pm_heap_push(float d2, vec3 power) {
    if (pm_heap_n < HEAP_K) {
        int i = pm_heap_n++;
        while (i > 0) {  // sift up
            int parent = (i - 1) >> 1;
            vec4 up = pm_heap[parent];
            if (up.w >= d2) break;
            pm_heap[i] = up;
            i = parent;
        }
        pm_heap[i] = vec4(power, d2);
    } else if (d2 < pm_heap[0].w) {  // replace the farthest, sift down
        int i = 0;
        for (;;) {
            int c = 2 * i + 1;
            if (c >= HEAP_K) break;
            vec4 child = pm_heap[c];
            if (c + 1 < HEAP_K) {
                vec4 other = pm_heap[c + 1];
                if (other.w > child.w) { child = other; c += 1; }
            }
            if (child.w <= d2) break;
            pm_heap[i] = child;
            i = c;
        }
        pm_heap[i] = vec4(power, d2);
    }
}

// The squared search radius now (the paper's radius shrink): the heap's farthest once it is
// full, else r^2. A full heap at distance 0 (k photons exactly at P) keeps r^2: the estimate
// then falls back to all counted photons (app.lab.photon_ref.estimate_knn), so they must all be seen.
float pm_limit2() {
    return (pm_heap_n < HEAP_K || !(pm_heap[0].w > 0.0)) ? u_pm_radius2 : pm_heap[0].w;
}
#endif

// The test of one photon whose first half (position, direction bits) is `a`: inside r and
// arriving at the side N faces. The caller fetches the power only when this holds.
bool pm_counts(inout PmQuery q, uvec4 a, out float d2) {
    vec3 d = uintBitsToFloat(a.xyz) - q.P;
    d2 = dot(d, d);
    q.visited += 1u;
    if (!(d2 < u_pm_radius2)) return false;
    q.within += 1u;
    return dot(q.N, pm_direction(a.w)) < 0.0;
}

void pm_add(inout PmQuery q, float d2, vec3 power) {
    q.sum += power;  // HEAP: all counted photons, for the fallback when r_k is 0
#ifdef HEAP
    if (d2 < pm_limit2()) pm_heap_push(d2, power);
#endif
}

vec3 pm_finish(PmQuery q) {
#ifdef COUNT
    pm_count(2, q.visited);
    pm_count(3, q.within);
#endif
#ifdef HEAP
    if (pm_heap_n == HEAP_K && pm_heap[0].w > 0.0) {
        // Full heap: the estimate's radius shrinks to the k-th nearest distance.
        vec3 sum = vec3(0.0);
        for (int i = 0; i < HEAP_K; ++i) sum += pm_heap[i].xyz;
        return sum / (PI * pm_heap[0].w);
    }
#endif
    return q.sum * u_pm_norm;
}

#ifdef GRID
// The query cell of P, or false when P lies outside the grid (then nothing is visited). The
// float test comes first so a huge P never reaches the int conversion.
bool pm_cell_of(vec3 P, vec3 N, out ivec3 c) {
    c = ivec3(0);
    if (!pm_valid(P, N) || any(lessThanEqual(u_pm_dims, ivec3(0)))) return false;
    vec3 f = floor((P - u_pm_origin) / u_pm_cell);
    if (any(lessThan(f, vec3(0.0))) || any(greaterThanEqual(f, vec3(u_pm_dims)))) return false;
    c = ivec3(f);
    return true;
}

// Run `row` (0 .. (2R+1)^2 - 1) of the cells around c: photon range [s, e) in pm_start order.
// Neighbour rows are clamped into the grid: the clamped cells are padding (empty), so visiting
// one twice adds nothing. Both ends are clamped to the photon count so no read is out of range.
uvec2 pm_run(ivec3 c, int row) {
    const int W = 2 * GRID_REACH + 1;
    int y = clamp(c.y + row % W - GRID_REACH, 0, u_pm_dims.y - 1);
    int z = clamp(c.z + row / W - GRID_REACH, 0, u_pm_dims.z - 1);
    int x0 = clamp(c.x - GRID_REACH, 0, u_pm_dims.x - 1);
    int x1 = clamp(c.x + GRID_REACH, 0, u_pm_dims.x - 1);
    int base = (z * u_pm_dims.y + y) * u_pm_dims.x;
    uint s = min(PM_START(base + x0), u_pm_count);
    uint e = min(PM_START(base + x1 + 1), u_pm_count);
    return uvec2(s, max(s, e));
}

vec3 gather_irradiance(vec3 P, vec3 N) {
    PmQuery q = pm_query(P, N);
#ifdef HEAP
    pm_heap_n = 0;
#endif
    ivec3 c;
    if (pm_cell_of(P, N, c)) {
        const int W = 2 * GRID_REACH + 1;
        for (int row = 0; row < W * W; ++row) {
            uvec2 r = pm_run(c, row);
            for (uint i = r.x; i < r.y; ++i) {
                float d2;
                if (pm_counts(q, PM_REC(2u * i), d2))
                    pm_add(q, d2, uintBitsToFloat(PM_REC(2u * i + 1u).xyz));
            }
        }
    }
    return pm_finish(q);
}
#endif  // GRID

#ifdef KDTREE
vec3 gather_irradiance(vec3 P, vec3 N) {
    PmQuery q = pm_query(P, N);
#ifdef HEAP
    pm_heap_n = 0;
#endif
    if (pm_valid(P, N) && u_pm_count > 0u) {
        // Pending far children with their squared distance to the split plane. Every push is at
        // a deeper level than the entry below it, so the depth of the tree (<= 32) bounds it.
        uint stack_node[32];
        float stack_d2[32];
        int sp = 0;
        uint node = 0u;
        for (;;) {
            while (node < u_pm_count) {
                uvec4 a = PM_REC(2u * node);
                uvec4 b = PM_REC(2u * node + 1u);  // power and split axis
                float d2;
                if (pm_counts(q, a, d2)) pm_add(q, d2, uintBitsToFloat(b.xyz));
                uint axis = min(b.w, 2u);
                float diff = P[axis] - uintBitsToFloat(a[axis]);
                // Left holds coords <= split: P below the split searches left first.
                uint near = diff < 0.0 ? 2u * node + 1u : 2u * node + 2u;
                uint far = diff < 0.0 ? 2u * node + 2u : 2u * node + 1u;
#ifdef HEAP
                float limit2 = pm_limit2();
#else
                float limit2 = u_pm_radius2;
#endif
                if (far < u_pm_count && diff * diff < limit2 && sp < 32) {
                    stack_node[sp] = far;
                    stack_d2[sp] = diff * diff;
                    ++sp;
                }
                node = near;
            }
            // Pop the next far child still closer than the (possibly shrunk) radius.
            node = 0xFFFFFFFFu;
            while (sp > 0) {
                --sp;
#ifdef HEAP
                if (stack_d2[sp] < pm_limit2()) { node = stack_node[sp]; break; }
#else
                node = stack_node[sp];
                break;
#endif
            }
            if (node == 0xFFFFFFFFu) break;
        }
    }
    return pm_finish(q);
}
#endif  // KDTREE

#ifdef SHARED
#ifndef GRID
#error "photon_gather.glsl: SHARED needs GRID"
#endif
// Algorithm 1. Every invocation of the (64-wide) group must call this in uniform control flow;
// `has_query` says whether it has a query (background / out-of-image / reused invocations pass
// false and still help load photons).
// PM_GROUP (injected, render/constants.py): invocations per work group.
shared uvec4 pm_shared[2u * PM_GROUP];
shared uint pm_cell_min;
shared uint pm_cell_max;

vec3 gather_irradiance_shared(vec3 P, vec3 N, bool has_query) {
    uint lid = gl_LocalInvocationIndex;
    ivec3 c;
    bool inside = has_query && pm_cell_of(P, N, c);
    uint h = inside ? uint((c.z * u_pm_dims.y + c.y) * u_pm_dims.x + c.x) : 0xFFFFFFFFu;
    if (lid == 0u) {
        pm_cell_min = 0xFFFFFFFFu;
        pm_cell_max = 0u;
    }
    barrier();
    // Queries outside the grid visit nothing, so they do not vote either.
    if (inside) {
        atomicMin(pm_cell_min, h);
        atomicMax(pm_cell_max, h);
    }
    barrier();
    uint hmin = pm_cell_min;
    uint hmax = pm_cell_max;
    // Everyone has read the vote before anyone can start the next call's reset.
    barrier();
    if (hmin == 0xFFFFFFFFu) return vec3(0.0);  // no active query in the group (uniform)
    if (hmin != hmax) {  // mixed cells (uniform): each invocation gathers on its own
        return has_query ? gather_irradiance(P, N) : vec3(0.0);
    }
    // One cell for the whole group: rebuild it from the hash so inactive invocations agree.
    int X = u_pm_dims.x;
    int XY = u_pm_dims.x * u_pm_dims.y;
    ivec3 cg = ivec3(int(hmin) % X, (int(hmin) % XY) / X, int(hmin) / XY);
    PmQuery q = pm_query(P, N);
#ifdef HEAP
    pm_heap_n = 0;
#endif
    const int W = 2 * GRID_REACH + 1;
    for (int row = 0; row < W * W; ++row) {
        uvec2 r = pm_run(cg, row);  // uniform: the same run for all
        for (uint base = r.x; base < r.y; base += PM_GROUP) {
            uint i = base + lid;
            if (i < r.y) {
                pm_shared[2u * lid] = PM_REC(2u * i);
                pm_shared[2u * lid + 1u] = PM_REC(2u * i + 1u);
            }
            barrier();
            if (inside) {
                uint n = min(PM_GROUP, r.y - base);
                for (uint k = 0u; k < n; ++k) {
                    float d2;
                    if (pm_counts(q, pm_shared[2u * k], d2))
                        pm_add(q, d2, uintBitsToFloat(pm_shared[2u * k + 1u].xyz));
                }
            }
            barrier();
        }
    }
    if (!inside) return vec3(0.0);
    return pm_finish(q);
}
#endif  // SHARED

// The estimate for one query in the variant the defines select (SHARED: from uniform control
// flow, every invocation of the group; without a query it only helps the group load).
vec3 gather_query(vec3 P, vec3 N, bool has_query) {
#ifdef SHARED
    return gather_irradiance_shared(P, N, has_query);
#else
    return has_query ? gather_irradiance(P, N) : vec3(0.0);
#endif
}
