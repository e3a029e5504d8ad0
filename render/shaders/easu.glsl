// Edge-adaptive upscaling after FSR 1's EASU (AMD FidelityFX Super Resolution 1, MIT): for
// each output pixel a 12-tap kernel around the source position
//        b c
//      e f g h
//      i j k l
//        n o
// whose Lanczos-like lobe is rotated along the local edge (luma gradients of f, g, j, k,
// weighted bilinearly) and stretched along it by how strong the edge is; the result is
// clamped to the range of f, g, j, k so edges do not ring. Works on display-encoded colour:
// the includer defines vec3 eye_tap(ivec2 p) (a clamped fetch, tone-mapped and encoded).

float easu_luma(vec3 c) { return c.g + 0.5 * (c.r + c.b); }

void easu_set(inout vec2 dir, inout float len, float w, float la, float lb, float lc, float ld,
              float le) {
    //    a
    //  b c d
    //    e
    float dc = ld - lc;
    float cb = lc - lb;
    float len_x = max(abs(dc), abs(cb));
    len_x = len_x > 0.0 ? 1.0 / len_x : 0.0;
    float dir_x = ld - lb;
    dir.x += dir_x * w;
    len_x = clamp(abs(dir_x) * len_x, 0.0, 1.0);
    len += len_x * len_x * w;
    float ec = le - lc;
    float ca = lc - la;
    float len_y = max(abs(ec), abs(ca));
    len_y = len_y > 0.0 ? 1.0 / len_y : 0.0;
    float dir_y = le - la;
    dir.y += dir_y * w;
    len_y = clamp(abs(dir_y) * len_y, 0.0, 1.0);
    len += len_y * len_y * w;
}

void easu_tap(inout vec3 acc, inout float acc_w, vec2 off, vec2 dir, vec2 len2, float lob,
              float clp, vec3 c) {
    vec2 v = vec2(dot(off, dir), dot(off, vec2(-dir.y, dir.x))) * len2;
    float d2 = min(dot(v, v), clp);
    float wb = 0.4 * d2 - 1.0;
    float wa = lob * d2 - 1.0;
    wb *= wb;
    wa *= wa;
    wb = 1.5625 * wb - 0.5625;
    float w = wb * wa;
    acc += c * w;
    acc_w += w;
}

// src_pos: the output pixel's centre in source pixels (x + 0.5 scaled by src / dst).
vec3 easu(vec2 src_pos) {
    vec2 pp = src_pos - 0.5;
    ivec2 fp = ivec2(floor(pp));
    pp -= floor(pp);
    vec3 b = eye_tap(fp + ivec2(0, -1)), c = eye_tap(fp + ivec2(1, -1));
    vec3 e = eye_tap(fp + ivec2(-1, 0)), f = eye_tap(fp), g = eye_tap(fp + ivec2(1, 0));
    vec3 h = eye_tap(fp + ivec2(2, 0)), i = eye_tap(fp + ivec2(-1, 1));
    vec3 j = eye_tap(fp + ivec2(0, 1)), k = eye_tap(fp + ivec2(1, 1));
    vec3 l = eye_tap(fp + ivec2(2, 1)), n = eye_tap(fp + ivec2(0, 2));
    vec3 o = eye_tap(fp + ivec2(1, 2));
    float bl = easu_luma(b), cl = easu_luma(c), el = easu_luma(e), fl = easu_luma(f);
    float gl = easu_luma(g), hl = easu_luma(h), il = easu_luma(i), jl = easu_luma(j);
    float kl = easu_luma(k), ll = easu_luma(l), nl = easu_luma(n), ol = easu_luma(o);
    vec2 dir = vec2(0.0);
    float len = 0.0;
    easu_set(dir, len, (1.0 - pp.x) * (1.0 - pp.y), bl, el, fl, gl, jl);
    easu_set(dir, len, pp.x * (1.0 - pp.y), cl, fl, gl, hl, kl);
    easu_set(dir, len, (1.0 - pp.x) * pp.y, fl, il, jl, kl, nl);
    easu_set(dir, len, pp.x * pp.y, gl, jl, kl, ll, ol);
    float dir_r = dot(dir, dir);
    bool flat_dir = dir_r < 1.0 / 32768.0;
    dir = flat_dir ? vec2(1.0, 0.0) : dir * inversesqrt(dir_r);
    len = 0.5 * len;
    len *= len;
    float stretch = dot(dir, dir) / max(abs(dir.x), abs(dir.y));
    vec2 len2 = vec2(1.0 + (stretch - 1.0) * len, 1.0 - 0.5 * len);
    float lob = 0.5 + (0.25 - 0.04 - 0.5) * len;
    float clp = 1.0 / lob;
    vec3 acc = vec3(0.0);
    float acc_w = 0.0;
    easu_tap(acc, acc_w, vec2(0.0, -1.0) - pp, dir, len2, lob, clp, b);
    easu_tap(acc, acc_w, vec2(1.0, -1.0) - pp, dir, len2, lob, clp, c);
    easu_tap(acc, acc_w, vec2(-1.0, 1.0) - pp, dir, len2, lob, clp, i);
    easu_tap(acc, acc_w, vec2(0.0, 1.0) - pp, dir, len2, lob, clp, j);
    easu_tap(acc, acc_w, vec2(0.0, 0.0) - pp, dir, len2, lob, clp, f);
    easu_tap(acc, acc_w, vec2(-1.0, 0.0) - pp, dir, len2, lob, clp, e);
    easu_tap(acc, acc_w, vec2(1.0, 1.0) - pp, dir, len2, lob, clp, k);
    easu_tap(acc, acc_w, vec2(2.0, 1.0) - pp, dir, len2, lob, clp, l);
    easu_tap(acc, acc_w, vec2(2.0, 0.0) - pp, dir, len2, lob, clp, h);
    easu_tap(acc, acc_w, vec2(1.0, 0.0) - pp, dir, len2, lob, clp, g);
    easu_tap(acc, acc_w, vec2(1.0, 2.0) - pp, dir, len2, lob, clp, o);
    easu_tap(acc, acc_w, vec2(0.0, 2.0) - pp, dir, len2, lob, clp, n);
    vec3 lo = min(min(f, g), min(j, k));
    vec3 hi = max(max(f, g), max(j, k));
    return clamp(acc / max(acc_w, 1e-6), lo, hi);
}

// The plain comparison: bilinear between the four nearest source pixels.
vec3 bilinear(vec2 src_pos) {
    vec2 pp = src_pos - 0.5;
    ivec2 fp = ivec2(floor(pp));
    vec2 t = pp - floor(pp);
    vec3 top = mix(eye_tap(fp), eye_tap(fp + ivec2(1, 0)), t.x);
    vec3 bottom = mix(eye_tap(fp + ivec2(0, 1)), eye_tap(fp + ivec2(1, 1)), t.x);
    return mix(top, bottom, t.y);
}
