/* Octahedral 2 x 12-bit normal code of the APO texel words. */
#include "ms_apo_format.h"

#include <math.h>

static uint32_t clamp_component(int64_t q)
{
    if (q < 0)
        return 0;
    if (q > (int64_t)MS_APO_NORMAL_MAX_CODE)
        return MS_APO_NORMAL_MAX_CODE;
    return (uint32_t)q;
}

void ms_apo_normal_decode(uint32_t code, float out[3])
{
    uint32_t qu = code & 0xFFFu, qv = (code >> 12) & 0xFFFu;
    if (qu > MS_APO_NORMAL_MAX_CODE)
        qu = MS_APO_NORMAL_MAX_CODE;
    if (qv > MS_APO_NORMAL_MAX_CODE)
        qv = MS_APO_NORMAL_MAX_CODE;
    float u = (float)((int32_t)qu - MS_APO_NORMAL_STEPS) / (float)MS_APO_NORMAL_STEPS;
    float v = (float)((int32_t)qv - MS_APO_NORMAL_STEPS) / (float)MS_APO_NORMAL_STEPS;
    float z = 1.0f - fabsf(u) - fabsf(v);
    float x = u, y = v;
    if (z < 0.0f) {
        /* Lower hemisphere: unfold. Zero counts as positive, like u >= 0.0 in GLSL. */
        x = (1.0f - fabsf(v)) * (u >= 0.0f ? 1.0f : -1.0f);
        y = (1.0f - fabsf(u)) * (v >= 0.0f ? 1.0f : -1.0f);
    }
    float len = sqrtf(x * x + y * y + z * z);
    out[0] = x / len;
    out[1] = y / len;
    out[2] = z / len;
}

bool ms_apo_normal_code_valid(uint32_t code)
{
    return (code & 0xFFFu) <= MS_APO_NORMAL_MAX_CODE && ((code >> 12) & 0xFFFu) <= MS_APO_NORMAL_MAX_CODE &&
           (code >> 24) == 0;
}

uint32_t ms_apo_normal_encode(const float n[3])
{
    double x = n[0], y = n[1], z = n[2];
    double l1 = fabs(x) + fabs(y) + fabs(z);
    if (!(l1 > 0.0) || !isfinite(l1)) {
        x = 0.0;
        y = 0.0;
        z = 1.0;
        l1 = 1.0;
    }
    double u = x / l1, v = y / l1;
    if (z < 0.0) {
        double fu = (1.0 - fabs(v)) * (u >= 0.0 ? 1.0 : -1.0);
        double fv = (1.0 - fabs(u)) * (v >= 0.0 ? 1.0 : -1.0);
        u = fu;
        v = fv;
    }
    double su = u * MS_APO_NORMAL_STEPS + MS_APO_NORMAL_STEPS;
    double sv = v * MS_APO_NORMAL_STEPS + MS_APO_NORMAL_STEPS;
    int64_t bu = (int64_t)floor(su), bv = (int64_t)floor(sv);
    /* Of the four codes around the exact point, keep the one whose decoded
     * direction is nearest to the input (largest cosine). Ties: first found. A
     * code that decodes to exactly the input wins outright: neighbouring codes
     * are only ~1e-7 apart in cosine, within float rounding, and re-encoding a
     * decoded normal must give its code back. */
    double len = sqrt(x * x + y * y + z * z);
    uint32_t best = 0;
    double best_cos = -2.0;
    for (int du = 0; du <= 1; ++du)
        for (int dv = 0; dv <= 1; ++dv) {
            uint32_t qu = clamp_component(bu + du), qv = clamp_component(bv + dv);
            uint32_t code = qu | (qv << 12);
            float d[3];
            ms_apo_normal_decode(code, d);
            double c = (d[0] * x + d[1] * y + d[2] * z) / len;
            if (d[0] == n[0] && d[1] == n[1] && d[2] == n[2])
                c = 2.0;
            if (c > best_cos) {
                best_cos = c;
                best = code;
            }
        }
    /* Canonical form on the octahedron's seams, where two codes decode to the
     * same direction: |u| = 1 ignores the sign of v, |v| = 1 that of u. Keep the
     * non-negative one so that re-encoding a decoded normal gives its code back. */
    uint32_t qu = best & 0xFFFu, qv = best >> 12;
    if (qu == 0 || qu == MS_APO_NORMAL_MAX_CODE)
        qv = qv < MS_APO_NORMAL_MAX_CODE - qv ? MS_APO_NORMAL_MAX_CODE - qv : qv;
    if (qv == 0 || qv == MS_APO_NORMAL_MAX_CODE)
        qu = qu < MS_APO_NORMAL_MAX_CODE - qu ? MS_APO_NORMAL_MAX_CODE - qu : qu;
    return qu | (qv << 12);
}

void ms_apo_words_to_bytes(const uint32_t *words, size_t count, uint8_t *bytes)
{
    for (size_t i = 0; i < count; ++i)
        for (int k = 0; k < 4; ++k)
            bytes[4 * i + (size_t)k] = (uint8_t)(words[i] >> (8 * k));
}

void ms_apo_words_from_bytes(const uint8_t *bytes, size_t count, uint32_t *words)
{
    for (size_t i = 0; i < count; ++i)
        words[i] = (uint32_t)bytes[4 * i] | (uint32_t)bytes[4 * i + 1] << 8 | (uint32_t)bytes[4 * i + 2] << 16 |
                   (uint32_t)bytes[4 * i + 3] << 24;
}
