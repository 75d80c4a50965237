// Colour into the cage's UVs.  A texel first finds its cage triangle (the
// UV triangles rasterised once, the first triangle over a texel keeping
// it), then its point on the capture, in parallel over texels.
#include "strata/baker/texture_transfer.h"

#include "parallel.h"
#include "strata/baker/dilate.h"
#include "strata/io/materials.h"
#include "strata/normals.h"
#include "strata/uv_raster.h"

#include <glm/geometric.hpp>

#include <algorithm>
#include <cmath>
#include <memory>

namespace strata {
namespace baker {

namespace {

// Per texel of a size x size image: the first of the UV triangles
// (uvIndex, 3 a triangle, into uvs) whose UVs cover its centre, or -1, and
// its barycentrics there.
void texelTriangles(const std::vector<glm::vec2>& uvs, const std::vector<uint32_t>& uvIndex, int size,
                    std::vector<int32_t>* faceOf, std::vector<glm::vec3>* baryOf)
{
    const size_t texels = size_t(size) * size_t(size);
    faceOf->assign(texels, -1);
    baryOf->assign(texels, glm::vec3(0.0f));
    for (size_t t = 0; 3 * t + 2 < uvIndex.size(); ++t) {
        const glm::vec2 uv[3] = {uvs[uvIndex[3 * t]], uvs[uvIndex[3 * t + 1]], uvs[uvIndex[3 * t + 2]]};
        forEachTexelInUVTriangle(uv, size, size, [&](int x, int y, double b0, double b1, double b2) {
            const size_t i = size_t(y) * size_t(size) + size_t(x);
            if ((*faceOf)[i] >= 0)
                return;  // the first triangle over a texel keeps it
            (*faceOf)[i] = int32_t(t);
            (*baryOf)[i] = glm::vec3(float(b0), float(b1), float(b2));
        });
    }
}

}  // namespace

Status transferColour(const ControlMesh& cage, const DisplacementMap& map, const TriangleIndex& capture,
                      const CaptureColour& colour, int size, ColorImage* out, int threads)
{
    if (!out)
        return Status(StatusCode::InvalidArgument, "transferColour: an output image is needed");
    std::vector<ColorImage> images;
    Status st = transferColours(cage, map, capture, {ColourLayer{colour, true}}, size, &images, threads);
    if (st)
        *out = std::move(images[0]);
    return st;
}

Status transferColours(const ControlMesh& cage, const DisplacementMap& map, const TriangleIndex& capture,
                       const std::vector<ColourLayer>& layers, int size, std::vector<ColorImage>* out, int threads)
{
    bool callable = !layers.empty();
    for (const ColourLayer& l : layers)
        callable = callable && bool(l.colour);
    if (!out || size <= 0 || size > 16384 || !cage.hasUVs() || !callable)
        return Status(StatusCode::InvalidArgument, "transferColours: a cage with UVs, colours and a size are needed");
    const size_t texels = size_t(size) * size_t(size);
    // Each texel's cage triangle and its barycentrics there.
    std::vector<int32_t> faceOf;
    std::vector<glm::vec3> baryOf;
    texelTriangles(cage.uvs, cage.uvIndices, size, &faceOf, &baryOf);
    std::vector<glm::vec3> normals(cage.vertexCount());
    computeControlNormals(normals.data(), cage.positions.data(), normals.size(), cage.triangles.data(),
                          cage.faceCount());
    const size_t nl = layers.size();
    std::vector<std::vector<float>> channel(4 * nl);  // layer l's channel k: 4 l + k
    for (std::vector<float>& c : channel)
        c.assign(texels, 0.0f);
    parallelFor(texels, threads, [&](size_t begin, size_t end) {
        int64_t hint = -1;
        for (size_t i = begin; i < end; ++i) {
            const int32_t f = faceOf[i];
            if (f < 0)
                continue;
            const glm::vec3 b = baryOf[i];
            glm::vec3 p(0.0f), n(0.0f);
            glm::vec2 uv(0.0f);
            for (int k = 0; k < 3; ++k) {
                const uint32_t v = cage.triangles[3 * size_t(f) + size_t(k)];
                p += b[k] * cage.positions[v];
                n += b[k] * normals[v];
                uv += b[k] * cage.uvs[cage.uvIndices[3 * size_t(f) + size_t(k)]];
            }
            const float d = map.texels.empty() ? 0.0f : sampleDisplacement(map, uv);
            const glm::dvec3 q(p + d * n);
            uint32_t face = 0;
            double b1 = 0.0, b2 = 0.0;
            if (capture.nearest(q, &face, &b1, &b2, hint) < 0.0)
                continue;
            hint = int64_t(face);
            for (size_t l = 0; l < nl; ++l) {
                const glm::vec4 c = glm::clamp(layers[l].colour(face, b1, b2), glm::vec4(0.0f), glm::vec4(1.0f));
                for (size_t k = 0; k < 4; ++k)
                    channel[4 * l + k][i] = c[int(k)];
            }
        }
    });
    // Gutters: each channel grown from the texels the triangles cover.
    std::vector<uint8_t> covered(texels);
    for (size_t i = 0; i < texels; ++i)
        covered[i] = faceOf[i] >= 0;
    out->assign(nl, ColorImage());
    for (size_t l = 0; l < nl; ++l) {
        ColorImage& image = (*out)[l];
        image.width = image.height = size;
        image.rgba.assign(texels * 4, 255);
        for (size_t k = 0; k < 4; ++k) {
            std::vector<float>& values = channel[4 * l + k];
            double mean = 0.0;
            size_t n = 0;
            for (size_t i = 0; i < texels; ++i)
                if (covered[i]) {
                    mean += values[i];
                    ++n;
                }
            std::vector<uint8_t> valid = covered;
            dilate(&values, &valid, size, 8, n ? float(mean / double(n)) : 1.0f, threads);
            // Colour channels sRGB-coded where the layer is a colour, as glTF
            // reads a base colour or emissive texture; alpha as it is.
            const bool coded = layers[l].srgb && k < 3;
            for (size_t i = 0; i < texels; ++i) {
                const double c = coded ? io::linearToSrgb(values[i]) : std::clamp(double(values[i]), 0.0, 1.0);
                image.rgba[4 * i + k] = uint8_t(std::lround(c * 255.0));
            }
            std::vector<float>().swap(values);
        }
    }
    return Status::ok();
}

Status transferNormals(const ControlMesh& cage, const DisplacementMap& map, Scheme scheme, int level, bool flat,
                       const TriangleIndex& capture, const CaptureNormal& normal, int size, ColorImage* out,
                       int threads)
{
    if (!out || size <= 0 || size > 16384 || !cage.hasUVs() || !normal)
        return Status(StatusCode::InvalidArgument, "transferNormals: a cage with UVs, normals and a size are needed");
    // The surface as drawn: refined, displaced, shaded by vertex normals.
    std::unique_ptr<Plan> plan;
    Status st = Plan::create(&plan, cage, scheme, level);
    if (st && !map.texels.empty())
        st = plan->setDisplacement(map);
    if (!st)
        return st;
    std::vector<glm::vec3> controlNormals(cage.vertexCount());
    computeControlNormals(controlNormals.data(), cage.positions.data(), controlNormals.size(), cage.triangles.data(),
                          cage.faceCount());
    const size_t nr = plan->refinedVertexCount();
    std::vector<glm::vec3> positions(nr), normals(nr);
    if (!(st = plan->evaluate(positions.data(), nullptr, 0, nr, cage.positions.data(), controlNormals.data(),
                              cage.vertexCount())))
        return st;
    plan->computeShadingNormals(normals.data(), positions.data());
    std::vector<glm::vec2> uvs;
    std::vector<uint32_t> uvIndex;
    plan->refinedUVs(&uvs, &uvIndex);
    const std::vector<uint32_t>& triangles = plan->refinedTriangles();
    const size_t texels = size_t(size) * size_t(size);
    std::vector<int32_t> faceOf;
    std::vector<glm::vec3> baryOf;
    texelTriangles(uvs, uvIndex, size, &faceOf, &baryOf);
    std::vector<std::vector<float>> channel(3, std::vector<float>(texels, 0.0f));
    std::vector<uint8_t> covered(texels, 0);  // a normal found (a frame, a capture point)
    parallelFor(texels, threads, [&](size_t begin, size_t end) {
        int64_t hint = -1;
        for (size_t i = begin; i < end; ++i) {
            const int32_t t = faceOf[i];
            if (t < 0)
                continue;
            glm::dvec3 p[3], q(0.0), n(0.0);
            glm::dvec2 uv[3];
            for (int k = 0; k < 3; ++k) {
                const uint32_t v = triangles[3 * size_t(t) + size_t(k)];
                p[k] = glm::dvec3(positions[v]);
                uv[k] = glm::dvec2(uvs[uvIndex[3 * size_t(t) + size_t(k)]]);
                q += double(baryOf[i][k]) * p[k];
                n += double(baryOf[i][k]) * glm::dvec3(normals[v]);
            }
            // The triangle's dP/du and dP/dv, from its edges in space and in UV.
            const glm::dvec3 e1 = p[1] - p[0], e2 = p[2] - p[0];
            glm::dvec3 dPdu, dPdv;
            if (!uvDerivatives(e1, e2, uv[1] - uv[0], uv[2] - uv[0], &dPdu, &dPdv))
                continue;
            if (flat) {
                const glm::dvec3 face = glm::cross(e1, e2);
                n = glm::dot(face, n) < 0.0 ? -face : face;
            }
            const double length = glm::length(n);
            if (!(length > 0.0))
                continue;
            n /= length;
            // The frame a viewer derives there (grad u, -grad v over the
            // longer, and n), and its dual basis to store a direction in.
            glm::dvec3 decodeX, decodeY, encodeX, encodeY;
            if (!normalTextureFrame(n, dPdu, dPdv, &decodeX, &decodeY, &encodeX, &encodeY))
                continue;
            uint32_t face = 0;
            double b1 = 0.0, b2 = 0.0;
            if (capture.nearest(q, &face, &b1, &b2, hint) < 0.0)
                continue;
            hint = int64_t(face);
            const glm::dvec3 s(normal(face, b1, b2));
            if (!(glm::dot(s, s) > 0.25))
                continue;  // no direction there: the gutters' fill
            // x X + y Y = s's part across n, X = grad u / m and Y = -grad v / m:
            // x = m (s . dP/du), y = -m (s . dP/dv), both in the plane.  Below
            // the surface is no direction a normal texture can hold.
            glm::dvec3 local(glm::dot(s, encodeX), glm::dot(s, encodeY), std::max(glm::dot(s, n), 0.02));
            local = glm::normalize(local);
            for (int k = 0; k < 3; ++k)
                channel[size_t(k)][i] = float(local[k]);
            covered[i] = 1;
        }
    });
    // Gutters grown from the texels found; (0, 0, 1) past them.
    out->width = out->height = size;
    out->rgba.assign(texels * 4, 255);
    for (size_t k = 0; k < 3; ++k) {
        std::vector<uint8_t> valid = covered;
        dilate(&channel[k], &valid, size, 8, k == 2 ? 1.0f : 0.0f, threads);
        for (size_t i = 0; i < texels; ++i) {
            const double coded = std::clamp(0.5 * double(channel[k][i]) + 0.5, 0.0, 1.0);
            out->rgba[4 * i + k] = uint8_t(std::lround(coded * 255.0));
        }
        std::vector<float>().swap(channel[k]);
    }
    return Status::ok();
}

}  // namespace baker
}  // namespace strata
