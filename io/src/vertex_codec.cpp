// Residuals in subdivision order, zigzag-mapped to one byte when below 255
// (escape 255 + four bytes otherwise), then zstd.  Each level's residuals
// are their own zstd frame: coarse levels carry large corrections, fine
// levels small ones, and one entropy table per level codes both well.
#include "vertex_codec.h"

#include "strata/displacement_math.h"

#include <zstd.h>

#include <cmath>
#include <cstdint>
#include <utility>

namespace strata {
namespace io {

namespace {

uint32_t zigzag(int32_t v) { return (uint32_t(v) << 1) ^ uint32_t(v >> 31); }
int32_t unzigzag(uint32_t u) { return int32_t(u >> 1) ^ -int32_t(u & 1); }

constexpr int kZstdLevel = 19;

// The 32-bit little-endian words of the format: frame lengths and escaped residuals.
void putLength(std::string* out, uint32_t n)
{
    for (int k = 0; k < 4; ++k)
        out->push_back(char((n >> (8 * k)) & 0xff));
}

uint32_t getLength(const unsigned char* p)
{
    return uint32_t(p[0]) | uint32_t(p[1]) << 8 | uint32_t(p[2]) << 16 | uint32_t(p[3]) << 24;
}

}  // namespace

Status encodeVertexDisplacements(const ControlMesh& mesh, int level, const std::vector<float>& values, double step,
                                 std::string* bytes, float* factor, float* offset)
{
    SubdivisionParents h;
    if (Status st = buildSubdivisionParents(&h, mesh, level); !st)
        return st;
    const size_t n = h.levelCounts.back();
    if (values.size() != n)
        return Status(StatusCode::InvalidArgument, "vertex displacements: " + std::to_string(values.size()) +
                                                       " values for " + std::to_string(n) + " vertices");
    std::vector<int32_t> quantized, residuals(n);
    float q = 1.0f, dmin = 0.0f;
    if (Status st = quantizeDisplacements(values, step, &quantized, &q, &dmin); !st)
        return st;
    predictSubdivisionResiduals(h, quantized.data(), residuals.data());
    std::string out;
    size_t begin = 0;
    for (size_t l = 0; l < h.levelCounts.size(); ++l) {
        const size_t end = h.levelCounts[l];
        std::string raw;
        raw.reserve(end - begin);
        for (size_t i = begin; i < end; ++i) {
            const uint32_t u = zigzag(residuals[i]);
            if (u < 255) {
                raw.push_back(char(u));
            } else {
                raw.push_back(char(255));
                putLength(&raw, u);
            }
        }
        std::string frame(ZSTD_compressBound(raw.size()), '\0');
        const size_t written = ZSTD_compress(&frame[0], frame.size(), raw.data(), raw.size(), kZstdLevel);
        if (ZSTD_isError(written))
            return Status(StatusCode::InvalidData, std::string("vertex displacements: zstd: ") +
                                                       ZSTD_getErrorName(written));
        putLength(&out, uint32_t(written));
        out.append(frame.data(), written);
        begin = end;
    }
    *bytes = std::move(out);
    *factor = q;
    *offset = dmin;
    return Status::ok();
}

Status decodeVertexDisplacements(const ControlMesh& mesh, int level, const unsigned char* data, size_t size,
                                 float factor, float offset, const std::string& what, std::vector<float>* values)
{
    SubdivisionParents h;
    if (Status st = buildSubdivisionParents(&h, mesh, level); !st)
        return Status(st.code(), what + ": " + st.message());
    auto bad = [&](const std::string& why) {
        return Status(StatusCode::InvalidData, what + ": per-vertex displacements " + why);
    };
    if (!std::isfinite(factor) || !std::isfinite(offset) || factor < 0.0f)
        return bad("have an invalid factor or offset");
    const size_t n = h.levelCounts.back();
    std::vector<int32_t> residuals(n), quantized(n);
    std::vector<unsigned char> raw;
    size_t pos = 0, begin = 0;
    for (size_t l = 0; l < h.levelCounts.size(); ++l) {
        const size_t end = h.levelCounts[l], count = end - begin;
        if (size - pos < 4)
            return bad("end early: levels 0 to " + std::to_string(h.levelCounts.size() - 1) + " are declared, the data stop in level " + std::to_string(l) + " (truncated, or the declared level was changed)");
        const size_t frameSize = getLength(data + pos);
        pos += 4;
        if (frameSize > size - pos)
            return bad("end early: levels 0 to " + std::to_string(h.levelCounts.size() - 1) + " are declared, the data stop in level " + std::to_string(l) + " (truncated, or the declared level was changed)");
        // A level of `count` residuals takes between count and 5 count bytes.
        const unsigned long long declared = ZSTD_getFrameContentSize(data + pos, frameSize);
        if (declared == ZSTD_CONTENTSIZE_ERROR || declared == ZSTD_CONTENTSIZE_UNKNOWN || declared < count ||
            declared > 5ull * count)
            return bad("are corrupt (level " + std::to_string(l) + " declares " +
                       (declared == ZSTD_CONTENTSIZE_ERROR || declared == ZSTD_CONTENTSIZE_UNKNOWN
                            ? std::string("no size")
                            : std::to_string(declared) + " bytes") +
                       " for " + std::to_string(count) + " vertices)");
        raw.resize(size_t(declared));
        const size_t got = ZSTD_decompress(raw.data(), raw.size(), data + pos, frameSize);
        if (ZSTD_isError(got) || got != raw.size())
            return bad("are corrupt (level " + std::to_string(l) + " does not decode)");
        pos += frameSize;
        size_t r = 0;
        for (size_t i = begin; i < end; ++i) {
            if (r >= raw.size())
                return bad("are corrupt (level " + std::to_string(l) + " ends early)");
            uint32_t u = raw[r++];
            if (u == 255) {
                if (raw.size() - r < 4)
                    return bad("are corrupt (level " + std::to_string(l) + " ends early)");
                u = getLength(raw.data() + r);
                r += 4;
            }
            residuals[i] = unzigzag(u);
        }
        if (r != raw.size())
            return bad("are corrupt (level " + std::to_string(l) + " has trailing bytes)");
        begin = end;
    }
    if (pos != size)
        return bad("have " + std::to_string(size - pos) + " trailing bytes");
    reconstructSubdivisionValues(h, residuals.data(), quantized.data());
    std::vector<float> out(n);
    for (size_t i = 0; i < n; ++i) {
        if (quantized[i] < 0 || quantized[i] > (1 << 24))
            return bad("are corrupt (vertex " + std::to_string(i) + " decodes out of range)");
        out[i] = shared::strata_decode_distance(float(quantized[i]), factor, offset);
        if (!std::isfinite(out[i]))
            return bad("decode to a non-finite distance at vertex " + std::to_string(i));
    }
    *values = std::move(out);
    return Status::ok();
}

}  // namespace io
}  // namespace strata
