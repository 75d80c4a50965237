// strata-view screenshots: the built-in example and Fox render, are in
// frame, change with the level, and the displaced image differs from the
// undisplaced one where the detail is (nose, ears) and nowhere outside the
// model.  Headless through EGL; the windowed path once under xvfb-run.
#include "strata/io/png.h"
#include "strata/io/rig_io.h"
#include "test_rigs.h"

#include <cstdlib>

#include <cstring>

using namespace strata;

namespace {

struct Image {
    int width = 0, height = 0;
    std::vector<uint8_t> rgb;
    const uint8_t* at(int x, int y) const { return &rgb[(size_t(y) * size_t(width) + size_t(x)) * 3]; }
};

// The viewer's clear colour (0.16, 0.17, 0.19) in 8 bits.
bool isBackground(const uint8_t* p)
{
    return std::abs(p[0] - 41) <= 2 && std::abs(p[1] - 43) <= 2 && std::abs(p[2] - 48) <= 2;
}

Image shoot(const std::string& file, const std::string& flags, const std::string& out)
{
    const test::CommandResult r = test::runCommand(std::string(STRATA_VIEW_EXE) + " '" + file +
                                                   "' --headless --no-grid --size 320x240 " + flags +
                                                   " --screenshot '" + out + "'");
    EXPECT_EQ(r.code, 0) << r.output;
    Image img;
    EXPECT_TRUE(io::readPngRgb(out, &img.width, &img.height, &img.rgb).isOk()) << out;
    return img;
}

struct Coverage {
    double fraction = 0.0;
    int x0 = 1 << 30, y0 = 1 << 30, x1 = -1, y1 = -1;
};

Coverage coverage(const Image& img)
{
    Coverage c;
    size_t n = 0;
    for (int y = 0; y < img.height; ++y)
        for (int x = 0; x < img.width; ++x)
            if (!isBackground(img.at(x, y))) {
                ++n;
                c.x0 = std::min(c.x0, x);
                c.y0 = std::min(c.y0, y);
                c.x1 = std::max(c.x1, x);
                c.y1 = std::max(c.y1, y);
            }
    c.fraction = double(n) / double(img.width * img.height);
    return c;
}

void expectInFrame(const Image& img, const std::string& what)
{
    ASSERT_EQ(img.width, 320) << what;
    ASSERT_EQ(img.height, 240) << what;
    const Coverage c = coverage(img);
    EXPECT_GT(c.fraction, 0.05) << what << ": nearly blank";
    EXPECT_LT(c.fraction, 0.9) << what << ": fills the frame";
    // Framed: the model's box leaves a margin on every side.
    EXPECT_GT(c.x0, 0) << what;
    EXPECT_GT(c.y0, 0) << what;
    EXPECT_LT(c.x1, img.width - 1) << what;
    EXPECT_LT(c.y1, img.height - 1) << what;
}

// Mean absolute difference over a window, per channel, 0..255.
double meanDifference(const Image& a, const Image& b, int x0, int y0, int x1, int y1)
{
    double sum = 0.0;
    for (int y = y0; y < y1; ++y)
        for (int x = x0; x < x1; ++x)
            for (int k = 0; k < 3; ++k)
                sum += std::abs(int(a.at(x, y)[k]) - int(b.at(x, y)[k]));
    return sum / double(3 * (x1 - x0) * (y1 - y0));
}

}  // namespace

TEST(Viewer, BuiltInExampleScreenshotsShowTheDetail)
{
    const std::string dir = test::tempDir("viewer");
    const std::string rig = test::writeExampleRig(dir, "head");
    // Front view (yaw 0): the head faces +z, the nose is in the middle.
    const Image l0 = shoot(rig, "--level 0 --yaw 0 --pitch 0", dir + "/l0.png");
    const Image l4 = shoot(rig, "--level 4 --yaw 0 --pitch 0", dir + "/l4.png");
    const Image bare = shoot(rig, "--level 4 --yaw 0 --pitch 0 --no-displacement", dir + "/bare.png");
    expectInFrame(l0, "level 0");
    expectInFrame(l4, "level 4");
    expectInFrame(bare, "no displacement");
    // Levels differ over the model.
    const Coverage c = coverage(l4);
    EXPECT_GT(meanDifference(l0, l4, c.x0, c.y0, c.x1, c.y1), 2.0);
    // Displacement changes the centre of the face (the nose) strongly...
    const int cx = (c.x0 + c.x1) / 2, cy = (c.y0 + c.y1) / 2, r = (c.x1 - c.x0) / 8;
    EXPECT_GT(meanDifference(l4, bare, cx - r, cy - r, cx + r, cy + r), 8.0);
    // ...and nothing outside the model: the corners stay background.
    EXPECT_EQ(meanDifference(l4, bare, 0, 0, 20, 20), 0.0);
    EXPECT_EQ(meanDifference(l4, bare, 300, 220, 320, 240), 0.0);
    // The false-colour view is not the shaded one.
    const Image colour = shoot(rig, "--level 4 --yaw 0 --pitch 0 --color displacement", dir + "/colour.png");
    EXPECT_GT(meanDifference(l4, colour, c.x0, c.y0, c.x1, c.y1), 10.0);
}

// --adaptive: the same silhouette as the uniform finest level, far fewer
// vertices (printed), several levels in false colour, and with level colours
// off a shaded image close to the uniform one.
TEST(Viewer, AdaptiveModeDrawsTheSameHeadWithFewerVertices)
{
    const std::string dir = test::tempDir("viewer_adaptive");
    const std::string rig = test::writeExampleRig(dir, "head");
    // Both in the plain base colour (the adaptive draw's materials: FoxIsDrawnWithItsTexture).
    const Image uniform = shoot(rig, "--level 4 --yaw 0 --pitch 0 --no-materials", dir + "/uniform.png");
    const Image shaded =
        shoot(rig, "--level 4 --yaw 0 --pitch 0 --no-materials --adaptive --no-level-colours", dir + "/shaded.png");
    const test::CommandResult r =
        test::runCommand(std::string(STRATA_VIEW_EXE) + " '" + rig + "' --headless --no-grid --size 320x240 --level 4 "
                         "--yaw 0 --pitch 0 --adaptive --pixel-error 2 --screenshot '" + dir + "/levels.png'");
    ASSERT_EQ(r.code, 0) << r.output;
    const size_t at = r.output.find("adaptive within 2.00 px: ");
    ASSERT_NE(at, std::string::npos) << r.output;
    const long vertices = std::atol(r.output.c_str() + at + std::strlen("adaptive within 2.00 px: "));
    EXPECT_GT(vertices, 0) << r.output;
    EXPECT_LT(vertices, 2562 * 4) << r.output;  // level 4 everywhere: 20 * 4^5 / 2 + 2 = 10242
    Image levels;
    ASSERT_TRUE(io::readPngRgb(dir + "/levels.png", &levels.width, &levels.height, &levels.rgb).isOk());
    expectInFrame(shaded, "adaptive shaded");
    const Coverage cu = coverage(uniform), ca = coverage(shaded);
    EXPECT_NEAR(ca.fraction, cu.fraction, 0.01);
    EXPECT_LT(meanDifference(uniform, shaded, cu.x0, cu.y0, cu.x1, cu.y1), 4.0);
    EXPECT_GT(meanDifference(shaded, levels, cu.x0, cu.y0, cu.x1, cu.y1), 10.0);
}

// glTF's base colour is linear (factor x sRGB-decoded texture x COLOR_0)
// and shown sRGB-coded.  Three ways to colour a sphere linear 0.5 grey (a
// factor, COLOR_0, a texture coded 188) draw alike; a sphere coloured by
// its factor and vertex colours together draws as its --control auto rig,
// whose one texture carries that colour, and not as it does grey.
// (strata-view drew COLOR_0 not at all and factors and textures each in
// its own space: the texture 60 levels from the factor; and no emission.)
TEST(Viewer, VertexColoursFactorsAndTexturesDrawAsGltfDefinesThem)
{
    const std::string dir = test::tempDir("viewer_vertex_colours");
    const auto shootSphere = [&](test::SphereColour how, const std::string& name, const std::string& flags = "") {
        EXPECT_TRUE(test::writeColouredSphere(dir + "/" + name + ".glb", how));
        return shoot(dir + "/" + name + ".glb", flags, dir + "/" + name + ".png");
    };
    const Image factor = shootSphere(test::SphereColour::HalfFactor, "factor");
    const Image vertex = shootSphere(test::SphereColour::HalfVertexColour, "vertex");
    const Image texture = shootSphere(test::SphereColour::HalfTexture, "texture");
    const Coverage c = coverage(factor);
    ASSERT_GT(c.fraction, 0.05);
    const auto middle = [&](const Image& a, const Image& b) {  // the disc's middle half, away from its silhouette
        const int w = (c.x1 - c.x0) / 4, h = (c.y1 - c.y0) / 4;
        return meanDifference(a, b, c.x0 + w, c.y0 + h, c.x1 - w, c.y1 - h);
    };
    EXPECT_LT(middle(factor, vertex), 0.5);
    EXPECT_LT(middle(factor, texture), 0.5);

    // dir/STEM.glb, a sphere coloured as `how` says, and its --control auto
    // rig, dir/STEM_rig.glb.
    const auto sphereAndRig = [&](test::SphereColour how, const std::string& stem) {
        EXPECT_TRUE(test::writeColouredSphere(dir + "/" + stem + ".glb", how));
        const test::CommandResult bake = test::runCommand(std::string(STRATA_BAKE_EXE) + " --high '" + dir + "/" +
                                                          stem + ".glb' --control auto -o '" + dir + "/" + stem +
                                                          "_rig.glb'");
        EXPECT_EQ(bake.code, 0) << bake.output;
    };
    sphereAndRig(test::SphereColour::VertexAndFactor, "sphere");
    const Image source = shoot(dir + "/sphere.glb", "", dir + "/source.png");
    const Image rig = shoot(dir + "/sphere_rig.glb", "", dir + "/rig.png");
    const Image grey = shoot(dir + "/sphere.glb", "--no-materials", dir + "/grey.png");
    EXPECT_LT(middle(source, rig), 3.0);
    EXPECT_GT(middle(source, grey), 10.0);

    // Emission, added to the lit colour: the sphere whose bottom glows
    // orange by its material's factor draws as its rig, which glows by an
    // emissive texture, and both glow (red well over blue) over a tenth of
    // the disc's box (18% from this camera, which looks down on it).
    sphereAndRig(test::SphereColour::TwoMaterials, "two");
    const Image two = shoot(dir + "/two.glb", "", dir + "/two.png");
    const Image twoRig = shoot(dir + "/two_rig.glb", "", dir + "/two_rig.png");
    const auto glowing = [&](const Image& img) {
        size_t n = 0, disc = 0;
        for (int y = c.y0; y <= c.y1; ++y)
            for (int x = c.x0; x <= c.x1; ++x) {
                const uint8_t* p = img.at(x, y);
                if (isBackground(p))
                    continue;
                ++disc;
                n += p[0] > 200 && p[0] > p[2] + 120;
            }
        return disc ? double(n) / double(disc) : 0.0;
    };
    EXPECT_GT(glowing(two), 0.1);
    EXPECT_GT(glowing(twoRig), 0.1);
    EXPECT_LT(middle(two, twoRig), 4.0);

    // An emissive texture on TEXCOORD_1 (a ramp along x): the sphere draws
    // as its rig, which carries the ramp through its one UV set, refined
    // uniformly and adaptively.  (strata-view read it through the base
    // colour's UVs, one texel of the ramp everywhere: 5 levels off.)
    sphereAndRig(test::SphereColour::SecondUVSet, "second");
    const Image second = shoot(dir + "/second.glb", "", dir + "/second.png");
    const Image secondAdaptive = shoot(dir + "/second.glb", "--adaptive --no-level-colours", dir + "/second_lod.png");
    const Image secondRig = shoot(dir + "/second_rig.glb", "", dir + "/second_rig.png");
    EXPECT_LT(middle(second, secondRig), 3.0);
    EXPECT_LT(middle(secondAdaptive, secondRig), 3.0);
    std::printf("vertex %.2f texture %.2f rig %.2f grey %.2f second set %.2f (adaptive %.2f)\n",
                middle(factor, vertex), middle(factor, texture), middle(source, rig), middle(source, grey),
                middle(second, secondRig), middle(secondAdaptive, secondRig));
}

// glTF's normal textures turn the shading normal in a frame derived per
// pixel (+u, -v): the sphere whose normal texture tilts every normal 22
// degrees draws unlike the same sphere without it, and its --control auto
// rig, which carries the tilt in a normal texture of its own, draws like
// the source.  (strata-view ignored normal textures, and the bake named
// them as not carried: the rig drew as the untilted sphere.)
TEST(Viewer, NormalTexturesTurnTheShadingAsGltfDefinesThem)
{
    const std::string dir = test::tempDir("viewer_normal_texture");
    ASSERT_TRUE(test::writeColouredSphere(dir + "/normal.glb", test::SphereColour::NormalTexture));
    tinygltf::TinyGLTF gltf;
    tinygltf::Model model;
    std::string err, warn;
    ASSERT_TRUE(gltf.LoadBinaryFromFile(&model, &err, &warn, dir + "/normal.glb")) << err;
    ASSERT_GE(model.materials[0].normalTexture.index, 0);
    model.materials[0].normalTexture.index = -1;
    ASSERT_TRUE(gltf.WriteGltfSceneToFile(&model, dir + "/plain.glb", true, true, false, true));
    const test::CommandResult bake = test::runCommand(std::string(STRATA_BAKE_EXE) + " --high '" + dir +
                                                      "/normal.glb' --control auto -o '" + dir + "/rig.glb'");
    ASSERT_EQ(bake.code, 0) << bake.output;
    const Image source = shoot(dir + "/normal.glb", "", dir + "/normal.png");
    const Image plain = shoot(dir + "/plain.glb", "", dir + "/plain.png");
    const Image rig = shoot(dir + "/rig.glb", "", dir + "/rig.png");
    const Image rigAdaptive = shoot(dir + "/rig.glb", "--adaptive --no-level-colours", dir + "/rig_lod.png");
    const Coverage c = coverage(source);
    ASSERT_GT(c.fraction, 0.05);
    const int w = (c.x1 - c.x0) / 4, h = (c.y1 - c.y0) / 4;  // the disc's middle half
    const auto middle = [&](const Image& a, const Image& b) {
        return meanDifference(a, b, c.x0 + w, c.y0 + h, c.x1 - w, c.y1 - h);
    };
    std::printf("normal texture against none %.2f, rig %.2f (adaptive %.2f)\n", middle(source, plain),
                middle(source, rig), middle(source, rigAdaptive));
    EXPECT_GT(middle(source, plain), 4.0);
    EXPECT_LT(middle(source, rig), 2.0);
    EXPECT_LT(middle(source, rigAdaptive), 2.5);

    // Without NORMAL glTF draws the sphere faceted, its normal texture about
    // each face's own normal; so does the rig (the layer's flat shading),
    // its normal texture written about its triangles' normals.  The tilt
    // drawn wrong or not at all would show as above (6 levels); the facets
    // themselves are small here.
    for (tinygltf::Primitive& p : model.meshes[0].primitives)
        p.attributes.erase("NORMAL");
    model.materials[0].normalTexture.index = 1;
    ASSERT_TRUE(gltf.WriteGltfSceneToFile(&model, dir + "/faceted.glb", true, true, false, true));
    const test::CommandResult flatBake = test::runCommand(std::string(STRATA_BAKE_EXE) + " --high '" + dir +
                                                          "/faceted.glb' --control auto -o '" + dir + "/flat_rig.glb'");
    ASSERT_EQ(flatBake.code, 0) << flatBake.output;
    const Image faceted = shoot(dir + "/faceted.glb", "", dir + "/faceted.png");
    const Image flatRig = shoot(dir + "/flat_rig.glb", "", dir + "/flat_rig.png");
    std::printf("faceted: rig %.2f, against the smooth source %.2f\n", middle(faceted, flatRig),
                middle(faceted, source));
    EXPECT_LT(middle(faceted, flatRig), 2.5);
}

// glTF's metallic-roughness model: one sphere of linear 0.5 grey drawn as
// a rough dielectric (metallic 0), a rough metal (glTF's default, 1) and a
// smooth metal (roughness 0.2).  The dielectric's diffuse light makes it
// brighter than the rough metal, whose grey tints only its reflections;
// the smooth metal gathers the key light into a small highlight, brighter
// than anything on the rough one.  (strata-view drew all three alike.)
TEST(Viewer, MetallicAndRoughnessShadeAsGltfDefinesThem)
{
    const std::string dir = test::tempDir("viewer_metallic_roughness");
    ASSERT_TRUE(test::writeColouredSphere(dir + "/metal.glb", test::SphereColour::HalfFactor));
    tinygltf::TinyGLTF gltf;
    tinygltf::Model model;
    std::string err, warn;
    ASSERT_TRUE(gltf.LoadBinaryFromFile(&model, &err, &warn, dir + "/metal.glb")) << err;
    ASSERT_EQ(model.materials[0].pbrMetallicRoughness.metallicFactor, 1.0);
    model.materials[0].pbrMetallicRoughness.metallicFactor = 0.0;
    ASSERT_TRUE(gltf.WriteGltfSceneToFile(&model, dir + "/dielectric.glb", true, true, false, true));
    model.materials[0].pbrMetallicRoughness.metallicFactor = 1.0;
    model.materials[0].pbrMetallicRoughness.roughnessFactor = 0.2;
    ASSERT_TRUE(gltf.WriteGltfSceneToFile(&model, dir + "/smooth.glb", true, true, false, true));
    const Image metal = shoot(dir + "/metal.glb", "", dir + "/metal.png");
    const Image dielectric = shoot(dir + "/dielectric.glb", "", dir + "/dielectric.png");
    const Image smooth = shoot(dir + "/smooth.glb", "", dir + "/smooth.png");
    const Coverage c = coverage(dielectric);
    ASSERT_GT(c.fraction, 0.05);
    // Mean and brightest grey over the disc (its pixels in any of the three).
    const auto grey = [&](const Image& img, double* mean, int* brightest) {
        double sum = 0.0;
        size_t n = 0;
        *brightest = 0;
        for (int y = c.y0; y <= c.y1; ++y)
            for (int x = c.x0; x <= c.x1; ++x) {
                const uint8_t* p = img.at(x, y);
                if (isBackground(p))
                    continue;
                sum += (p[0] + p[1] + p[2]) / 3.0;
                *brightest = std::max(*brightest, (p[0] + p[1] + p[2]) / 3);
                ++n;
            }
        *mean = n ? sum / double(n) : 0.0;
    };
    double meanMetal, meanDielectric, meanSmooth;
    int topMetal, topDielectric, topSmooth;
    grey(metal, &meanMetal, &topMetal);
    grey(dielectric, &meanDielectric, &topDielectric);
    grey(smooth, &meanSmooth, &topSmooth);
    std::printf("mean / brightest: dielectric %.1f / %d, rough metal %.1f / %d, smooth metal %.1f / %d\n",
                meanDielectric, topDielectric, meanMetal, topMetal, meanSmooth, topSmooth);
    EXPECT_GT(meanDielectric, meanMetal + 20.0);
    EXPECT_GT(topSmooth, topMetal + 40);
    EXPECT_GT(meanDifference(metal, smooth, c.x0, c.y0, c.x1, c.y1), 5.0);
}

TEST(Viewer, BadFileIsAOneLineErrorAndNoImage)
{
    const std::string dir = test::tempDir("viewer_bad");
    test::writeText(dir + "/broken.glb", "glTF this is not");
    const test::CommandResult r = test::runCommand(std::string(STRATA_VIEW_EXE) + " " + dir +
                                                   "/broken.glb --headless --screenshot " + dir + "/out.png");
    EXPECT_EQ(r.code, 2) << r.output;
    EXPECT_NE(r.output.find("broken.glb"), std::string::npos) << r.output;
    EXPECT_NE(r.output.find("strata-view: error: "), std::string::npos) << r.output;
    EXPECT_FALSE(test::fileExists(dir + "/out.png"));
}

// A pose that overflows (two nested joints scaled by 1e20) is refused, not
// drawn as NaNs or as the last pose: one line naming the joint, no image.
TEST(Viewer, OverflowingPoseIsAnErrorNamingTheJoint)
{
    Rig rig;
    DisplacementMap map;
    test::makeBendingExampleRig(&rig, &map);
    rig.skeleton.animations.push_back(test::overflowingAnimation());
    const std::string dir = test::tempDir("viewer_overflow");
    ASSERT_TRUE(io::saveRig(dir + "/huge.glb", rig, &map).isOk());
    const test::CommandResult r = test::runCommand(std::string(STRATA_VIEW_EXE) + " " + dir +
                                                   "/huge.glb --anim grow --time 0.5 --headless --screenshot " + dir +
                                                   "/out.png");
    EXPECT_EQ(r.code, 2) << r.output;
    EXPECT_NE(r.output.find("is not finite"), std::string::npos) << r.output;
    EXPECT_NE(r.output.find("(node 1 \"chest\")"), std::string::npos) << r.output;
    EXPECT_FALSE(test::fileExists(dir + "/out.png"));
}

TEST(Viewer, WindowedScreenshotUnderXvfb)
{
    // xvfb-run and xauth come with cmake/install-deps.sh.
    ASSERT_EQ(test::runCommand("command -v xvfb-run").code, 0) << "xvfb-run is not installed";
    const std::string dir = test::tempDir("viewer_window");
    const std::string rig = test::writeExampleRig(dir, "head");
    const test::CommandResult r =
        test::runCommand("env -u WAYLAND_DISPLAY xvfb-run -a -s '-screen 0 640x480x24' " + std::string(STRATA_VIEW_EXE) +
                         " " + rig + " --no-grid --size 640x480 --screenshot " + dir + "/window.png");
    ASSERT_EQ(r.code, 0) << r.output;
    Image img;
    ASSERT_TRUE(io::readPngRgb(dir + "/window.png", &img.width, &img.height, &img.rgb).isOk());
    ASSERT_EQ(img.width, 640);
    // The panel sits top left; the model is drawn around the centre and
    // does not reach the bottom-right corner.
    size_t model = 0;
    for (int y = 280; y < 340; ++y)
        for (int x = 300; x < 420; ++x)
            model += isBackground(img.at(x, y)) ? 0 : 1;
    EXPECT_GT(model, 5000u);
    EXPECT_TRUE(isBackground(img.at(639, 479)));
}

TEST(ViewerRealData, FoxPlaysAndIsFramed)
{
    STRATA_REQUIRE_DATA(fox, "Fox.glb");
    const std::string dir = test::tempDir("viewer_fox");
    const Image a = shoot(fox, "--anim Run --time 0.1", dir + "/a.png");
    const Image b = shoot(fox, "--anim Run --time 0.4", dir + "/b.png");
    expectInFrame(a, "Fox t 0.1");
    expectInFrame(b, "Fox t 0.4");
    EXPECT_GT(meanDifference(a, b, 0, 0, 320, 240), 0.5);  // it moved
}

TEST(ViewerRealData, FoxIsDrawnWithItsTexture)
{
    STRATA_REQUIRE_DATA(fox, "Fox.glb");
    const std::string dir = test::tempDir("viewer_fox_texture");
    const Image textured = shoot(fox, "", dir + "/textured.png");
    const Image grey = shoot(fox, "--no-materials", dir + "/grey.png");
    // Fox's texture is orange fur with white and dark patches: count model
    // pixels whose red clearly exceeds blue.  Flat grey has none.
    auto orange = [](const Image& img) {
        size_t n = 0, model = 0;
        for (int y = 0; y < img.height; ++y)
            for (int x = 0; x < img.width; ++x) {
                const uint8_t* p = img.at(x, y);
                if (isBackground(p))
                    continue;
                ++model;
                n += p[0] > p[2] + 60 && p[0] > p[1] + 20;
            }
        return model ? double(n) / double(model) : 0.0;
    };
    EXPECT_GT(orange(textured), 0.4);
    EXPECT_LT(orange(grey), 0.01);
    // The adaptive draw too, at mixed levels of the smooth surface: the same
    // fur, the same place on screen as the uniform draw of its finest level.
    const Image uniform = shoot(fox, "--level 3 --scheme smooth", dir + "/uniform.png");
    const test::CommandResult r =
        test::runCommand(std::string(STRATA_VIEW_EXE) + " '" + fox + "' --headless --no-grid --size 320x240 --level 3 "
                         "--scheme smooth --adaptive --no-level-colours --screenshot '" + dir + "/adaptive.png'");
    ASSERT_EQ(r.code, 0) << r.output;
    EXPECT_NE(r.output.find("levels 0..2"), std::string::npos) << r.output;
    Image adaptive;
    ASSERT_TRUE(io::readPngRgb(dir + "/adaptive.png", &adaptive.width, &adaptive.height, &adaptive.rgb).isOk());
    EXPECT_GT(orange(adaptive), 0.4);
    const Coverage cu = coverage(uniform), ca = coverage(adaptive);
    EXPECT_NEAR(ca.fraction, cu.fraction, 0.01);
    EXPECT_LT(meanDifference(uniform, adaptive, cu.x0, cu.y0, cu.x1, cu.y1), 8.0);
}

// glTF draws a primitive without NORMAL with face normals.  Fox has none:
// refined on its flat triangles (linear scheme), each pixel's shade depends
// on its triangle's plane alone, so level 2 draws as level 0 does.
// CesiumMan has normals and is drawn smooth: the shading normals of its
// refined vertices change with the level, and so does the picture.
TEST(ViewerRealData, APrimitiveWithoutNormalsIsShadedFlat)
{
    STRATA_REQUIRE_DATA(fox, "Fox.glb");
    STRATA_REQUIRE_DATA(man, "CesiumMan.glb");
    const std::string dir = test::tempDir("viewer_flat");
    const Image fox0 = shoot(fox, "--level 0", dir + "/fox0.png");
    const Image fox2 = shoot(fox, "--level 2 --scheme linear", dir + "/fox2.png");
    const Image man0 = shoot(man, "--level 0", dir + "/man0.png");
    const Image man2 = shoot(man, "--level 2 --scheme linear", dir + "/man2.png");
    EXPECT_LT(meanDifference(fox0, fox2, 0, 0, 320, 240), 0.05);
    EXPECT_GT(meanDifference(man0, man2, 0, 0, 320, 240), 0.2);
}

TEST(ViewerRealData, CesiumManIsFramedStandingOnTheGrid)
{
    STRATA_REQUIRE_DATA(man, "CesiumMan.glb");
    const std::string dir = test::tempDir("viewer_cesium_frame");
    // --time alone plays animation 0; the posed figure is framed whole at
    // any aspect ratio.
    for (const char* size : {"320x240", "240x320"}) {
        const test::CommandResult r =
            test::runCommand(std::string(STRATA_VIEW_EXE) + " '" + man + "' --headless --no-grid --time 0.5 --size " +
                             size + " --screenshot '" + dir + "/man.png'");
        ASSERT_EQ(r.code, 0) << r.output;
        Image img;
        ASSERT_TRUE(io::readPngRgb(dir + "/man.png", &img.width, &img.height, &img.rgb).isOk());
        const Coverage c = coverage(img);
        EXPECT_GT(c.fraction, 0.03) << size;
        EXPECT_GT(c.x0, 0) << size;
        EXPECT_GT(c.y0, 0) << size << ": the head is cut off";
        EXPECT_LT(c.x1, img.width - 1) << size;
        EXPECT_LT(c.y1, img.height - 1) << size;
    }
}
