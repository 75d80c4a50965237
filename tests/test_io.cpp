// strata_io: EXR maps, glTF rigs, OBJ meshes, atomic writes; every bad input
// gives a clear Status naming the file, never a crash.
#include "procedural.h"
#include "strata/baker/atlas.h"
#include "strata/io/exr.h"
#include "strata/io/file.h"
#include "strata/io/mesh_io.h"
#include "strata/io/png.h"
#include "strata/io/rig_io.h"
#include "strata/plan.h"
#include "test_util.h"

#include <nlohmann/json.hpp>
#include <stb/stb_image.h>

#include <cctype>
#include <cstring>
#include <filesystem>
#include <fstream>

#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfOutputFile.h>


using namespace strata;

namespace {

using strata::test::filesIn;
using strata::test::readText;
using strata::test::writeText;

// Writes a float EXR with arbitrary channels and values, bypassing the
// project's writer (which refuses bad maps).
void writeRawExr(const std::string& path, const char* channel, int w, int h, float fill, float special = 0.0f)
{
    Imf::Header header(w, h);
    header.channels().insert(channel, Imf::Channel(Imf::FLOAT));
    std::vector<float> px(size_t(w) * h, fill);
    px[px.size() / 2] = special == 0.0f ? fill : special;
    Imf::OutputFile file(path.c_str(), header);
    Imf::FrameBuffer fb;
    fb.insert(channel, Imf::Slice(Imf::FLOAT, reinterpret_cast<char*>(px.data()), sizeof(float), sizeof(float) * w));
    file.setFrameBuffer(fb);
    file.writePixels(h);
}

Rig exampleRig(int mapSize)
{
    Rig rig;
    rig.mesh = examples::makeIcosphere(0);
    EXPECT_TRUE(baker::buildTriangleAtlas(&rig.mesh, {mapSize, 2}).isOk());
    rig.hasDisplacement = true;
    rig.displacement.uri = "rig.exr";
    rig.displacement.encoding = "exr";
    rig.displacement.width = rig.displacement.height = mapSize;
    rig.displacement.factor = 0.5f;
    rig.displacement.offset = -0.25f;
    rig.displacement.scheme = Scheme::Smooth;
    rig.displacement.recommendedLevel = 4;
    return rig;
}

// exampleRig on a once-subdivided icosahedron, its atlas in a 128^2 map,
// recommending `level`: the per-vertex tests' rig.
Rig vertexExampleRig(int level)
{
    Rig rig = exampleRig(128);
    rig.mesh = examples::makeIcosphere(1);
    EXPECT_TRUE(baker::buildTriangleAtlas(&rig.mesh, {128, 2}).isOk());
    rig.displacement.recommendedLevel = level;
    return rig;
}

// exampleRig at level 2 with a 64^2 map of stripes: texel i holds
// offset + step * (i % 17).
Rig stripedRig(DisplacementMap* map, float step, float offset)
{
    Rig rig = exampleRig(64);
    rig.displacement.recommendedLevel = 2;
    map->width = map->height = 64;
    map->texels.clear();
    for (int i = 0; i < 64 * 64; ++i)
        map->texels.push_back(offset + step * float(i % 17));
    return rig;
}

}  // namespace

TEST(Exr, RoundTripsHalfAndFloat)
{
    const std::string dir = test::tempDir("exr_roundtrip");
    DisplacementMap map;
    map.width = 37;
    map.height = 23;
    for (int i = 0; i < map.width * map.height; ++i)
        map.texels.push_back(std::sin(float(i)) * 0.3f);
    ASSERT_TRUE(io::writeDisplacementExr(dir + "/f.exr", map, io::ExrPixelType::Float).isOk());
    ASSERT_TRUE(io::writeDisplacementExr(dir + "/h.exr", map, io::ExrPixelType::Half).isOk());
    DisplacementMap f, h;
    ASSERT_TRUE(io::readDisplacementExr(dir + "/f.exr", &f).isOk());
    ASSERT_TRUE(io::readDisplacementExr(dir + "/h.exr", &h).isOk());
    ASSERT_EQ(f.width, 37);
    ASSERT_EQ(f.height, 23);
    EXPECT_EQ(f.texels, map.texels);
    for (size_t i = 0; i < map.texels.size(); ++i)
        EXPECT_NEAR(h.texels[i], map.texels[i], 2e-4f);  // half: 11-bit mantissa
    EXPECT_EQ(filesIn(dir), 2u);                         // no temporary files left
}

TEST(Exr, RejectsBadFiles)
{
    const std::string dir = test::tempDir("exr_bad");
    DisplacementMap map;
    Status st = io::readDisplacementExr(dir + "/missing.exr", &map);
    EXPECT_FALSE(st.isOk());
    EXPECT_NE(st.message().find("missing.exr"), std::string::npos);

    writeText(dir + "/empty.exr", "");
    st = io::readDisplacementExr(dir + "/empty.exr", &map);
    EXPECT_NE(st.message().find("empty"), std::string::npos) << st.message();

    writeText(dir + "/text.exr", "this is not an image at all");
    st = io::readDisplacementExr(dir + "/text.exr", &map);
    EXPECT_NE(st.message().find("not an OpenEXR"), std::string::npos) << st.message();

    writeRawExr(dir + "/rgb.exr", "R", 8, 8, 0.0f);
    st = io::readDisplacementExr(dir + "/rgb.exr", &map);
    EXPECT_FALSE(st.isOk());
    EXPECT_NE(st.message().find("no \"Y\" channel (the file has: R)"), std::string::npos) << st.message();

    writeRawExr(dir + "/nan.exr", "Y", 8, 8, 0.0f, std::nanf(""));
    st = io::readDisplacementExr(dir + "/nan.exr", &map);
    EXPECT_NE(st.message().find("not finite"), std::string::npos) << st.message();

    writeRawExr(dir + "/inf.exr", "Y", 8, 8, 0.0f, INFINITY);
    st = io::readDisplacementExr(dir + "/inf.exr", &map);
    EXPECT_NE(st.message().find("not finite"), std::string::npos) << st.message();

    // Truncated: a valid header whose pixel data is cut off.
    writeRawExr(dir + "/whole.exr", "Y", 64, 64, 0.5f);
    const std::string bytes = readText(dir + "/whole.exr");
    writeText(dir + "/cut.exr", bytes.substr(0, bytes.size() / 2));
    st = io::readDisplacementExr(dir + "/cut.exr", &map);
    EXPECT_FALSE(st.isOk());
    // In Strata's words, the file named once (OpenEXR repeats the path).
    EXPECT_EQ(st.message().find("cut.exr"), st.message().rfind("cut.exr")) << st.message();
    EXPECT_EQ(st.message().find("Cannot read"), std::string::npos) << st.message();

    // Values a half cannot hold are refused rather than written as inf.
    DisplacementMap big;
    big.width = big.height = 2;
    big.texels = {0.0f, 1e6f, 0.0f, 0.0f};
    st = io::writeDisplacementExr(dir + "/big.exr", big, io::ExrPixelType::Half);
    EXPECT_FALSE(st.isOk());
    EXPECT_FALSE(test::fileExists(dir + "/big.exr"));
}

// Hostile EXR headers, from bytes: the sizes are refused from the header
// before OpenEXR sizes its tables or any texel is allocated.
TEST(Exr, RefusesHostileHeadersFromBytes)
{
    const std::string dir = test::tempDir("exr_hostile");
    writeRawExr(dir + "/small.exr", "Y", 8, 8, 0.25f);
    const std::string text = readText(dir + "/small.exr");
    const std::vector<unsigned char> good(text.begin(), text.end());
    DisplacementMap map;
    ASSERT_TRUE(io::decodeDisplacementExr(good.data(), good.size(), "small.exr", &map).isOk());
    EXPECT_EQ(map.width, 8);
    EXPECT_EQ(map.texels[3], 0.25f);

    // Finds the dataWindow value (4 int32: xmin ymin xmax ymax).
    const std::string key = std::string("dataWindow") + '\0' + "box2i" + '\0';
    const size_t at = text.find(key);
    ASSERT_NE(at, std::string::npos);
    const size_t value = at + key.size() + 4;
    auto withWindow = [&](int32_t xmax, int32_t ymax) {
        std::vector<unsigned char> b = good;
        std::memcpy(&b[value + 8], &xmax, 4);
        std::memcpy(&b[value + 12], &ymax, 4);
        return b;
    };
    // 65536^2 declared in a file of a few hundred bytes.
    std::vector<unsigned char> huge = withWindow(65535, 65535);
    Status st = io::decodeDisplacementExr(huge.data(), huge.size(), "huge.exr", &map);
    EXPECT_EQ(st.code(), StatusCode::InvalidData);
    EXPECT_NE(st.message().find("huge.exr: image size 65536x65536 is outside"), std::string::npos) << st.message();
    // 16384^2 is a legal size, but not in this many bytes.
    std::vector<unsigned char> dense = withWindow(16383, 16383);
    st = io::decodeDisplacementExr(dense.data(), dense.size(), "dense.exr", &map);
    EXPECT_NE(st.message().find("declares 16384x16384 texels but holds only"), std::string::npos) << st.message();
    // An inverted window.
    std::vector<unsigned char> inverted = withWindow(-5, 7);
    st = io::decodeDisplacementExr(inverted.data(), inverted.size(), "inv.exr", &map);
    EXPECT_NE(st.message().find("is outside"), std::string::npos) << st.message();
    // A caller's texel budget.
    st = io::decodeDisplacementExr(good.data(), good.size(), "small.exr", &map, 0, 0, 16);
    EXPECT_NE(st.message().find("exceed the budget of 16"), std::string::npos) << st.message();
    // An attribute of a type OpenEXR does not know, whose declared size runs
    // past the end of the file (OpenEXR would allocate it).
    const std::string orderKey = std::string("lineOrder") + '\0' + "lineOrder" + '\0';
    const size_t order = text.find(orderKey);
    ASSERT_NE(order, std::string::npos);
    std::vector<unsigned char> longAttr = good;
    longAttr[order + 10 + 8] = 'X';  // type "lineOrdeX"
    const int32_t twoGiB = 0x7fffffff;
    std::memcpy(&longAttr[order + orderKey.size()], &twoGiB, 4);
    st = io::decodeDisplacementExr(longAttr.data(), longAttr.size(), "attr.exr", &map);
    EXPECT_NE(st.message().find("attr.exr: not a readable OpenEXR file"), std::string::npos) << st.message();
    // Fuzzer finds: a channel list whose declared size differs from its
    // content put OpenEXR's header walk out of step with ours and it then
    // allocated a 1.6 GB attribute; both are refused from the header now.
    for (const char* name : {"exr_opaque_attribute_1600mb.exr", "exr_slow_header.exr"}) {
        const std::string found = readText(std::string(STRATA_SOURCE_DIR) + "/tests/data/hostile/" + name);
        ASSERT_FALSE(found.empty()) << name;
        st = io::decodeDisplacementExr(reinterpret_cast<const unsigned char*>(found.data()), found.size(), name, &map);
        EXPECT_FALSE(st.isOk()) << name;
        EXPECT_EQ(st.message().rfind(name, 0), 0u) << st.message();
    }
    // Every prefix of a good file fails cleanly (no throw, no crash).
    for (size_t n = 0; n < good.size(); n += 7)
        EXPECT_FALSE(io::decodeDisplacementExr(good.data(), n, "cut.exr", &map).isOk()) << n;
}

// Fuzzer find: a rig whose embedded PNG declares a 1.8 GB chunk; stb_image
// grew its buffer to it before reading.  Chunks are now checked to lie
// inside the file first, and the image's size against the rig's.
TEST(Png, RefusesChunksLongerThanTheFile)
{
    const std::string found = readText(std::string(STRATA_SOURCE_DIR) + "/tests/data/hostile/rig_png_1800mb.glb");
    ASSERT_FALSE(found.empty());
    Rig rig;
    Status st = io::loadRigFromMemory(reinterpret_cast<const unsigned char*>(found.data()), found.size(), true,
                                      "found.glb", &rig);
    if (st.isOk()) {
        DisplacementMap map;
        st = io::loadRigDisplacementMap("found.glb", rig, &map);
    }
    EXPECT_FALSE(st.isOk());
    EXPECT_EQ(st.message().rfind("found.glb", 0), 0u) << st.message();
    // A valid PNG with one chunk length raised past the end.
    std::string png;
    ASSERT_TRUE(io::encodePngGray(4, 4, 16, std::vector<uint16_t>(16, 7), &png).isOk());
    int w = 0, h = 0, bits = 0;
    std::vector<uint16_t> samples;
    ASSERT_TRUE(io::decodePngGray(reinterpret_cast<const unsigned char*>(png.data()), png.size(), "ok.png", &w, &h,
                                  &bits, &samples).isOk());
    EXPECT_EQ(samples, std::vector<uint16_t>(16, 7));
    std::string bad = png;
    bad[8] = char(0x7f);  // the IHDR chunk's length, high byte
    st = io::decodePngGray(reinterpret_cast<const unsigned char*>(bad.data()), bad.size(), "bad.png", &w, &h, &bits,
                           &samples);
    EXPECT_NE(st.message().find("bad.png: not a readable PNG image"), std::string::npos) << st.message();
    // The rig's size is checked from the header, before decoding.
    st = io::decodePngGray(reinterpret_cast<const unsigned char*>(png.data()), png.size(), "ok.png", &w, &h, &bits,
                           &samples, 8, 8);
    EXPECT_NE(st.message().find("image is 4x4 but the rig declares 8x8"), std::string::npos) << st.message();
}

// A colour texture is stored as the smaller of JPEG and PNG: flat colours
// (a low-poly character's palette) as a lossless PNG that reads back
// exactly, a photograph-like texture as JPEG, anything with alpha as PNG.
TEST(Png, ColourImagesTakeTheSmallerCoding)
{
    const int side = 256;
    std::vector<uint8_t> flat(size_t(side) * side * 4, 255), noisy = flat;
    uint32_t seed = 12345;
    for (int y = 0; y < side; ++y)
        for (int x = 0; x < side; ++x) {
            uint8_t* f = &flat[4 * (size_t(y) * side + size_t(x))];
            f[0] = x < side / 2 ? 230 : 80;  // four flat patches
            f[1] = y < side / 2 ? 120 : 40;
            f[2] = 20;
            uint8_t* n = &noisy[4 * (size_t(y) * side + size_t(x))];
            for (int c = 0; c < 3; ++c) {
                seed = seed * 1664525u + 1013904223u;
                n[c] = uint8_t((x + y * (c + 1)) / 3 + int(seed >> 28));  // a gradient with grain
            }
        }
    std::string bytes, mime, png;
    ASSERT_TRUE(io::encodeColourImage(side, side, flat, 90, &bytes, &mime).isOk());
    EXPECT_EQ(mime, "image/png");
    const std::string path = test::tempDir("colour_coding") + "/flat.png";
    std::ofstream(path, std::ios::binary).write(bytes.data(), std::streamsize(bytes.size()));
    int w = 0, h = 0;
    std::vector<uint8_t> rgb;
    ASSERT_TRUE(io::readPngRgb(path, &w, &h, &rgb).isOk());
    ASSERT_EQ(rgb.size(), size_t(side) * side * 3);
    for (size_t i = 0; i < size_t(side) * side; ++i)
        ASSERT_TRUE(std::equal(&rgb[3 * i], &rgb[3 * i] + 3, &flat[4 * i])) << i;

    ASSERT_TRUE(io::encodeColourImage(side, side, noisy, 90, &bytes, &mime).isOk());
    EXPECT_EQ(mime, "image/jpeg");
    ASSERT_TRUE(io::encodePngRgba(side, side, noisy, &png).isOk());
    EXPECT_LT(bytes.size(), png.size());

    noisy[3] = 128;  // one translucent texel: PNG keeps the alpha
    ASSERT_TRUE(io::encodeColourImage(side, side, noisy, 90, &bytes, &mime).isOk());
    EXPECT_EQ(mime, "image/png");
}

// An image of at most 256 colours (a low-poly character's palette) is coded
// indexed, a byte a pixel, and decodes to the same colours, translucent ones
// included (tRNS); one more colour and it is RGB.
TEST(Png, FewColoursAreCodedIndexed)
{
    const int side = 128;
    std::vector<uint8_t> image(size_t(side) * side * 4, 255);
    for (int y = 0; y < side; ++y)
        for (int x = 0; x < side; ++x) {
            uint8_t* p = &image[4 * (size_t(y) * side + size_t(x))];
            const int patch = (x / 16) + 8 * (y / 16);  // 64 patches, 64 colours
            p[0] = uint8_t(patch * 4);
            p[1] = uint8_t(255 - patch * 3);
            p[2] = uint8_t(patch % 7 * 30);
            p[3] = patch == 5 ? 100 : 255;
        }
    std::vector<uint32_t> colours;
    ASSERT_TRUE(io::paletteOf(image, &colours));
    EXPECT_EQ(colours.size(), 64u);
    EXPECT_TRUE(std::is_sorted(colours.begin(), colours.end()));
    std::string png, rgba;
    ASSERT_TRUE(io::encodePngRgba(side, side, image, &png).isOk());
    ASSERT_GT(png.size(), 26u);
    EXPECT_EQ(png[25], 3) << "colour type";
    EXPECT_NE(png.find("PLTE"), std::string::npos);
    EXPECT_NE(png.find("tRNS"), std::string::npos);
    int w = 0, h = 0, comp = 0;
    stbi_uc* px =
        stbi_load_from_memory(reinterpret_cast<const stbi_uc*>(png.data()), int(png.size()), &w, &h, &comp, 4);
    ASSERT_NE(px, nullptr);
    ASSERT_EQ(w, side);
    ASSERT_EQ(h, side);
    EXPECT_TRUE(std::equal(image.begin(), image.end(), px));
    stbi_image_free(px);

    // 257 colours (the 64, one more and 192 shades of red in the first
    // patch): no palette, and RGBA (one is translucent).
    std::vector<uint8_t> more = image;
    more[0] = 1;
    more[1] = 2;
    more[2] = 3;
    for (int i = 1; i <= 192; ++i)
        more[4 * size_t(i)] = uint8_t(i);
    EXPECT_FALSE(io::paletteOf(more, &colours));
    EXPECT_TRUE(colours.empty());
    ASSERT_TRUE(io::encodePngRgba(side, side, more, &png).isOk());
    EXPECT_EQ(png[25], 6) << "colour type";
}

TEST(Rig, RoundTripsThroughGlbAndGltf)
{
    const std::string dir = test::tempDir("rig_roundtrip");
    const Rig rig = exampleRig(256);
    for (const char* name : {"/rig.glb", "/rig.gltf"}) {
        ASSERT_TRUE(io::saveRig(dir + name, rig).isOk());
        Rig back;
        const Status st = io::loadRig(dir + name, &back);
        ASSERT_TRUE(st.isOk()) << st.message();
        EXPECT_EQ(back.mesh.positions, rig.mesh.positions);
        EXPECT_EQ(back.mesh.triangles, rig.mesh.triangles);
        ASSERT_EQ(back.mesh.uvIndices.size(), rig.mesh.uvIndices.size());
        for (size_t i = 0; i < rig.mesh.uvIndices.size(); ++i)
            EXPECT_EQ(back.mesh.uvs[back.mesh.uvIndices[i]], rig.mesh.uvs[rig.mesh.uvIndices[i]]);
        ASSERT_TRUE(back.hasDisplacement);
        EXPECT_EQ(back.displacement.uri, "rig.exr");
        EXPECT_EQ(back.displacement.width, 256);
        EXPECT_EQ(back.displacement.factor, 0.5f);
        EXPECT_EQ(back.displacement.offset, -0.25f);
        EXPECT_EQ(back.displacement.scheme, Scheme::Smooth);
        EXPECT_EQ(back.displacement.recommendedLevel, 4);
    }
}

// The "vertex" encoding: the map's samples at the recommended level's
// refined vertices, quantised, predicted and zstd-coded inside the rig.
TEST(Rig, StoresDisplacementsPerVertexWithinHalfAStep)
{
    const std::string dir = test::tempDir("rig_vertex");
    Rig rig = vertexExampleRig(3);
    DisplacementMap map;
    map.width = map.height = 128;
    for (int y = 0; y < 128; ++y)
        for (int x = 0; x < 128; ++x)
            map.texels.push_back(0.05f * std::sin(0.3f * float(x)) * std::cos(0.2f * float(y)));
    std::unique_ptr<Plan> plan;
    ASSERT_TRUE(Plan::create(&plan, rig.mesh, Scheme::Linear, 3).isOk());
    ASSERT_TRUE(plan->setDisplacement(map).isOk());
    const double step = 1e-3;
    io::RigWriteOptions options;
    options.vertexDisplacements = true;
    options.maxQuantizationStep = step;
    for (const char* name : {"/rig.glb", "/rig.gltf"}) {
        ASSERT_TRUE(io::saveRig(dir + name, rig, &map, nullptr, &options).isOk());
        Rig back;
        const Status st = io::loadRig(dir + name, &back);
        ASSERT_TRUE(st.isOk()) << st.message();
        EXPECT_EQ(back.displacement.encoding, "vertex");
        EXPECT_EQ(back.displacement.vertexLevel, 3);
        ASSERT_EQ(back.displacement.vertexValues.size(), plan->refinedVertexCount());
        // Each value is the map's sample at the vertex, within half a step;
        // on a UV seam, the median of its charts' samples (here, with one
        // chart per triangle, every vertex is on one).
        std::vector<std::vector<float>> samples(plan->refinedVertexCount());
        std::vector<std::vector<uint32_t>> seen(plan->refinedVertexCount());
        std::vector<glm::vec2> uvs;
        std::vector<uint32_t> uvIndices;
        plan->refinedUVs(&uvs, &uvIndices);
        for (size_t c = 0; c < plan->refinedTriangles().size(); ++c) {
            const uint32_t v = plan->refinedTriangles()[c], u = uvIndices[c];
            if (std::find(seen[v].begin(), seen[v].end(), u) == seen[v].end()) {
                seen[v].push_back(u);
                samples[v].push_back(sampleDisplacement(map, uvs[u]));
            }
        }
        for (size_t v = 0; v < plan->refinedVertexCount(); ++v) {
            std::vector<float>& s = samples[v];
            std::sort(s.begin(), s.end());
            const size_t k = s.size();
            const float expected = k % 2 ? s[k / 2] : 0.5f * (s[k / 2 - 1] + s[k / 2]);
            ASSERT_NEAR(back.displacement.vertexValues[v], expected, 0.5 * step + 1e-6) << v;
        }
        // Texture consumers get a map of the declared size.
        DisplacementMap raster;
        ASSERT_TRUE(io::loadRigDisplacementMap(dir + name, back, &raster).isOk());
        EXPECT_EQ(raster.width, 128);
        // Written back unchanged, the rig keeps its coded values.
        ASSERT_TRUE(io::saveRig(dir + "/again.glb", back).isOk());
        Rig again;
        ASSERT_TRUE(io::loadRig(dir + "/again.glb", &again).isOk());
        EXPECT_EQ(again.displacement.vertexValues, back.displacement.vertexValues);
    }
    // Fewer bytes than the same map as a PNG at the same step.
    io::RigWriteOptions png = options;
    png.vertexDisplacements = false;
    ASSERT_TRUE(io::saveRig(dir + "/png.glb", rig, &map, nullptr, &png).isOk());
    EXPECT_LT(test::readText(dir + "/rig.glb").size(), test::readText(dir + "/png.glb").size());
}

// The writer in steps: the caller gives its own per-vertex values over the
// control mesh as the file numbers it, and they are what the file holds; a
// commit without them, or values for another mesh, is refused and writes
// nothing.
TEST(Rig, WriterCodesTheValuesItIsGiven)
{
    const std::string dir = test::tempDir("rig_writer");
    Rig rig = vertexExampleRig(2);
    DisplacementMap map;
    map.width = map.height = 128;
    map.texels.assign(128 * 128, 0.0f);
    io::RigWriteOptions options;
    options.vertexDisplacements = true;
    options.compress = true;  // meshopt: the file's numbering may differ from rig.mesh's
    const double step = 1e-4;

    io::RigWriter writer;
    ASSERT_TRUE(writer.begin(dir + "/rig.glb", rig, &map, options).isOk());
    ASSERT_TRUE(writer.needsVertexValues());
    EXPECT_EQ(writer.vertexLevel(), 2);
    std::unique_ptr<Plan> plan;
    ASSERT_TRUE(Plan::create(&plan, writer.fileMesh(), Scheme::Linear, 2).isOk());
    ASSERT_EQ(writer.sampledValues().size(), plan->refinedVertexCount());
    for (float v : writer.sampledValues())
        EXPECT_EQ(v, 0.0f);  // the map is flat
    // Not yet committable, and values of the wrong count are refused.
    EXPECT_FALSE(writer.setVertexValues(std::vector<float>(3, 0.0f), step).isOk());
    // A ramp over the refined vertices of the file's numbering.
    std::vector<float> values(plan->refinedVertexCount());
    for (size_t v = 0; v < values.size(); ++v)
        values[v] = 0.01f * float(v % 17) - 0.05f;
    const ControlMesh fileMesh = writer.fileMesh();
    ASSERT_TRUE(writer.setVertexValues(values, step).isOk());
    EXPECT_FALSE(writer.needsVertexValues());
    ASSERT_TRUE(writer.commit().isOk());
    Rig back;
    ASSERT_TRUE(io::loadRig(dir + "/rig.glb", &back).isOk());
    // The file holds the mesh the values were given over, in its numbering.
    EXPECT_EQ(back.mesh.triangles, fileMesh.triangles);
    EXPECT_EQ(back.mesh.positions, fileMesh.positions);
    ASSERT_EQ(back.displacement.vertexValues.size(), values.size());
    for (size_t v = 0; v < values.size(); ++v)
        ASSERT_NEAR(back.displacement.vertexValues[v], values[v], 0.5 * step + 1e-7) << v;

    // Committing without the values writes nothing.
    io::RigWriter incomplete;
    ASSERT_TRUE(incomplete.begin(dir + "/incomplete.glb", rig, &map, options).isOk());
    const Status st = incomplete.commit();
    EXPECT_FALSE(st.isOk());
    EXPECT_NE(st.message().find("per-vertex displacements were not given"), std::string::npos) << st.message();
    EXPECT_FALSE(std::filesystem::exists(dir + "/incomplete.glb"));
}

// The io API takes std::filesystem::path: a rig written to and read from a
// folder and file name with spaces and non-ASCII letters (UTF-8).
TEST(Rig, PathsAreFilesystemPaths)
{
    namespace fs = std::filesystem;
    const fs::path dir = fs::path(test::tempDir("rig_paths")) / fs::u8path("t\xc3\xaate de cire");
    fs::create_directories(dir);
    Rig rig = exampleRig(64);
    const fs::path file = dir / fs::u8path("r\xc3\xa9sum\xc3\xa9 rig.glb");
    ASSERT_TRUE(io::saveRig(file, rig).isOk());
    EXPECT_TRUE(fs::is_regular_file(file));
    Rig back;
    const Status st = io::loadRig(file, &back);
    ASSERT_TRUE(st.isOk()) << st.message();
    EXPECT_EQ(back.mesh.faceCount(), rig.mesh.faceCount());
    const Status missing = io::loadRig(dir / "absent.glb", &back);
    EXPECT_FALSE(missing.isOk());
    EXPECT_NE(missing.message().find("absent.glb"), std::string::npos) << missing.message();
}

TEST(Rig, CorruptPerVertexDisplacementsAreRefused)
{
    const std::string dir = test::tempDir("rig_vertex_bad");
    DisplacementMap map;
    const Rig rig = stripedRig(&map, 0.01f, 0.0f);
    io::RigWriteOptions options;
    options.vertexDisplacements = true;
    ASSERT_TRUE(io::saveRig(dir + "/rig.glb", rig, &map, nullptr, &options).isOk());
    const std::string glb = readText(dir + "/rig.glb");
    uint32_t jsonLength = 0;
    std::memcpy(&jsonLength, glb.data() + 12, 4);
    const std::string json = glb.substr(20, jsonLength);
    // The coded view: the last bufferView (the block's), found by its offset.
    const size_t key = json.find("\"displacementVertices\"");
    ASSERT_NE(key, std::string::npos);
    const size_t bin = 20 + jsonLength + 8;
    Rig back;
    ASSERT_TRUE(io::loadRigFromMemory(reinterpret_cast<const unsigned char*>(glb.data()), glb.size(), true, "ok.glb",
                                      &back).isOk());
    const std::vector<unsigned char> coded = back.displacement.embedded;
    const size_t at = glb.find(std::string(coded.begin(), coded.end()), bin);
    ASSERT_NE(at, std::string::npos);
    // Every byte of the coded data flipped in turn, and every frame length
    // made huge: a clean error or a valid decode, never a crash or a hang.
    size_t refused = 0;
    for (size_t i = 0; i < coded.size(); ++i) {
        std::string bad = glb;
        bad[at + i] = char(bad[at + i] ^ 0x5a);
        Rig r;
        const Status st = io::loadRigFromMemory(reinterpret_cast<const unsigned char*>(bad.data()), bad.size(), true,
                                                "bad.glb", &r);
        if (!st.isOk()) {
            ++refused;
            EXPECT_NE(st.message().find("bad.glb"), std::string::npos) << st.message();
            EXPECT_EQ(st.message().find('\n'), std::string::npos);
        }
    }
    EXPECT_GT(refused, coded.size() / 2);
    std::string huge = glb;
    huge[at + 3] = char(0x7f);
    Rig r;
    const Status st = io::loadRigFromMemory(reinterpret_cast<const unsigned char*>(huge.data()), huge.size(), true,
                                            "huge.glb", &r);
    EXPECT_FALSE(st.isOk());
    EXPECT_NE(st.message().find("per-vertex displacements end early"), std::string::npos) << st.message();
}

// Version 5 is the declared extension STRATA_layered_displacement: listed in
// extensionsUsed only, the coded values reached through an accessor, the
// control mesh it was baked on recorded, and (as version 4) the fields that
// have one value left out.  Its numbers of float data carry float precision.
// Version 4 (the same block in extras, the values by bufferView) and a
// version 3 block that spells everything out load the same, and a coding
// this build does not know is refused.
TEST(Rig, VersionFiveIsTheDeclaredExtensionAndVersionsThreeAndFourStillLoad)
{
    const std::string dir = test::tempDir("rig_version4");
    DisplacementMap map;
    const Rig rig = stripedRig(&map, 0.013f, -0.05f);
    io::RigWriteOptions options;
    options.vertexDisplacements = true;
    options.omitDisplacementUVs = true;
    ASSERT_TRUE(io::saveRig(dir + "/rig.gltf", rig, &map, nullptr, &options).isOk());
    const std::string text = readText(dir + "/rig.gltf");
    nlohmann::json doc = nlohmann::json::parse(text);
    const nlohmann::json& layer = doc["meshes"][0]["extensions"][io::kLayerExtension];
    ASSERT_TRUE(layer.is_object());
    EXPECT_EQ(doc["extensionsUsed"], nlohmann::json::array({io::kLayerExtension}));
    EXPECT_FALSE(doc.contains("extensionsRequired"));
    EXPECT_FALSE(doc["meshes"][0].contains("extras"));
    for (const char* omitted : {"version", "direction", "normalWeighting", "subdivision", "displacementGeometryTexture"})
        EXPECT_FALSE(layer.contains(omitted)) << omitted;
    EXPECT_FALSE(layer["displacementVertices"].contains("coding"));
    const nlohmann::json& values = doc["accessors"][layer["displacementVertices"]["accessor"].get<size_t>()];
    EXPECT_EQ(values["componentType"], 5121);
    EXPECT_EQ(values["type"], "SCALAR");
    EXPECT_EQ(layer["control"]["vertices"], rig.mesh.vertexCount());
    EXPECT_EQ(layer["control"]["triangles"], rig.mesh.faceCount());
    for (const char* hash : {"topology", "positions", "shape"})
        EXPECT_EQ(layer["control"][hash].get<std::string>().find_first_not_of("0123456789abcdef"), std::string::npos)
            << hash;
    // Float data in at most nine significant digits ("0.57565022").
    for (const char* key : {"\"displacementGeometryFactor\":", "\"displacementGeometryOffset\":", "\"max\":"}) {
        size_t at = text.find(key);
        ASSERT_NE(at, std::string::npos) << key;
        at += std::strlen(key);
        while (at < text.size() && (text[at] == ' ' || text[at] == '[' || text[at] == '\n'))
            ++at;
        int digits = 0;
        bool leading = true;
        for (; at < text.size() && (std::isdigit(static_cast<unsigned char>(text[at])) || text[at] == '.' ||
                                    text[at] == '-');
             ++at) {
            if (std::isdigit(static_cast<unsigned char>(text[at])) && !(leading && text[at] == '0')) {
                leading = false;
                ++digits;
            }
        }
        EXPECT_GE(digits, 1) << key;
        EXPECT_LE(digits, 9) << key;
    }
    Rig five;
    Status st = io::loadRig(dir + "/rig.gltf", &five);
    ASSERT_TRUE(st.isOk()) << st.message();
    EXPECT_EQ(five.displacement.texCoord, -1);
    EXPECT_EQ(five.displacement.encoding, "vertex");

    test::layerToVersionFour(doc);
    nlohmann::json& block = doc["meshes"][0]["extras"]["strata"];
    writeText(dir + "/v4.gltf", doc.dump());
    Rig four;
    st = io::loadRig(dir + "/v4.gltf", &four);
    ASSERT_TRUE(st.isOk()) << st.message();
    EXPECT_EQ(four.displacement.vertexValues, five.displacement.vertexValues);
    EXPECT_EQ(four.displacement.encoding, "vertex");

    block["version"] = 3;
    block["direction"] = "interpolated-control-normal";
    block["normalWeighting"] = "angle";
    block["subdivision"] = {{"rule", "loop"}, {"boundary", "edge-and-corner"}, {"faceVaryingInterpolation", "linear-all"}};
    block["displacementGeometryTexture"] = {{"encoding", "vertex"}, {"width", 64}, {"height", 64}};
    block["displacementVertices"]["coding"] = "subdivision-midpoint-zstd";
    writeText(dir + "/v3.gltf", doc.dump());
    Rig three;
    st = io::loadRig(dir + "/v3.gltf", &three);
    ASSERT_TRUE(st.isOk()) << st.message();
    EXPECT_EQ(three.displacement.vertexValues, four.displacement.vertexValues);
    EXPECT_EQ(three.displacement.factor, four.displacement.factor);
    EXPECT_EQ(three.displacement.offset, four.displacement.offset);
    EXPECT_EQ(three.displacement.width, 64);

    // A version 3 block must spell out the direction.
    block.erase("direction");
    writeText(dir + "/v3bad.gltf", doc.dump());
    st = io::loadRig(dir + "/v3bad.gltf", &three);
    EXPECT_FALSE(st.isOk());
    EXPECT_NE(st.message().find("\"direction\""), std::string::npos) << st.message();
    block["direction"] = "interpolated-control-normal";
    block["displacementVertices"]["coding"] = "wavelet";
    writeText(dir + "/coding.gltf", doc.dump());
    st = io::loadRig(dir + "/coding.gltf", &three);
    EXPECT_FALSE(st.isOk());
    EXPECT_NE(st.message().find("coding \"wavelet\" is not supported"), std::string::npos) << st.message();
}

// glTF allows accessors without a bufferView (zeros) and sparse accessors
// (a base, or zeros, with elements replaced): gltf-transform writes both.
// A quad whose positions are sparse over a base, whose UVs have no
// bufferView and whose morph target is sparse over zeros loads with the
// values the spec defines, and writes back as plain valid glTF.  A sparse
// part whose indices do not increase, or a count no bytes back, is refused.
TEST(Rig, AccessorsWithoutBufferViewsAndSparseAccessorsRead)
{
    const std::string dir = test::tempDir("rig_sparse");
    std::vector<unsigned char> bin(88, 0);
    const float positions[12] = {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0};
    const uint16_t indices[6] = {0, 1, 2, 0, 2, 3};
    const uint16_t sparseIndices[2] = {1, 2};
    const float sparseValues[6] = {2, 0, 0, 2, 2, 0.5f};
    std::memcpy(&bin[0], positions, 48);
    std::memcpy(&bin[48], indices, 12);
    std::memcpy(&bin[60], sparseIndices, 4);
    std::memcpy(&bin[64], sparseValues, 24);
    {
        std::ofstream f(dir + "/quad.bin", std::ios::binary);
        f.write(reinterpret_cast<const char*>(bin.data()), std::streamsize(bin.size()));
    }
    const std::string sparse = R"("sparse":{"count":2,"indices":{"bufferView":2,"componentType":5123},"values":{"bufferView":3}})";
    auto gltf = [&](const std::string& positionSparse, size_t uvCount) {
        return std::string(R"({"asset":{"version":"2.0"},"buffers":[{"uri":"quad.bin","byteLength":88}],)") +
               R"("bufferViews":[{"buffer":0,"byteOffset":0,"byteLength":48},{"buffer":0,"byteOffset":48,"byteLength":12},)" +
               R"({"buffer":0,"byteOffset":60,"byteLength":4},{"buffer":0,"byteOffset":64,"byteLength":24}],)" +
               R"("accessors":[{"bufferView":0,"componentType":5126,"count":4,"type":"VEC3","min":[0,0,0],"max":[2,2,0.5],)" +
               positionSparse + R"(},{"bufferView":1,"componentType":5123,"count":6,"type":"SCALAR"},)" +
               R"({"componentType":5126,"count":)" + std::to_string(uvCount) + R"(,"type":"VEC2"},)" +
               R"({"componentType":5126,"count":4,"type":"VEC3","min":[0,0,0],"max":[2,2,0.5],)" + sparse + "}],"
               R"("meshes":[{"primitives":[{"attributes":{"POSITION":0,"TEXCOORD_0":2},"indices":1,"targets":[{"POSITION":3}]}],"weights":[0]}],)"
               R"("nodes":[{"mesh":0}],"scenes":[{"nodes":[0]}],"scene":0})";
    };
    writeText(dir + "/quad.gltf", gltf(sparse, 4));
    Rig rig;
    Status st = io::loadRig(dir + "/quad.gltf", &rig);
    ASSERT_TRUE(st.isOk()) << st.message();
    ASSERT_EQ(rig.mesh.vertexCount(), 4u);
    EXPECT_EQ(rig.mesh.positions[0], glm::vec3(0, 0, 0));
    EXPECT_EQ(rig.mesh.positions[1], glm::vec3(2, 0, 0));  // replaced by the sparse part
    EXPECT_EQ(rig.mesh.positions[2], glm::vec3(2, 2, 0.5f));
    EXPECT_EQ(rig.mesh.positions[3], glm::vec3(0, 1, 0));
    ASSERT_TRUE(rig.mesh.hasUVs());
    for (const glm::vec2& uv : rig.mesh.uvs)
        EXPECT_EQ(uv, glm::vec2(0.0f));  // no bufferView: zeros
    ASSERT_TRUE(io::saveRig(dir + "/back.glb", rig).isOk());
    int code = 0;
    const std::string report = test::runGltfValidator({dir + "/back.glb"}, &code);
    EXPECT_EQ(code, 0) << report;
    Rig back;
    ASSERT_TRUE(io::loadRig(dir + "/back.glb", &back).isOk());
    EXPECT_EQ(back.mesh.positions, rig.mesh.positions);

    // Sparse indices that do not increase.
    std::vector<unsigned char> swapped = bin;
    const uint16_t down[2] = {2, 1};
    std::memcpy(&swapped[60], down, 4);
    {
        std::ofstream f(dir + "/quad.bin", std::ios::binary);
        f.write(reinterpret_cast<const char*>(swapped.data()), std::streamsize(swapped.size()));
    }
    st = io::loadRig(dir + "/quad.gltf", &rig);
    EXPECT_FALSE(st.isOk());
    EXPECT_NE(st.message().find("not increasing"), std::string::npos) << st.message();
    // A billion zeros that no byte backs.
    {
        std::ofstream f(dir + "/quad.bin", std::ios::binary);
        f.write(reinterpret_cast<const char*>(bin.data()), std::streamsize(bin.size()));
    }
    writeText(dir + "/huge.gltf", gltf(sparse, 1000000000));
    st = io::loadRig(dir + "/huge.gltf", &rig);
    EXPECT_FALSE(st.isOk());
    EXPECT_NE(st.message().find("without the bytes to back them"), std::string::npos) << st.message();
}

// External files are confined by what they resolve to, not by spelling: a
// buffer that is a symbolic link out of the rig's folder, or that lies in a
// sub-folder linking out of it, is refused; a link that stays inside loads.
TEST(Rig, SymbolicLinksOutOfTheRigFolderAreRefused)
{
    const std::string root = test::tempDir("rig_symlinks");
    const std::string dir = root + "/rig", secret = root + "/secret";
    std::filesystem::create_directories(dir);
    std::filesystem::create_directories(secret);
    const float positions[9] = {0, 0, 0, 1, 0, 0, 0, 1, 0};
    {
        std::ofstream f(secret + "/data.bin", std::ios::binary);
        f.write(reinterpret_cast<const char*>(positions), 36);
        std::ofstream g(dir + "/real.bin", std::ios::binary);
        g.write(reinterpret_cast<const char*>(positions), 36);
    }
    auto gltf = [](const std::string& uri) {
        return R"({"asset":{"version":"2.0"},"buffers":[{"uri":")" + uri +
               R"(","byteLength":36}],"bufferViews":[{"buffer":0,"byteLength":36}],)"
               R"("accessors":[{"bufferView":0,"componentType":5126,"count":3,"type":"VEC3","min":[0,0,0],"max":[1,1,0]}],)"
               R"("meshes":[{"primitives":[{"attributes":{"POSITION":0}}]}],"nodes":[{"mesh":0}],"scenes":[{"nodes":[0]}]})";
    };
    std::filesystem::create_symlink("../secret/data.bin", dir + "/out.bin");
    std::filesystem::create_directory_symlink("../secret", dir + "/sub");
    std::filesystem::create_symlink("real.bin", dir + "/in.bin");
    Rig rig;
    for (const char* uri : {"out.bin", "sub/data.bin"}) {
        writeText(dir + "/r.gltf", gltf(uri));
        const Status st = io::loadRig(dir + "/r.gltf", &rig);
        EXPECT_FALSE(st.isOk()) << uri;
        EXPECT_NE(st.message().find("leads outside the rig's folder"), std::string::npos) << st.message();
    }
    writeText(dir + "/r.gltf", gltf("in.bin"));
    const Status st = io::loadRig(dir + "/r.gltf", &rig);
    ASSERT_TRUE(st.isOk()) << st.message();
    EXPECT_EQ(rig.mesh.vertexCount(), 3u);
}

// Memory is justified by bytes: an EXT_meshopt_compression fallback buffer
// that declares 2 GiB (a fallback is no backing), or a view that declares
// far more decoded bytes than its coded bytes can carry, is refused before
// anything is allocated.
TEST(Rig, MeshoptFallbackBuffersAreNoBacking)
{
    const std::string dir = test::tempDir("rig_fallback");
    DisplacementMap map;
    const Rig rig = stripedRig(&map, 0.013f, -0.05f);
    io::RigWriteOptions options;
    options.compress = true;
    ASSERT_TRUE(io::saveRig(dir + "/rig.glb", rig, &map, nullptr, &options).isOk());
    const std::string glb = test::readText(dir + "/rig.glb");
    nlohmann::json doc = test::glbJson(glb);
    ASSERT_GE(doc["buffers"].size(), 2u) << "a meshopt rig has a fallback buffer";
    Rig back;
    ASSERT_TRUE(io::loadRigFromMemory(reinterpret_cast<const unsigned char*>(glb.data()), glb.size(), true, "rig.glb",
                                      &back).isOk());
    doc["buffers"][1]["byteLength"] = 2147483000;
    std::string hostile = test::glbWithJson(glb, doc);
    Status st = io::loadRigFromMemory(reinterpret_cast<const unsigned char*>(hostile.data()), hostile.size(), true,
                                      "rig.glb", &back);
    EXPECT_FALSE(st.isOk());
    EXPECT_NE(st.message().find("a fallback is no backing"), std::string::npos) << st.message();
    doc = test::glbJson(glb);
    for (nlohmann::json& view : doc["bufferViews"])
        if (view.contains("extensions")) {
            view["byteLength"] = 1 << 30;
            view["extensions"]["EXT_meshopt_compression"]["count"] = (1 << 30) / view["extensions"]["EXT_meshopt_compression"]["byteStride"].get<int>();
            break;
        }
    hostile = test::glbWithJson(glb, doc);
    st = io::loadRigFromMemory(reinterpret_cast<const unsigned char*>(hostile.data()), hostile.size(), true, "rig.glb",
                               &back);
    EXPECT_FALSE(st.isOk());
    EXPECT_NE(st.message().find("coded bytes"), std::string::npos) << st.message();
}

TEST(Rig, LoadsTheMapBesideItAndChecksItsSize)
{
    const std::string dir = test::tempDir("rig_map");
    Rig rig = exampleRig(64);
    ASSERT_TRUE(io::saveRig(dir + "/rig.glb", rig).isOk());
    DisplacementMap map;
    Status st = io::loadRigDisplacementMap(dir + "/rig.glb", rig, &map);
    EXPECT_FALSE(st.isOk());  // the EXR is not there yet
    EXPECT_NE(st.message().find("rig.exr"), std::string::npos) << st.message();

    DisplacementMap wrong;
    wrong.width = wrong.height = 32;
    wrong.texels.assign(32 * 32, 0.25f);
    ASSERT_TRUE(io::writeDisplacementExr(dir + "/rig.exr", wrong).isOk());
    st = io::loadRigDisplacementMap(dir + "/rig.glb", rig, &map);
    EXPECT_FALSE(st.isOk());
    EXPECT_NE(st.message().find("32x32"), std::string::npos) << st.message();

    DisplacementMap right;
    right.width = right.height = 64;
    right.texels.assign(64 * 64, 0.25f);
    ASSERT_TRUE(io::writeDisplacementExr(dir + "/rig.exr", right).isOk());
    ASSERT_TRUE(io::loadRigDisplacementMap(dir + "/rig.glb", rig, &map).isOk());
    EXPECT_EQ(map.factor, 0.5f);
    EXPECT_FLOAT_EQ(sampleDisplacement(map, {0.3f, 0.7f}), 0.25f * 0.5f - 0.25f);
}

TEST(Rig, RejectsAnotherFormatVersion)
{
    const std::string dir = test::tempDir("rig_version");
    ASSERT_TRUE(io::saveRig(dir + "/rig.gltf", exampleRig(64)).isOk());
    nlohmann::json doc = nlohmann::json::parse(readText(dir + "/rig.gltf"));
    test::layerToVersionFour(doc);
    doc["meshes"][0]["extras"]["strata"]["version"] = 7;
    writeText(dir + "/v7.gltf", doc.dump());
    Rig rig;
    const Status st = io::loadRig(dir + "/v7.gltf", &rig);
    EXPECT_FALSE(st.isOk());
    EXPECT_NE(st.message().find("version 7 in extras, this build reads versions 1 to 4"), std::string::npos)
        << st.message();
}

TEST(Rig, RejectsBrokenGltf)
{
    const std::string dir = test::tempDir("rig_broken");
    Rig rig;
    auto expectError = [&](const std::string& name, const std::string& content, const std::string& needle) {
        writeText(dir + "/" + name, content);
        const Status st = io::loadRig(dir + "/" + name, &rig);
        EXPECT_FALSE(st.isOk()) << name;
        EXPECT_NE(st.message().find(name), std::string::npos) << st.message();
        EXPECT_NE(st.message().find(needle), std::string::npos) << name << ": " << st.message();
    };
    expectError("empty.glb", "", "empty");
    expectError("garbage.glb", std::string(200, 'x'), "");
    expectError("garbage.gltf", "{ this is not json", "");
    expectError("nomesh.gltf", R"({"asset":{"version":"2.0"}})", "no triangle mesh");
    // 3 vertices declared, but the buffer holds 12 bytes.
    const std::string shortBuffer =
        R"({"asset":{"version":"2.0"},"buffers":[{"byteLength":12,"uri":"data:application/octet-stream;base64,AAAAAAAAAAAAAAAA"}],
            "bufferViews":[{"buffer":0,"byteLength":12}],
            "accessors":[{"bufferView":0,"componentType":5126,"count":3,"type":"VEC3"}],
            "meshes":[{"primitives":[{"attributes":{"POSITION":0}}]}]})";
    expectError("short.gltf", shortBuffer, "past the end");
    const std::string noPosition =
        R"({"asset":{"version":"2.0"},"meshes":[{"primitives":[{"attributes":{}}]}]})";
    expectError("noposition.gltf", noPosition, "POSITION");
    std::string truncated = readText(dir + "/../rig_version/rig.gltf");
    if (!truncated.empty())
        expectError("truncated.gltf", truncated.substr(0, truncated.size() / 2), "");
    ASSERT_TRUE(io::saveRig(dir + "/ok.glb", exampleRig(64)).isOk());
    const std::string glb = readText(dir + "/ok.glb");
    expectError("cut.glb", glb.substr(0, glb.size() - 100), "");
    // Out-of-range index: one triangle referencing vertex 7 of 3.
    const std::string badIndex =
        R"({"asset":{"version":"2.0"},"buffers":[{"byteLength":44,"uri":"data:application/octet-stream;base64,AAAAAAAAAAAAAAAAAACAPwAAAAAAAAAAAAAAAAAAgD8AAAAAAAABAAcAAAA="}],
            "bufferViews":[{"buffer":0,"byteLength":36},{"buffer":0,"byteOffset":36,"byteLength":6}],
            "accessors":[{"bufferView":0,"componentType":5126,"count":3,"type":"VEC3","min":[0,0,0],"max":[1,1,0]},
                         {"bufferView":1,"componentType":5123,"count":3,"type":"SCALAR"}],
            "meshes":[{"primitives":[{"attributes":{"POSITION":0},"indices":1}]}]})";
    expectError("badindex.gltf", badIndex, "beyond");
    expectError("rig.txt", "whatever", "not a .glb or .gltf");
}

// The layer's optional "shading": written only when flat, read back, and
// any other value than "flat" or "smooth" refused by name.  Plain glTF
// parts are flat exactly where a primitive has no NORMAL (Fox has none,
// CesiumMan has them), as glTF draws them.
TEST(Rig, ShadingIsGltfsForPlainFilesAndTheLayersForRigs)
{
    const std::string dir = test::tempDir("rig_shading");
    Rig rig = exampleRig(64);
    ASSERT_TRUE(io::saveRig(dir + "/smooth.gltf", rig).isOk());
    EXPECT_EQ(readText(dir + "/smooth.gltf").find("\"shading\""), std::string::npos);
    Rig back;
    ASSERT_TRUE(io::loadRig(dir + "/smooth.gltf", &back).isOk());
    EXPECT_FALSE(back.displacement.flatShading);
    for (const RigPart& part : back.parts)
        EXPECT_FALSE(part.flat) << "a control mesh without NORMAL is not flat unless its layer says so";
    rig.displacement.flatShading = true;
    ASSERT_TRUE(io::saveRig(dir + "/flat.gltf", rig).isOk());
    ASSERT_TRUE(io::loadRig(dir + "/flat.gltf", &back).isOk());
    EXPECT_TRUE(back.displacement.flatShading);
    ASSERT_FALSE(back.parts.empty());
    for (const RigPart& part : back.parts)
        EXPECT_TRUE(part.flat);
    std::string text = readText(dir + "/flat.gltf");
    const size_t at = text.find("\"flat\"", text.find("\"shading\""));
    ASSERT_NE(at, std::string::npos);
    text.replace(at, std::strlen("\"flat\""), "\"faceted\"");
    writeText(dir + "/faceted.gltf", text);
    const Status st = io::loadRig(dir + "/faceted.gltf", &back);
    EXPECT_FALSE(st.isOk());
    EXPECT_NE(st.message().find("faceted.gltf: shading \"faceted\""), std::string::npos) << st.message();
    for (const char* name : {"Fox.glb", "CesiumMan.glb"}) {
        STRATA_REQUIRE_DATA(path, name);
        Rig plain;
        ASSERT_TRUE(io::loadRig(path, &plain).isOk());
        ASSERT_FALSE(plain.parts.empty());
        for (const RigPart& part : plain.parts)
            EXPECT_EQ(part.flat, std::string(name) == "Fox.glb") << name << " " << part.name;
    }
}

TEST(Rig, WeldsSplitVerticesOfPlainGltf)
{
    STRATA_REQUIRE_DATA(path, "Fox.glb");
    Rig rig;
    const Status st = io::loadRig(path, &rig);
    ASSERT_TRUE(st.isOk()) << st.message();
    EXPECT_FALSE(rig.hasDisplacement);
    EXPECT_EQ(rig.sourceVertex.size(), 1728u);  // non-indexed: 3 file vertices per triangle
    EXPECT_LT(rig.mesh.positions.size(), 1728u / 2);
    EXPECT_TRUE(rig.mesh.hasUVs());
}

TEST(Obj, ReadsPolygonsAndUVs)
{
    const std::string dir = test::tempDir("obj_read");
    writeText(dir + "/quad.obj", "# a quad\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n"
                                 "f 1/1 2/2 3/3 4/4\n");
    ControlMesh m;
    io::ObjReadInfo info;
    ASSERT_TRUE(io::readObj(dir + "/quad.obj", &m, &info).isOk());
    EXPECT_EQ(m.faceCount(), 2u);
    EXPECT_EQ(info.triangulated, 1u);
    EXPECT_EQ(m.uvs[0], glm::vec2(0.0f, 1.0f));  // v flipped to glTF's convention
    writeText(dir + "/neg.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf -3 -2 -1\n");
    ASSERT_TRUE(io::readObj(dir + "/neg.obj", &m).isOk());
    EXPECT_EQ(m.triangles, (std::vector<uint32_t>{0, 1, 2}));
    EXPECT_FALSE(m.hasUVs());
}

TEST(Obj, RejectsBadFiles)
{
    const std::string dir = test::tempDir("obj_bad");
    ControlMesh m;
    auto expectError = [&](const std::string& name, const std::string& content, const std::string& needle) {
        writeText(dir + "/" + name, content);
        const Status st = io::readObj(dir + "/" + name, &m);
        EXPECT_FALSE(st.isOk()) << name;
        EXPECT_NE(st.message().find(name), std::string::npos) << st.message();
        EXPECT_NE(st.message().find(needle), std::string::npos) << name << ": " << st.message();
    };
    expectError("empty.obj", "", "empty");
    expectError("novertices.obj", "# nothing\n", "no vertices");
    expectError("nofaces.obj", "v 0 0 0\n", "no faces");
    expectError("nan.obj", "v 0 0 0\nv nan 0 0\nv 0 1 0\nf 1 2 3\n", ":2:");
    expectError("inf.obj", "v 0 0 0\nv 1e39 0 0\nv 0 1 0\nf 1 2 3\n", ":2:");
    expectError("index.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n", "vertex 9 of 3");
    expectError("zero.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n", ":4:");
    expectError("two.obj", "v 0 0 0\nv 1 0 0\nf 1 2\n", "fewer than 3");
    expectError("mixed.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nf 1/1 2 3\n", "mixes");
    expectError("binary.obj", std::string("v 0 0 0\n\0\0\0", 11), "binary");
    EXPECT_FALSE(io::readObj(dir + "/does-not-exist.obj", &m).isOk());
    EXPECT_FALSE(io::readObj(dir, &m).isOk());  // a directory
}

TEST(AtomicWrite, FailsCleanlyAndLeavesNothing)
{
    const std::string dir = test::tempDir("atomic");
    const char data[] = "hello";
    EXPECT_FALSE(io::writeFileAtomic(dir + "/no/such/dir/file.bin", data, 5).isOk());
    ASSERT_TRUE(io::writeFileAtomic(dir + "/file.bin", data, 5).isOk());
    EXPECT_EQ(readText(dir + "/file.bin"), "hello");
    // A writer that fails half-way leaves neither the target nor a temporary.
    const Status st = io::writeViaTempFile(dir + "/half.bin", [](const std::string& tmp) {
        writeText(tmp, "partial");
        return std::string("simulated failure");
    });
    EXPECT_FALSE(st.isOk());
    EXPECT_NE(st.message().find("simulated failure"), std::string::npos);
    EXPECT_EQ(filesIn(dir), 1u);
    // Overwriting keeps the old content until the new one is complete.
    ASSERT_TRUE(io::writeFileAtomic(dir + "/file.bin", "bye", 3).isOk());
    EXPECT_EQ(readText(dir + "/file.bin"), "bye");
}

TEST(MeshWrite, WritesEveryFormatAndRejectsUnknownOnes)
{
    const std::string dir = test::tempDir("mesh_write");
    const ControlMesh m = examples::makeSquare();
    io::MeshView view;
    view.positions = m.positions.data();
    view.vertexCount = m.positions.size();
    view.triangles = m.triangles.data();
    view.faceCount = m.faceCount();
    view.uvs = m.uvs.data();
    view.uvCount = m.uvs.size();
    view.uvIndices = m.uvIndices.data();
    for (const char* ext : {".obj", ".ply", ".glb", ".gltf"})
        EXPECT_TRUE(io::writeMesh(dir + "/m" + ext, view).isOk()) << ext;
    ControlMesh back;
    ASSERT_TRUE(io::readObj(dir + "/m.obj", &back).isOk());
    EXPECT_EQ(back.positions, m.positions);
    EXPECT_EQ(back.uvs, m.uvs);
    EXPECT_FALSE(io::writeMesh(dir + "/m.xyz", view).isOk());
    EXPECT_EQ(filesIn(dir), 4u);
}
