// Single-channel OpenEXR displacement maps.  OpenEXR reports errors by
// exception; they are caught here and become Status values.
#include "strata/io/exr.h"

#include "strata/io/file.h"

#include "text.h"

#include <filesystem>
#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfInputFile.h>
#include <OpenEXR/ImfOutputFile.h>
#include <OpenEXR/ImfTestFile.h>
#include <OpenEXR/ImfThreading.h>

#include <Imath/half.h>

#include <cmath>
#include <vector>
#include <cstring>
#include <stdexcept>
#include <utility>

namespace strata {
namespace io {

namespace {

// OpenEXR reads through an IStream; this one reads a caller's bytes, so the
// same decoder serves files, embedded bytes and the fuzzer.
class MemoryStream : public Imf::IStream {
public:
    MemoryStream(const unsigned char* data, size_t size, const char* name)
        : Imf::IStream(name), data_(reinterpret_cast<const char*>(data)), size_(size)
    {
    }
    bool read(char c[], int n) override
    {
        if (n < 0 || uint64_t(n) > size_ - pos_)
            throw std::runtime_error("the file ends early");
        std::memcpy(c, data_ + pos_, size_t(n));
        pos_ += uint64_t(n);
        return pos_ < size_;
    }
    uint64_t tellg() override { return pos_; }
    void seekg(uint64_t pos) override
    {
        if (pos > size_)
            throw std::runtime_error("a seek goes past the end of the file");
        pos_ = pos;
    }

private:
    const char* data_;
    uint64_t size_;
    uint64_t pos_ = 0;
};

}  // namespace

namespace {

// The first header, walked the way Imf::Header::readFrom walks it, before
// Imf::InputFile sees the bytes: OpenEXR sizes its chunk tables from the
// data window and allocates attribute values at sizes it reads from the
// file (an unknown type at its declared size, a preview at width x height),
// so hostile values must be refused first.  Types OpenEXR reads at a fixed
// size, or (chlist) by content, advance by what it reads, whatever size the
// file declares, so both walks stay in step.  False when anything would read
// past the end of the file or there is no dataWindow.
bool peekDataWindow(const unsigned char* data, size_t size, long* w, long* h)
{
    size_t pos = 8;  // magic + version
    auto readName = [&](std::string* name) {
        size_t end = pos;
        while (end < size && data[end] != 0 && end - pos < 256)
            ++end;
        if (end >= size || data[end] != 0)
            return false;
        name->assign(reinterpret_cast<const char*>(data + pos), end - pos);
        pos = end + 1;
        return true;
    };
    auto readInt = [&](size_t at) {
        uint32_t v = uint32_t(data[at]) | uint32_t(data[at + 1]) << 8 | uint32_t(data[at + 2]) << 16 |
                     uint32_t(data[at + 3]) << 24;
        return int32_t(v);
    };
    static const std::pair<const char*, size_t> kFixed[] = {
        {"box2i", 16}, {"box2f", 16}, {"compression", 1}, {"lineOrder", 1}, {"envmap", 1}, {"deepImageState", 1},
        {"int", 4}, {"float", 4}, {"double", 8}, {"v2i", 8}, {"v2f", 8}, {"v2d", 16}, {"v3i", 12}, {"v3f", 12},
        {"v3d", 24}, {"m33f", 36}, {"m33d", 72}, {"m44f", 64}, {"m44d", 128}, {"chromaticities", 32}, {"keycode", 28},
        {"timecode", 8}, {"rational", 8}, {"tiledesc", 9}};
    bool found = false;
    for (;;) {
        std::string name, type;
        if (!readName(&name))
            return false;
        if (name.empty())
            return found;
        if (!readName(&type) || size - pos < 4)
            return false;
        const int32_t attrSize = readInt(pos);
        pos += 4;
        if (attrSize < 0)
            return false;
        size_t advance = size_t(attrSize);
        for (const auto& [fixedType, bytes] : kFixed)
            if (type == fixedType)
                advance = bytes;
        if (type == "chlist") {
            // name, then type, pLinear, 3 reserved bytes, xSampling, ySampling
            const size_t start = pos;
            for (;;) {
                std::string channel;
                if (!readName(&channel))
                    return false;
                if (channel.empty())
                    break;
                if (size - pos < 16)
                    return false;
                pos += 16;
            }
            advance = pos - start;
            pos = start;
        } else if (type == "preview") {
            if (size - pos < 8)
                return false;
            const uint64_t pixels = uint64_t(uint32_t(readInt(pos))) * uint64_t(uint32_t(readInt(pos + 4)));
            if (pixels > (size - pos - 8) / 4)
                return false;
            advance = 8 + size_t(pixels) * 4;
        }
        if (advance > size - pos)
            return false;
        if (name == "dataWindow") {
            if (type != "box2i")
                return false;
            const long x0 = readInt(pos), y0 = readInt(pos + 4), x1 = readInt(pos + 8), y1 = readInt(pos + 12);
            *w = x1 - x0 + 1;
            *h = y1 - y0 + 1;
            found = true;
        }
        pos += advance;
    }
}

}  // namespace

Status decodeDisplacementExr(const unsigned char* data, size_t size, const std::string& what, DisplacementMap* out,
                             int expectWidth, int expectHeight, size_t maxTexels)
{
    const std::string name = printable(what);
    if (size == 0)
        return Status(StatusCode::InvalidData, name + ": displacement map file is empty");
    try {
        bool tiled = false, deep = false, multipart = false;
        {
            MemoryStream probe(data, size, "exr");
            if (!Imf::isOpenExrFile(probe, tiled, deep, multipart))
                return Status(StatusCode::InvalidData, name + ": not an OpenEXR file");
        }
        if (deep)
            return Status(StatusCode::InvalidData, name + ": deep OpenEXR images are not displacement maps");
        if (multipart)
            return Status(StatusCode::InvalidData, name + ": multi-part OpenEXR files are not displacement maps");
        long w = 0, h = 0;
        if (!peekDataWindow(data, size, &w, &h))
            return Status(StatusCode::InvalidData, name + ": not a readable OpenEXR file (no valid dataWindow)");
        if (w <= 0 || h <= 0 || w > kMaxDisplacementMapSize || h > kMaxDisplacementMapSize)
            return Status(StatusCode::InvalidData, name + ": image size " + std::to_string(w) + "x" + std::to_string(h) +
                                                       " is outside 1.." + std::to_string(kMaxDisplacementMapSize));
        if ((expectWidth > 0 && w != expectWidth) || (expectHeight > 0 && h != expectHeight))
            return Status(StatusCode::InvalidData, name + ": image is " + std::to_string(w) + "x" + std::to_string(h) +
                                                       " but the rig declares " + std::to_string(expectWidth) + "x" +
                                                       std::to_string(expectHeight));
        // No OpenEXR compression packs half texels much past deflate's
        // 1032:1, so a header that declares more than its bytes can hold is
        // refused before the texels are allocated.
        if (double(w) * double(h) * 2.0 > double(size) * 1100.0 + 65536.0)
            return Status(StatusCode::InvalidData, name + ": declares " + std::to_string(w) + "x" + std::to_string(h) +
                                                       " texels but holds only " + std::to_string(size) + " bytes");
        if (maxTexels > 0 && double(w) * double(h) > double(maxTexels))
            return Status(StatusCode::InvalidData, name + ": " + std::to_string(w) + "x" + std::to_string(h) +
                                                       " texels exceed the budget of " + std::to_string(maxTexels));
        MemoryStream stream(data, size, "exr");
        Imf::InputFile file(stream, 0);  // decode on the calling thread
        const Imath::Box2i dw = file.header().dataWindow();
        if (long(dw.max.x) - long(dw.min.x) + 1 != w || long(dw.max.y) - long(dw.min.y) + 1 != h)
            return Status(StatusCode::InvalidData, name + ": not a readable OpenEXR file (inconsistent dataWindow)");
        const Imf::ChannelList& channels = file.header().channels();
        if (!channels.findChannel(kDisplacementChannel)) {
            std::string names;
            for (auto it = channels.begin(); it != channels.end(); ++it)
                names += (names.empty() ? "" : ", ") + std::string(it.name());
            return Status(StatusCode::InvalidData, name + ": no \"" + kDisplacementChannel +
                                                       "\" channel (the file has: " +
                                                       (names.empty() ? "none" : printable(names)) + ")");
        }
        const Imf::Channel* ch = channels.findChannel(kDisplacementChannel);
        if (ch->xSampling != 1 || ch->ySampling != 1)
            return Status(StatusCode::InvalidData, name + ": the Y channel is subsampled");
        DisplacementMap map;
        map.width = int(w);
        map.height = int(h);
        map.texels.assign(size_t(w) * size_t(h), 0.0f);
        Imf::FrameBuffer fb;
        // Slice base is offset by the data window origin, as OpenEXR expects.
        char* base = reinterpret_cast<char*>(map.texels.data()) -
                     (long(dw.min.x) + long(dw.min.y) * w) * long(sizeof(float));
        fb.insert(kDisplacementChannel,
                  Imf::Slice(Imf::FLOAT, base, sizeof(float), size_t(w) * sizeof(float), 1, 1, 0.0));
        file.setFrameBuffer(fb);
        file.readPixels(dw.min.y, dw.max.y);
        for (size_t i = 0; i < map.texels.size(); ++i)
            if (!std::isfinite(map.texels[i]))
                return Status(StatusCode::InvalidData, name + ": texel (" + std::to_string(i % size_t(w)) + ", " +
                                                           std::to_string(i / size_t(w)) + ") is not finite");
        *out = std::move(map);
        return Status::ok();
    } catch (const std::exception& e) {
        // OpenEXR's own wording, translated where it says something a user
        // can act on (truncated, not EXR), on one line after the file's name.
        return Status(StatusCode::InvalidData, name + ": not a readable OpenEXR file (" + plainExrError(e.what()) + ")");
    }
}

Status readDisplacementExr(const std::filesystem::path& pathFile, DisplacementMap* out, int expectWidth, int expectHeight)
{
    const std::string path = pathFile.string();
    std::vector<unsigned char> bytes;
    Status st = readFile(path, &bytes, size_t(1) << 31);
    if (!st)
        return st;
    return decodeDisplacementExr(bytes.data(), bytes.size(), path, out, expectWidth, expectHeight);
}

Status writeDisplacementExr(const std::filesystem::path& pathFile, const DisplacementMap& map, ExrPixelType type,
                            int threads)
{
    const std::string path = pathFile.string();
    Status st = validateDisplacementMap(map);
    if (!st)
        return Status(st.code(), path + ": " + st.message());
    if (type == ExrPixelType::Half)
        for (float t : map.texels)
            if (std::fabs(t) > 65504.0f)
                return Status(StatusCode::InvalidArgument,
                              path + ": a texel exceeds the half-float range (65504); write a float map instead");
    return writeViaTempFile(path, [&](const std::string& tmp) -> std::string {
        Imf::Header header(map.width, map.height);
        header.channels().insert(kDisplacementChannel, Imf::Channel(type == ExrPixelType::Half ? Imf::HALF : Imf::FLOAT));
        header.compression() = Imf::ZIP_COMPRESSION;
        // OpenEXR converts pixel types only when reading: hand it halves to write halves.
        std::vector<Imath::half> halves;
        Imf::FrameBuffer fb;
        if (type == ExrPixelType::Half) {
            halves.assign(map.texels.begin(), map.texels.end());
            fb.insert(kDisplacementChannel, Imf::Slice(Imf::HALF, reinterpret_cast<char*>(halves.data()),
                                                       sizeof(Imath::half), size_t(map.width) * sizeof(Imath::half)));
        } else {
            fb.insert(kDisplacementChannel,
                      Imf::Slice(Imf::FLOAT, const_cast<char*>(reinterpret_cast<const char*>(map.texels.data())),
                                 sizeof(float), size_t(map.width) * sizeof(float)));
        }
        {
            if (threads > 1 && Imf::globalThreadCount() < threads)
                Imf::setGlobalThreadCount(threads);
            Imf::OutputFile file(tmp.c_str(), header, threads > 1 ? threads : 0);
            file.setFrameBuffer(fb);
            file.writePixels(map.height);
        }  // the file is complete only once OutputFile is destroyed
        return std::string();
    });
}

}  // namespace io
}  // namespace strata
