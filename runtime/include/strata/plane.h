// Strata: orientation in the plane, the one home of the 2D edge function
// (UV space for the baker's rasterisers, atlases and hole filling, the io
// layer's map embedding and OBJ polygon checks).  Written once, with the
// scalar type of its arguments (float stays float), so every caller gets the
// same bits it computed inline before.
#pragma once

namespace strata {

/// a.x b.y - a.y b.x: twice the signed area of the triangle (0, a, b),
/// positive when b lies counter-clockwise of a.
template <typename Vec2>
constexpr auto cross2(const Vec2& a, const Vec2& b)
{
    return a.x * b.y - a.y * b.x;
}

/// The edge function of p against the directed edge a -> b: twice the
/// signed area of the triangle (a, b, p), positive when p lies to the left.
template <typename Vec2>
constexpr auto orient2(const Vec2& a, const Vec2& b, const Vec2& p)
{
    return (b.x - a.x) * (p.y - a.y) - (b.y - a.y) * (p.x - a.x);
}

}  // namespace strata
