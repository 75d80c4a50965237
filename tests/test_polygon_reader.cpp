// The bounded PLY / OFF / STL reader: one cube in every encoding reads the
// same, and hostile headers (counts beyond the file, huge lists, bad
// indices, truncation, NaN) are one clear error each, without allocating
// what the header claims.
#include "strata/io/mesh_io.h"
#include "test_util.h"

#include <cstring>

using namespace strata;

namespace {

const float kCube[8][3] = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}, {0, 0, 1}, {1, 0, 1}, {1, 1, 1}, {0, 1, 1}};
const int kQuads[6][4] = {{0, 3, 2, 1}, {4, 5, 6, 7}, {0, 1, 5, 4}, {2, 3, 7, 6}, {1, 2, 6, 5}, {0, 4, 7, 3}};

template <typename T>
void put(std::string& s, T v, bool big)
{
    char b[sizeof(T)];
    std::memcpy(b, &v, sizeof(T));
    if (big)
        for (size_t i = 0; i < sizeof(T) / 2; ++i)
            std::swap(b[i], b[sizeof(T) - 1 - i]);
    s.append(b, sizeof(T));
}

// A cube as PLY: a colour byte before x, double coordinates, ushort-counted
// int indices named vertex_index, an extra element after the faces.
std::string plyCube(const std::string& format)
{
    std::string s = "ply\nformat " + format + " 1.0\ncomment a cube\nelement vertex 8\nproperty uchar red\n"
                    "property double z\nproperty double x\nproperty double y\nelement face 6\n"
                    "property list ushort int vertex_index\nelement extra 1\nproperty list uchar float junk\nend_header\n";
    const bool ascii = format == "ascii", big = format == "binary_big_endian";
    for (const auto& p : kCube) {
        if (ascii) {
            s += "200 " + std::to_string(p[2]) + " " + std::to_string(p[0]) + " " + std::to_string(p[1]) + "\n";
        } else {
            put<uint8_t>(s, 200, big);
            put<double>(s, p[2], big);
            put<double>(s, p[0], big);
            put<double>(s, p[1], big);
        }
    }
    for (const auto& q : kQuads) {
        if (ascii) {
            s += "4 " + std::to_string(q[0]) + " " + std::to_string(q[1]) + " " + std::to_string(q[2]) + " " +
                 std::to_string(q[3]) + "\n";
        } else {
            put<uint16_t>(s, 4, big);
            for (int k = 0; k < 4; ++k)
                put<int32_t>(s, q[k], big);
        }
    }
    if (ascii) {
        s += "2 0.5 0.25\n";
    } else {
        put<uint8_t>(s, 2, big);
        put<float>(s, 0.5f, big);
        put<float>(s, 0.25f, big);
    }
    return s;
}

// The layout most scanners write (the reader's fast path): float x, y, z
// with another float after them, uchar-counted 32-bit indices; the first face
// a quad, the others split into triangles.
std::string plyScannerCube(const std::string& indexType)
{
    std::string s = "ply\nformat binary_little_endian 1.0\nelement vertex 8\nproperty float x\nproperty float y\n"
                    "property float z\nproperty float confidence\nelement face 11\nproperty list uchar " +
                    indexType + " vertex_indices\nend_header\n";
    for (const auto& p : kCube) {
        for (int a = 0; a < 3; ++a)
            put<float>(s, float(p[a]), false);
        put<float>(s, 0.5f, false);
    }
    for (size_t f = 0; f < std::size(kQuads); ++f) {
        const auto& q = kQuads[f];
        if (f == 0) {
            put<uint8_t>(s, 4, false);
            for (int k = 0; k < 4; ++k)
                put<int32_t>(s, q[k], false);
            continue;
        }
        for (int t = 0; t < 2; ++t) {
            put<uint8_t>(s, 3, false);
            for (int c : {q[0], q[1 + t], q[2 + t]})
                put<int32_t>(s, c, false);
        }
    }
    return s;
}

std::string offCube()
{
    std::string s = "OFF\n# a cube\n8 6 0\n";
    for (const auto& p : kCube)
        s += std::to_string(p[0]) + " " + std::to_string(p[1]) + " " + std::to_string(p[2]) + "\n";
    for (const auto& q : kQuads)
        s += "4 " + std::to_string(q[0]) + " " + std::to_string(q[1]) + " " + std::to_string(q[2]) + " " +
             std::to_string(q[3]) + " 255 0 0\n";
    return s;
}

std::string stlCube(bool binary)
{
    std::string s = binary ? std::string(80, ' ') : "solid cube\n";
    if (binary)
        put<uint32_t>(s, 12, false);
    for (const auto& q : kQuads)
        for (int t = 0; t < 2; ++t) {
            const int c[3] = {q[0], q[1 + t], q[2 + t]};
            if (binary) {
                for (int k = 0; k < 3; ++k)
                    put<float>(s, 0.0f, false);
                for (int k = 0; k < 3; ++k)
                    for (int a = 0; a < 3; ++a)
                        put<float>(s, kCube[c[k]][a], false);
                put<uint16_t>(s, 0, false);
            } else {
                s += "facet normal 0 0 0\nouter loop\n";
                for (int k = 0; k < 3; ++k)
                    s += "vertex " + std::to_string(kCube[c[k]][0]) + " " + std::to_string(kCube[c[k]][1]) + " " +
                         std::to_string(kCube[c[k]][2]) + "\n";
                s += "endloop\nendfacet\n";
            }
        }
    if (!binary)
        s += "endsolid cube\n";
    return s;
}

void expectCube(const io::PolygonMesh& m, const std::string& what)
{
    ASSERT_EQ(m.positions.size(), 8u) << what;
    ASSERT_EQ(m.triangles.size(), 36u) << what;
    // Every triangle of the cube has area 1/2 and lies on a face of the unit cube.
    double area = 0.0;
    for (size_t t = 0; t < 36; t += 3) {
        const glm::vec3 a = m.positions[m.triangles[t]], b = m.positions[m.triangles[t + 1]],
                        c = m.positions[m.triangles[t + 2]];
        area += 0.5 * double(glm::length(glm::cross(b - a, c - a)));
    }
    EXPECT_NEAR(area, 6.0, 1e-6) << what;
    const MeshTopologyStats s = computeTopologyStats(m.triangles.data(), m.triangles.size() / 3);
    EXPECT_EQ(s.boundaryEdges, 0u) << what;
    EXPECT_EQ(s.eulerCharacteristic, 2) << what;
}

}  // namespace

TEST(PolygonReader, OneCubeInEveryEncoding)
{
    const std::string dir = test::tempDir("polygon_reader");
    const std::pair<std::string, std::string> files[] = {
        {"ascii.ply", plyCube("ascii")},         {"little.ply", plyCube("binary_little_endian")},
        {"big.ply", plyCube("binary_big_endian")}, {"scanner_int.ply", plyScannerCube("int")},
        {"scanner_uint.ply", plyScannerCube("uint")}, {"cube.off", offCube()},
        {"binary.stl", stlCube(true)},          {"ascii.stl", stlCube(false)}};
    for (const auto& [name, text] : files) {
        test::writeText(dir + "/" + name, text);
        io::PolygonMesh m;
        const Status st = io::readPolygonMesh(dir + "/" + name, &m);
        ASSERT_TRUE(st.isOk()) << name << ": " << st.message();
        expectCube(m, name);
        if (name.find("scanner") != std::string::npos) {
            EXPECT_EQ(m.polygonsTriangulated, 1u) << name;
        } else if (name.find(".stl") == std::string::npos) {
            EXPECT_EQ(m.polygonsTriangulated, 6u) << name;
        }
    }
}

TEST(PolygonReader, HostileFilesAreOneClearError)
{
    const std::string dir = test::tempDir("polygon_reader_bad");
    std::string hugeList = "ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                           "property float z\nelement face 1\nproperty list uint int vertex_indices\nend_header\n";
    hugeList += std::string(36, '\0');
    put<uint32_t>(hugeList, 70000, false);
    const std::string ascii = plyCube("ascii");
    const std::string little = plyCube("binary_little_endian");
    const std::string scanner = plyScannerCube("int");
    const size_t faces = scanner.find("end_header\n") + 11 + 8 * 16;  // the first face's count byte
    std::string badIndex = scanner, nanVertex = scanner, twoCorners = scanner;
    badIndex.replace(faces + 1 + 16 + 1 + 8, 4, std::string("\x08\x00\x00\x00", 4));  // vertex 8 of 8
    nanVertex.replace(faces - 16, 4, std::string("\x00\x00\xc0\x7f", 4));            // x of vertex 7: NaN
    twoCorners[faces + 17] = 2;                                                          // the second face
    const std::pair<std::string, std::string> cases[] = {
        {"scanner_index.ply", badIndex},
        {"scanner_nan.ply", nanVertex},
        {"scanner_two.ply", twoCorners},
        {"scanner_truncated.ply", scanner.substr(0, scanner.size() - 6)},
        {"count.ply", "ply\nformat binary_little_endian 1.0\nelement vertex 2147483648\nproperty float x\n"
                      "property float y\nproperty float z\nend_header\n0000"},
        {"list.ply", hugeList},
        {"index.ply", ascii.substr(0, ascii.find("4 0 3 2 1")) + "3 0 1 99\n"},
        {"truncated.ply", little.substr(0, little.size() / 2)},
        {"keyword.ply", "ply\nformat ascii 1.0\nbogus line\nend_header\n"},
        {"noxyz.ply", "ply\nformat ascii 1.0\nelement vertex 1\nproperty float u\nend_header\n1\n"},
        {"nan.ply", "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
                    "element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\nnan 0 0\n0 1 0\n3 0 1 2\n"},
        {"noheader.ply", "ply\nformat ascii 1.0\n"},
        {"counts.off", "OFF\n1000000000 1000000000 0\n0 0 0\n"},
        {"negative.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 -1\n"},
        {"variant.off", "COFF\n3 1 0\n0 0 0 1 1 1 1\n"},
        {"short.stl", std::string(100, 'x')},
        {"partial.stl", "solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nendloop\nendfacet\n"},
        {"empty.ply", ""},
    };
    for (const auto& [name, text] : cases) {
        test::writeText(dir + "/" + name, text);
        io::PolygonMesh m;
        const Status st = io::readPolygonMesh(dir + "/" + name, &m);
        EXPECT_FALSE(st.isOk()) << name;
        EXPECT_NE(st.message().find(name), std::string::npos) << st.message();
        EXPECT_EQ(st.message().find('\n'), std::string::npos) << st.message();
    }
}

// Vertex colours as scanners and MeshLab write them: a PLY's red, green and
// blue (uchar, ushort or float; alpha optional) and an OBJ's "v x y z r g b"
// (0..1, or 0..255 where any value passes 1), sRGB-coded, read as linear
// RGBA (code 188 of 255 is 0.5029, 128 is 0.2158).  A lone red is no colour.
TEST(PolygonReader, VertexColoursReadAsLinear)
{
    const std::string dir = test::tempDir("polygon_reader_colours");
    const double l188 = 0.5028864580325687, l128 = 0.21586050011389926;
    for (const std::string format : {"ascii", "binary_little_endian", "binary_big_endian"}) {
        std::string s = "ply\nformat " + format + " 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                        "property float z\nproperty uchar red\nproperty uchar green\nproperty uchar blue\n"
                        "property float alpha\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n";
        const bool ascii = format == "ascii", big = format == "binary_big_endian";
        for (int v = 0; v < 3; ++v) {
            const float p[3] = {float(v == 1), float(v == 2), 0.0f};
            const uint8_t rgb[3] = {188, uint8_t(v == 0 ? 128 : 0), 255};
            if (ascii) {
                s += std::to_string(p[0]) + " " + std::to_string(p[1]) + " 0 188 " + std::to_string(rgb[1]) +
                     " 255 0.5\n";
            } else {
                for (float x : p)
                    put<float>(s, x, big);
                for (uint8_t c : rgb)
                    put<uint8_t>(s, c, big);
                put<float>(s, 0.5f, big);
            }
        }
        if (ascii) {
            s += "3 0 1 2\n";
        } else {
            put<uint8_t>(s, 3, big);
            for (int32_t i : {0, 1, 2})
                put<int32_t>(s, i, big);
        }
        test::writeText(dir + "/c.ply", s);
        io::PolygonMesh m;
        const Status st = io::readPolygonMesh(dir + "/c.ply", &m);
        ASSERT_TRUE(st.isOk()) << format << ": " << st.message();
        ASSERT_EQ(m.colours.size(), 3u) << format;
        EXPECT_NEAR(m.colours[0].r, l188, 1e-6) << format;
        EXPECT_NEAR(m.colours[0].g, l128, 1e-6) << format;
        EXPECT_EQ(m.colours[1].g, 0.0f) << format;
        EXPECT_NEAR(m.colours[2].b, 1.0, 1e-6) << format;
        EXPECT_EQ(m.colours[2].a, 0.5f) << format;
    }
    // A cube whose vertices carry red alone has no colours.
    test::writeText(dir + "/red.ply", plyCube("ascii"));
    io::PolygonMesh cube;
    ASSERT_TRUE(io::readPolygonMesh(dir + "/red.ply", &cube).isOk());
    EXPECT_TRUE(cube.colours.empty());

    // OBJ: 0..1, then 0..255; a vertex without a colour is white; four
    // numbers are a position and w, not a colour.
    for (const std::string& values : {std::string("0.737255 0.501961 1"), std::string("188 128 255")}) {
        test::writeText(dir + "/c.obj", "v 0 0 0 " + values + "\nv 1 0 0\nv 0 1 0 1\nf 1 2 3\n");
        ControlMesh mesh;
        io::ObjReadInfo info;
        ASSERT_TRUE(io::readObj(dir + "/c.obj", &mesh, &info).isOk()) << values;
        ASSERT_EQ(info.colours.size(), 3u) << values;
        EXPECT_NEAR(info.colours[0].r, l188, 1e-4) << values;
        EXPECT_NEAR(info.colours[0].g, l128, 1e-4) << values;
        EXPECT_NEAR(info.colours[0].b, 1.0, 1e-6) << values;
        EXPECT_EQ(info.colours[0].a, 1.0f) << values;
        EXPECT_EQ(info.colours[1], glm::vec4(1.0f)) << values;
        EXPECT_EQ(info.colours[2], glm::vec4(1.0f)) << values;
    }
    test::writeText(dir + "/plain.obj", "v 0 0 0 1\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
    ControlMesh mesh;
    io::ObjReadInfo info;
    ASSERT_TRUE(io::readObj(dir + "/plain.obj", &mesh, &info).isOk());
    EXPECT_TRUE(info.colours.empty());
}
