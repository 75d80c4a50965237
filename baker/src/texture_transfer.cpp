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

namespace strata {
namespace baker {

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
    std::vector<int32_t> faceOf(texels, -1);
    std::vector<glm::vec3> baryOf(texels);
    for (size_t f = 0; f < cage.faceCount(); ++f) {
        glm::vec2 uv[3];
        for (int k = 0; k < 3; ++k)
            uv[k] = cage.uvs[cage.uvIndices[3 * f + size_t(k)]];
        forEachTexelInUVTriangle(uv, size, size, [&](int x, int y, double b0, double b1, double b2) {
            const size_t i = size_t(y) * size_t(size) + size_t(x);
            if (faceOf[i] >= 0)
                return;  // the first triangle over a texel keeps it
            faceOf[i] = int32_t(f);
            baryOf[i] = glm::vec3(float(b0), float(b1), float(b2));
        });
    }
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

}  // namespace baker
}  // namespace strata
