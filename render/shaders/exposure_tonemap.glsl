// Tone curves for the present pass: exposed linear sRGB in, display-linear [0, 1] out.
// TONE_ACES / TONE_AGX / neither (clamp) is injected by PresentPass; app/exposure.py has the
// numpy twins and the sources (the tests compare the two).

// Stephen Hill's ACES fit (BakingLab ACES.hlsl): sRGB -> AP1 with the RRT's saturation, the
// fitted RRT + ODT (sRGB, 100 nits), AP1 -> sRGB. The matrices are written as HLSL's rows;
// v * M multiplies by the HLSL matrix (mul(M, v)).
const mat3 ACES_INPUT = mat3(
    0.59719, 0.35458, 0.04823,
    0.07600, 0.90834, 0.01566,
    0.02840, 0.13383, 0.83777);
const mat3 ACES_OUTPUT = mat3(
    1.60475, -0.53108, -0.07367,
    -0.10208, 1.10813, -0.00605,
    -0.00327, -0.07276, 1.07602);

vec3 tone_aces(vec3 c) {
    vec3 v = c * ACES_INPUT;
    vec3 a = v * (v + 0.0245786) - 0.000090537;
    vec3 b = v * (0.983729 * v + 0.4329510) + 0.238081;
    return clamp((a / b) * ACES_OUTPUT, 0.0, 1.0);
}

// AgX base contrast (Troy Sobotka, as in Blender 4) in Benjamin Wrensch's fit (iolite engine,
// "Minimal AgX implementation"): inset, log2 over [-12.47, 4.03] EV around 18% grey, the
// 6th-order polynomial of the base contrast, outset, 2.2 power back to linear.
const mat3 AGX_INSET = mat3(
    0.842479062253094, 0.0423282422610123, 0.0423756549057051,
    0.0784335999999992, 0.878468636469772, 0.0784336,
    0.0792237451477643, 0.0791661274605434, 0.879142973793104);
const mat3 AGX_OUTSET = mat3(
    1.19687900512017, -0.0528968517574562, -0.0529716355144438,
    -0.0980208811401368, 1.15190312990417, -0.0980434501171241,
    -0.0990297440797205, -0.0989611768448433, 1.15107367264116);
const float AGX_MIN_EV = -12.47393;
const float AGX_MAX_EV = 4.026069;

vec3 agx_contrast(vec3 x) {
    vec3 x2 = x * x;
    vec3 x4 = x2 * x2;
    return 15.5 * x4 * x2 - 40.14 * x4 * x + 31.96 * x4 - 6.868 * x2 * x + 0.4298 * x2
        + 0.1191 * x - 0.00232;
}

vec3 tone_agx(vec3 c) {
    vec3 v = AGX_INSET * c;
    v = clamp(log2(max(v, vec3(1e-10))), AGX_MIN_EV, AGX_MAX_EV);
    v = agx_contrast((v - AGX_MIN_EV) / (AGX_MAX_EV - AGX_MIN_EV));
    v = max(AGX_OUTSET * v, 0.0);
    return clamp(pow(v, vec3(2.2)), 0.0, 1.0);
}

vec3 tone_map(vec3 c) {
    c = max(c, 0.0);
#if defined(TONE_ACES)
    return tone_aces(c);
#elif defined(TONE_AGX)
    return tone_agx(c);
#else
    return clamp(c, 0.0, 1.0);
#endif
}
