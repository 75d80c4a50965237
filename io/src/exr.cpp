// Single-channel OpenEXR displacement maps.  OpenEXR reports errors by
// exception; they are caught here and become Status values.
#include "strata/io/exr.h"

#include "strata/io/file.h"

#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfInputFile.h>
#include <OpenEXR/ImfOutputFile.h>
#include <OpenEXR/ImfTestFile.h>

#include <Imath/half.h>

#include <cmath>
#include <vector>
#include <fstream>

namespace strata {
namespace io {

Status readDisplacementExr(const std::string& path, DisplacementMap* out, int expectWidth, int expectHeight)
{
    {
        std::ifstream probe(path, std::ios::binary);
        if (!probe)
            return Status(StatusCode::IoError, path + ": cannot open displacement map");
        probe.seekg(0, std::ios::end);
        if (probe.tellg() <= 0)
            return Status(StatusCode::InvalidData, path + ": displacement map file is empty");
    }
    bool tiled = false, deep = false, multipart = false;
    if (!Imf::isOpenExrFile(path.c_str(), tiled, deep, multipart))
        return Status(StatusCode::InvalidData, path + ": not an OpenEXR file");
    if (deep)
        return Status(StatusCode::InvalidData, path + ": deep OpenEXR images are not displacement maps");
    try {
        Imf::InputFile file(path.c_str());
        const Imath::Box2i dw = file.header().dataWindow();
        const long w = long(dw.max.x) - long(dw.min.x) + 1, h = long(dw.max.y) - long(dw.min.y) + 1;
        if (w <= 0 || h <= 0 || w > kMaxDisplacementMapSize || h > kMaxDisplacementMapSize)
            return Status(StatusCode::InvalidData, path + ": image size " + std::to_string(w) + "x" + std::to_string(h) +
                                                       " is outside 1.." + std::to_string(kMaxDisplacementMapSize));
        if ((expectWidth > 0 && w != expectWidth) || (expectHeight > 0 && h != expectHeight))
            return Status(StatusCode::InvalidData, path + ": image is " + std::to_string(w) + "x" + std::to_string(h) +
                                                       " but the rig declares " + std::to_string(expectWidth) + "x" +
                                                       std::to_string(expectHeight));
        const Imf::ChannelList& channels = file.header().channels();
        if (!channels.findChannel(kDisplacementChannel)) {
            std::string names;
            for (auto it = channels.begin(); it != channels.end(); ++it)
                names += (names.empty() ? "" : ", ") + std::string(it.name());
            return Status(StatusCode::InvalidData, path + ": no \"" + kDisplacementChannel +
                                                       "\" channel (the file has: " + (names.empty() ? "none" : names) +
                                                       ")");
        }
        const Imf::Channel* ch = channels.findChannel(kDisplacementChannel);
        if (ch->xSampling != 1 || ch->ySampling != 1)
            return Status(StatusCode::InvalidData, path + ": the Y channel is subsampled");
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
                return Status(StatusCode::InvalidData, path + ": texel (" + std::to_string(i % size_t(w)) + ", " +
                                                           std::to_string(i / size_t(w)) + ") is not finite");
        *out = std::move(map);
        return Status::ok();
    } catch (const std::exception& e) {
        return Status(StatusCode::InvalidData, path + ": " + e.what());
    }
}

Status writeDisplacementExr(const std::string& path, const DisplacementMap& map, ExrPixelType type)
{
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
            Imf::OutputFile file(tmp.c_str(), header);
            file.setFrameBuffer(fb);
            file.writePixels(map.height);
        }  // the file is complete only once OutputFile is destroyed
        return std::string();
    });
}

}  // namespace io
}  // namespace strata
