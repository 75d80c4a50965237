// Rigs several tests share: the built-in example, the baked penguin, and
// the watertightness check of an animated reconstruction.
#pragma once

#include "procedural.h"
#include "strata/baker/atlas.h"
#include "strata/baker/bake.h"
#include "strata/baker/mesh_input.h"
#include "strata/io/exr.h"
#include "strata/io/reconstruct.h"
#include "strata/io/rig_io.h"
#include "test_util.h"

#include <string>

namespace strata {
namespace test {

/// The built-in example's rig: icosphere(1) with a per-triangle atlas and
/// the closed-form head map at mapSize^2.
inline void makeExampleRig(Rig* rig, DisplacementMap* map, int mapSize = 256)
{
    rig->mesh = examples::makeIcosphere(1);
    ASSERT_TRUE(baker::buildTriangleAtlas(&rig->mesh, {mapSize, 2}).isOk());
    ASSERT_TRUE(examples::bakeRadialSurface(map, rig->mesh, mapSize, 2, examples::headRadius).isOk());
    rig->hasDisplacement = true;
    rig->displacement.encoding = "exr";
    rig->displacement.width = rig->displacement.height = mapSize;
    rig->displacement.recommendedLevel = 4;
}

/// Writes the example rig as dir/stem.glb beside dir/stem.exr; returns the glb path.
inline std::string writeExampleRig(const std::string& dir, const std::string& stem, Rig* rigOut = nullptr)
{
    Rig rig;
    DisplacementMap map;
    makeExampleRig(&rig, &map);
    rig.displacement.uri = stem + ".exr";
    EXPECT_TRUE(io::writeDisplacementExr(dir + "/" + stem + ".exr", map).isOk());
    EXPECT_TRUE(io::saveRig(dir + "/" + stem + ".glb", rig).isOk());
    if (rigOut)
        *rigOut = rig;
    return dir + "/" + stem + ".glb";
}

/// The penguin pair baked at 512^2 (per-triangle atlas, linear scheme).
/// \pre ../shared/data holds penguin_hr.obj and penguin_control_mesh.obj
inline void bakePenguin(const std::string& highPath, const std::string& controlPath, Rig* rig, DisplacementMap* map)
{
    baker::TriangleMesh high;
    ASSERT_TRUE(baker::loadHighMesh(highPath, &high, nullptr).isOk());
    ASSERT_TRUE(baker::loadControlMesh(controlPath, &rig->mesh).isOk());
    ASSERT_TRUE(baker::buildTriangleAtlas(&rig->mesh, {512, 2}).isOk());
    baker::BakeOptions options;
    options.size = 512;
    ASSERT_TRUE(baker::bake(map, nullptr, nullptr, rig->mesh, high, options).isOk());
}

/// Writes rec as glb, loads it back welded by position, and checks it is as
/// closed as the control mesh: same Euler characteristic, no boundary, no
/// vertex merged or split.
inline void expectWatertightRoundTrip(const io::Reconstruction& rec, const MeshTopologyStats& control,
                                      const std::string& path, const std::string& label)
{
    ASSERT_TRUE(io::writeReconstruction(path, rec).isOk());
    Rig back;
    ASSERT_TRUE(io::loadRig(path, &back).isOk());
    const MeshTopologyStats st = computeTopologyStats(back.mesh.triangles.data(), back.mesh.faceCount());
    EXPECT_EQ(back.mesh.positions.size(), rec.positions.size()) << label;
    EXPECT_EQ(st.eulerCharacteristic, control.eulerCharacteristic) << label;
    EXPECT_EQ(st.boundaryEdges, 0u) << label;
}

}  // namespace test
}  // namespace strata
