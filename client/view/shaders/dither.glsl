// The 4x4 Bayer threshold of a pixel, in (0, 1): the dissolve between a model's
// geometry (cell.frag.glsl, MS_EFFECT_IMPOSTORS) and its impostor
// (impostor.frag.glsl), which draw complementary pixels of the same pattern.
// Inserted after the #version line of both (no #version here).

float bayer(vec2 p)
{
    ivec2 q = ivec2(p) & 3;
    int m[16] = int[16](0, 8, 2, 10, 12, 4, 14, 6, 3, 11, 1, 9, 15, 7, 13, 5);
    return (float(m[q.y * 4 + q.x]) + 0.5) / 16.0;
}
