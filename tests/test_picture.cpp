// The baker's CPU pictures (picture.h) and glTF's default sampler
// (io::sampleImage), in closed form: a square facing the eye lit at a known
// angle, a texture's rows where glTF puts them, the nearer of two squares,
// flat parts that ignore their normals, and PSNR of known differences.
#include "strata/baker/picture.h"
#include "strata/io/materials.h"

#include <gtest/gtest.h>

#include <glm/geometric.hpp>

#include <cmath>

using namespace strata;

namespace {

// A square of side 2 at depth z (the plane z = const, facing +Z), centred on
// the axis, its UVs (0, 0) at the top left as the eye sees it (glTF's v down).
void addSquare(baker::PictureMesh* m, float z, glm::vec4 colour, std::vector<float>* uvs = nullptr)
{
    const uint32_t base = uint32_t(m->positions.size());
    const glm::vec3 corners[4] = {{-1, 1, z}, {1, 1, z}, {1, -1, z}, {-1, -1, z}};
    const float uv[8] = {0, 0, 1, 0, 1, 1, 0, 1};
    for (int k = 0; k < 4; ++k) {
        m->positions.push_back(corners[k]);
        m->normals.push_back(glm::vec3(0, 0, 1));
        if (uvs) {
            uvs->push_back(uv[2 * k]);
            uvs->push_back(uv[2 * k + 1]);
        }
    }
    baker::PicturePart part;
    part.firstTriangle = m->triangles.size() / 3;
    part.triangleCount = 2;
    part.colour = colour;
    m->parts.push_back(part);
    for (uint32_t i : {0u, 3u, 2u, 0u, 2u, 1u})
        m->triangles.push_back(base + i);
}

baker::PictureCamera frontCamera()
{
    baker::PictureCamera c;
    c.eye = glm::vec3(0, 0, 4);
    c.target = glm::vec3(0, 0, 0);
    c.fovYDegrees = 60.0f;
    c.size = 64;
    return c;
}

const uint8_t* pixel(const std::vector<uint8_t>& rgb, int size, int x, int y)
{
    return &rgb[3 * (size_t(y) * size_t(size) + size_t(x))];
}

// The shade of a surface facing the eye along +Z: ambient 0.3 plus 0.7 of
// the light's cosine, the light over the eye's shoulder (picture.cpp).
double facingShade()
{
    const glm::dvec3 light = glm::normalize(glm::dvec3(0.0, 0.0, 1.0) + glm::dvec3(0.3, 0.6, 0.0));
    return 0.3 + 0.7 * light.z;
}

}  // namespace

TEST(Picture, ASquareFacingTheEyeIsItsColourTimesTheShade)
{
    // The colour is glTF's base colour factor, linear: drawn sRGB-coded
    // (IEC 61966-2-1: 0.5 -> 0.735357, 0.2 -> 0.484529, 0.8 -> 0.906332,
    // 0.55 -> 0.767376), then shaded.
    baker::PictureMesh a, b;
    addSquare(&a, 0.0f, glm::vec4(0.5f, 0.2f, 0.8f, 1.0f));
    addSquare(&b, 0.0f, glm::vec4(0.55f, 0.2f, 0.8f, 1.0f));
    const baker::PictureCamera camera = frontCamera();
    std::vector<uint8_t> pa, pb, none;
    baker::renderPicture(a, camera, &pa);
    baker::renderPicture(b, camera, &pb);
    ASSERT_EQ(pa.size(), 3u * 64 * 64);
    // The centre is the square's colour times the shade; a corner is empty.
    const double shade = facingShade();
    const uint8_t* c = pixel(pa, 64, 32, 32);
    EXPECT_EQ(int(c[0]), int(std::lround(255.0 * 0.7353569830524495 * shade)));
    EXPECT_EQ(int(c[1]), int(std::lround(255.0 * 0.48452920448170694 * shade)));
    EXPECT_EQ(int(c[2]), int(std::lround(255.0 * 0.9063317533440594 * shade)));
    EXPECT_EQ(int(pixel(pa, 64, 0, 0)[0]), 0);
    // The square spans 2 of the 2 tan(30) * 4 = 4.62 units the view shows:
    // 64 * 2 / 4.62 = 27.7 pixels across.
    int across = 0;
    for (int x = 0; x < 64; ++x)
        across += pixel(pa, 64, x, 32)[2] != 0;
    EXPECT_NEAR(across, 64.0 * 2.0 / (8.0 * std::tan(glm::radians(30.0))), 1.5);
    // PSNR: only the red channel differs, by the shaded step, over every
    // pixel the square covers.
    const int step = int(std::lround(255.0 * 0.7673756580558262 * shade)) - int(c[0]);
    EXPECT_NEAR(baker::picturePsnr(pa, pb), 10.0 * std::log10(255.0 * 255.0 / (step * step / 3.0)), 1e-9);
    EXPECT_EQ(baker::picturePsnr(pa, pa), 99.0);
    baker::renderPicture(baker::PictureMesh(), camera, &none);
    EXPECT_EQ(baker::picturePsnr(none, none), 0.0);
    EXPECT_EQ(baker::picturePsnr(pa, std::vector<uint8_t>(5)), 0.0);
}

TEST(Picture, TheNearerSquareIsDrawnWhicheverComesFirst)
{
    for (bool nearFirst : {true, false}) {
        baker::PictureMesh m;
        const glm::vec4 red(1, 0, 0, 1), blue(0, 0, 1, 1);
        if (nearFirst) {
            addSquare(&m, 0.5f, red);
            addSquare(&m, -0.5f, blue);
        } else {
            addSquare(&m, -0.5f, blue);
            addSquare(&m, 0.5f, red);
        }
        std::vector<uint8_t> p;
        baker::renderPicture(m, frontCamera(), &p);
        const uint8_t* c = pixel(p, 64, 32, 32);
        EXPECT_GT(int(c[0]), 0) << nearFirst;
        EXPECT_EQ(int(c[2]), 0) << nearFirst;
    }
}

TEST(Picture, TexturesAreReadWhereGltfPutsTheirRows)
{
    // Row 0 (v = 0) red, the rest green: the top of the square is red.
    io::ImageRGBA image;
    image.width = 4;
    image.height = 4;
    for (int y = 0; y < 4; ++y)
        for (int x = 0; x < 4; ++x)
            for (uint8_t v : {uint8_t(y < 2 ? 255 : 0), uint8_t(y < 2 ? 0 : 255), uint8_t(0), uint8_t(255)})
                image.rgba.push_back(v);
    baker::PictureMesh m;
    std::vector<float> uvs;
    addSquare(&m, 0.0f, glm::vec4(1.0f), &uvs);
    m.parts[0].uvs = uvs.data();
    m.parts[0].image = &image;
    std::vector<uint8_t> p;
    baker::renderPicture(m, frontCamera(), &p);
    const uint8_t* top = pixel(p, 64, 32, 22);
    const uint8_t* bottom = pixel(p, 64, 32, 42);
    // (Bilinear and repeating: near the square's top edge the last row, green,
    // blends in a little.)
    EXPECT_GT(int(top[0]), 200);
    EXPECT_LT(int(top[1]), 20);
    EXPECT_LT(int(bottom[0]), 20);
    EXPECT_GT(int(bottom[1]), 200);
}

// glTF's base colour: factor x decoded texture x COLOR_0, all linear, drawn
// sRGB-coded.  A vertex colour of 0.5 under a factor of 1 draws as a factor
// of 0.5; a texel coded 188 (0.5029 linear) under a factor of 1 draws as
// 188; its colour halved by the vertex colours draws as linear 0.2514.
TEST(Picture, VertexColoursAndTexturesMultiplyInLinear)
{
    const double shade = facingShade();
    baker::PictureMesh factor, coloured, textured;
    addSquare(&factor, 0.0f, glm::vec4(0.5f, 0.5f, 0.5f, 1.0f));
    addSquare(&coloured, 0.0f, glm::vec4(1.0f));
    const std::vector<float> half(16, 0.5f);
    coloured.parts[0].colours = half.data();
    coloured.parts[0].colourComponents = 4;
    std::vector<uint8_t> a, b;
    baker::renderPicture(factor, frontCamera(), &a);
    baker::renderPicture(coloured, frontCamera(), &b);
    EXPECT_EQ(int(pixel(a, 64, 32, 32)[0]), int(std::lround(255.0 * 0.7353569830524495 * shade)));
    EXPECT_EQ(a, b);

    io::ImageRGBA image;
    image.width = image.height = 2;
    image.rgba.assign(16, 188);
    std::vector<float> uvs;
    addSquare(&textured, 0.0f, glm::vec4(1.0f), &uvs);
    textured.parts[0].uvs = uvs.data();
    textured.parts[0].image = &image;
    baker::renderPicture(textured, frontCamera(), &a);
    EXPECT_EQ(int(pixel(a, 64, 32, 32)[1]), int(std::lround(188.0 * shade)));
    const std::vector<float> rgb(12, 0.5f);  // RGB: alpha stays 1
    textured.parts[0].colours = rgb.data();
    textured.parts[0].colourComponents = 3;
    baker::renderPicture(textured, frontCamera(), &a);
    // sRGB of 0.5 x 0.502886 (188 decoded) = 0.251443: 0.538521.
    EXPECT_EQ(int(pixel(a, 64, 32, 32)[1]), int(std::lround(255.0 * 0.538521 * shade)));
}

// The sRGB transfer (IEC 61966-2-1) at known points, and every 8-bit code
// decoded and coded again is itself.
TEST(Picture, SrgbCodingIsTheStandardsAndRoundTrips)
{
    EXPECT_NEAR(io::linearToSrgb(0.5), 0.7353569830524495, 1e-12);
    EXPECT_NEAR(io::linearToSrgb(0.001), 0.01292, 1e-12);  // the linear segment
    EXPECT_NEAR(io::srgbToLinear(188.0 / 255.0), 0.5028864580325687, 1e-12);
    EXPECT_EQ(io::srgbToLinear(0.0), 0.0);
    EXPECT_EQ(io::srgbToLinear(1.0), 1.0);
    EXPECT_NEAR(io::linearToSrgb(2.0), 1.0, 1e-12);
    for (int b = 0; b < 256; ++b)
        EXPECT_EQ(std::lround(255.0 * io::linearToSrgb(io::srgbToLinear(b / 255.0))), b);
}

TEST(Picture, FlatPartsTakeTheirFacesNormal)
{
    // Normals pointing away at a slant: smooth, the square is darker than
    // facing; flat, it is exactly the facing shade, its normals unread.
    baker::PictureMesh m;
    addSquare(&m, 0.0f, glm::vec4(1.0f));
    for (glm::vec3& n : m.normals)
        n = glm::vec3(-1.0f, -1.0f, 0.2f);
    std::vector<uint8_t> smooth, flat;
    baker::renderPicture(m, frontCamera(), &smooth);
    m.parts[0].flat = true;
    baker::renderPicture(m, frontCamera(), &flat);
    EXPECT_EQ(int(pixel(flat, 64, 32, 32)[0]), int(std::lround(255.0 * facingShade())));
    EXPECT_LT(int(pixel(smooth, 64, 32, 32)[0]), int(pixel(flat, 64, 32, 32)[0]) - 40);
}

TEST(Picture, FramingKeepsTheBoxInView)
{
    const glm::vec3 lo(-3, 0, -1), hi(1, 8, 2);
    const baker::PictureCamera c = baker::frameBox(lo, hi, 128);
    EXPECT_EQ(c.size, 128);
    EXPECT_EQ(c.target, 0.5f * (lo + hi));
    // Seen from the front (+Z), a little from the side and above.
    const glm::vec3 d = glm::normalize(c.eye - c.target);
    EXPECT_GT(d.z, 0.8f);
    EXPECT_GT(d.x, 0.0f);
    EXPECT_GT(d.y, 0.0f);
    // The box's sphere fits the view: its angular radius is 45% of the field.
    const float radius = 0.5f * glm::length(hi - lo);
    EXPECT_NEAR(std::asin(radius / glm::length(c.eye - c.target)), 0.45f * glm::radians(c.fovYDegrees), 1e-5f);
}

TEST(Sampler, BilinearOrNearestWrappedAsGltfsSamplers)
{
    io::ImageRGBA image;
    image.width = 2;
    image.height = 1;
    image.rgba = {0, 0, 0, 255, 200, 100, 50, 255};
    // Texel centres read their texels; halfway between them, the mean.
    EXPECT_DOUBLE_EQ(io::sampleImage(image, {0.25, 0.5}).r, 0.0);
    EXPECT_DOUBLE_EQ(io::sampleImage(image, {0.75, 0.5}).r, 200.0 / 255.0);
    EXPECT_DOUBLE_EQ(io::sampleImage(image, {0.5, 0.5}).g, 50.0 / 255.0);
    // Repeating: the texture's edge blends its last texel with its first,
    // and a UV whole units away reads the same.
    EXPECT_DOUBLE_EQ(io::sampleImage(image, {1.0, 0.5}).r, 100.0 / 255.0);
    EXPECT_DOUBLE_EQ(io::sampleImage(image, {-2.25, 3.5}).r, io::sampleImage(image, {0.75, 0.5}).r);
    // Nearest: the texel whose square holds the UV.
    EXPECT_DOUBLE_EQ(io::sampleImage(image, {0.45, 0.5}, true).r, 0.0);
    EXPECT_DOUBLE_EQ(io::sampleImage(image, {0.55, 0.5}, true).r, 200.0 / 255.0);
    // Clamped to its edge texels, or repeated as a mirror (a glTF sampler's
    // other wrap modes): past u = 1, a mirror reads the last texel first.
    using io::TextureWrap;
    EXPECT_DOUBLE_EQ(io::sampleImage(image, {1.0, 0.5}, false, TextureWrap::ClampToEdge).r, 200.0 / 255.0);
    EXPECT_DOUBLE_EQ(io::sampleImage(image, {-3.0, 0.5}, false, TextureWrap::ClampToEdge).r, 0.0);
    EXPECT_DOUBLE_EQ(io::sampleImage(image, {1.25, 0.5}, true, TextureWrap::MirroredRepeat).r, 200.0 / 255.0);
    EXPECT_DOUBLE_EQ(io::sampleImage(image, {1.75, 0.5}, true, TextureWrap::MirroredRepeat).r, 0.0);
    EXPECT_DOUBLE_EQ(io::sampleImage(image, {-0.25, 0.5}, true, TextureWrap::MirroredRepeat).r, 0.0);
    EXPECT_DOUBLE_EQ(io::sampleImage(image, {1.25, 0.5}, true).r, 0.0);  // repeating: the first texel again
    EXPECT_DOUBLE_EQ(io::sampleImage(image, {1.0, 0.5}, false, TextureWrap::MirroredRepeat).r, 200.0 / 255.0);
    // No image reads white; a UV that is not a number reads a texel.
    EXPECT_EQ(io::sampleImage(io::ImageRGBA(), {0.5, 0.5}), glm::dvec4(1.0));
    const glm::dvec4 nan = io::sampleImage(image, {std::nan(""), 0.5});
    EXPECT_TRUE(std::isfinite(nan.r));
}

// A normal texture read as glTF viewers read one on a mesh without TANGENT:
// +X along the UVs' +u, +Y along -v, +Z the normal.  One texel tilting the
// normal towards +X turns a square facing the eye to +x; with its UVs a
// quarter turn round (+u up the square), to +y; each shaded by its dot
// product with the light (over the eye's shoulder, up and to the right),
// 229 and 249 of 255 where facing is 225; at scale 0 the tilt is gone and
// the square is the facing shade.
TEST(Picture, NormalTexturesAreReadInTheFrameTheUVsGive)
{
    const glm::dvec3 light = glm::normalize(glm::dvec3(0.3, 0.6, 1.0));
    const glm::dvec3 tilt = glm::normalize(glm::dvec3(0.5, 0.0, 1.0));
    io::ImageRGBA texel;
    texel.width = texel.height = 1;
    texel.rgba = {uint8_t(std::lround(255.0 * (0.5 * tilt.x + 0.5))), uint8_t(std::lround(255.0 * (0.5 * tilt.y + 0.5))),
                  uint8_t(std::lround(255.0 * (0.5 * tilt.z + 0.5))), 255};
    // The texel as the picture decodes it (8 bits a channel).
    const glm::dvec3 stored = glm::normalize(glm::dvec3(2.0 * texel.rgba[0] / 255.0 - 1.0, 2.0 * texel.rgba[1] / 255.0 - 1.0,
                                                        2.0 * texel.rgba[2] / 255.0 - 1.0));
    const auto shadeOf = [&](const glm::dvec3& n) {
        return int(std::lround(255.0 * (0.3 + 0.7 * std::max(0.0, glm::dot(n, light)))));
    };
    for (int turn = 0; turn < 3; ++turn) {
        baker::PictureMesh m;
        std::vector<float> uvs;
        addSquare(&m, 0.0f, glm::vec4(1.0f), &uvs);
        if (turn == 1)  // u up the square (+y), v across it (+x)
            for (size_t k = 0; k < uvs.size(); k += 2) {
                const float u = uvs[k], v = uvs[k + 1];
                uvs[k] = 1.0f - v;
                uvs[k + 1] = u;
            }
        io::MaterialInfo material;
        material.normalImage = 0;
        material.normalScale = turn == 2 ? 0.0f : 1.0f;
        m.parts[0].normalImage = &texel;
        m.parts[0].normalUvs = uvs.data();
        m.parts[0].normalMaterial = &material;
        std::vector<uint8_t> rgb;
        baker::renderPicture(m, frontCamera(), &rgb);
        // +u is +x and +v is -y on the square as laid out: X = (1, 0, 0),
        // Y = (0, 1, 0).  A quarter turn makes +u +y and +v +x: X = (0, 1, 0),
        // Y = (-1, 0, 0).
        const glm::dvec3 expected = turn == 0   ? stored
                                    : turn == 1 ? glm::dvec3(-stored.y, stored.x, stored.z)
                                                : glm::dvec3(0.0, 0.0, 1.0);
        EXPECT_EQ(int(pixel(rgb, 64, 32, 32)[0]), shadeOf(expected)) << "turn " << turn;
        EXPECT_EQ(shadeOf(expected), turn == 0 ? 229 : turn == 1 ? 249 : 225) << "turn " << turn;
    }
    EXPECT_EQ(shadeOf(glm::dvec3(0.0, 0.0, 1.0)), int(std::lround(255.0 * facingShade())));
}
