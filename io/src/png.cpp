// PNG writing with zlib (stb_image_write has no 16-bit output) and reading
// with stb_image (Debian's libstb holds the implementation).
#include "strata/io/png.h"

#include <filesystem>
#include <cstring>

#include "strata/io/file.h"

#include <stb/stb_image.h>
#include <stb/stb_image_write.h>
#include <zlib.h>

#include <algorithm>

#include <cstdlib>

namespace strata {
namespace io {
namespace {

void putBigEndian32(std::string& out, uint32_t v)
{
    out += char(v >> 24);
    out += char(v >> 16);
    out += char(v >> 8);
    out += char(v);
}

void chunk(std::string& out, const char* type, const std::string& data)
{
    putBigEndian32(out, uint32_t(data.size()));
    const std::string typed = std::string(type, 4) + data;
    out += typed;
    putBigEndian32(out, uint32_t(crc32(0, reinterpret_cast<const Bytef*>(typed.data()), uInt(typed.size()))));
}

// PNG filter of one row (types 0-4, RFC 2083 6.2); bpp bytes per pixel.
void filterRow(int type, const uint8_t* row, const uint8_t* prev, size_t n, size_t bpp, uint8_t* out)
{
    for (size_t i = 0; i < n; ++i) {
        const int a = i >= bpp ? row[i - bpp] : 0, b = prev ? prev[i] : 0, c = (prev && i >= bpp) ? prev[i - bpp] : 0;
        int pred = 0;
        switch (type) {
        case 1: pred = a; break;
        case 2: pred = b; break;
        case 3: pred = (a + b) / 2; break;
        case 4: {
            const int p = a + b - c, pa = std::abs(p - a), pb = std::abs(p - b), pc = std::abs(p - c);
            pred = (pa <= pb && pa <= pc) ? a : (pb <= pc ? b : c);
            break;
        }
        default: break;
        }
        out[i] = uint8_t(row[i] - pred);
    }
}

// colourType 0 = grey, 2 = RGB, 3 = indexed (its PLTE and tRNS chunks
// given as `palette`), 6 = RGBA; rows already laid out big-endian.  Each
// row takes the filter with the smallest sum of absolute residuals
// (libpng's heuristic), which suits smooth displacement maps; indexed rows
// are not filtered (their bytes are names, not amounts, as libpng does).
Status encodePng(int width, int height, int bits, int colourType, int channels, const std::vector<uint8_t>& rowBytes,
                 std::string* out, const std::string& palette = std::string(), int level = 9)
{
    if (width <= 0 || height <= 0)
        return Status(StatusCode::InvalidArgument, "empty image");
    const size_t stride = size_t(width) * size_t(channels) * size_t(bits / 8);
    const size_t bpp = size_t(channels) * size_t(bits / 8);
    std::string raw;
    raw.reserve((stride + 1) * size_t(height));
    std::vector<uint8_t> best(stride), trial(stride);
    for (int y = 0; y < height; ++y) {
        const uint8_t* row = rowBytes.data() + size_t(y) * stride;
        const uint8_t* prev = y > 0 ? row - stride : nullptr;
        long bestCost = -1;
        int bestType = 0;
        for (int type = 0; type <= (colourType == 3 ? 0 : 4); ++type) {
            filterRow(type, row, prev, stride, bpp, trial.data());
            long cost = 0;
            for (uint8_t v : trial)
                cost += v < 128 ? v : 256 - v;
            if (bestCost < 0 || cost < bestCost) {
                bestCost = cost;
                bestType = type;
                best.swap(trial);
            }
        }
        raw += char(bestType);
        raw.append(reinterpret_cast<const char*>(best.data()), stride);
    }
    uLongf zsize = compressBound(uLong(raw.size()));
    std::string z(zsize, '\0');
    if (compress2(reinterpret_cast<Bytef*>(&z[0]), &zsize, reinterpret_cast<const Bytef*>(raw.data()), uLong(raw.size()),
                  level) != Z_OK)
        return Status(StatusCode::IoError, "PNG compression failed");
    z.resize(zsize);
    *out = std::string("\x89PNG\r\n\x1a\n", 8);
    std::string ihdr;
    putBigEndian32(ihdr, uint32_t(width));
    putBigEndian32(ihdr, uint32_t(height));
    ihdr += char(bits);
    ihdr += char(colourType);
    ihdr += std::string(3, '\0');  // compression, filter, interlace
    chunk(*out, "IHDR", ihdr);
    *out += palette;
    chunk(*out, "IDAT", z);
    chunk(*out, "IEND", std::string());
    return Status::ok();
}

Status writePng(const std::string& path, int width, int height, int bits, int colourType, int channels,
                const std::vector<uint8_t>& rowBytes)
{
    std::string bytes;
    if (Status st = encodePng(width, height, bits, colourType, channels, rowBytes, &bytes); !st)
        return Status(st.code(), path + ": " + st.message());
    return writeFileAtomic(path, bytes.data(), bytes.size());
}

}  // namespace

namespace {

Status grayRows(int width, int height, int bits, const std::vector<uint16_t>& samples, std::vector<uint8_t>* bytes)
{
    if (bits != 8 && bits != 16)
        return Status(StatusCode::InvalidArgument, "PNG depth must be 8 or 16 bits");
    if (width <= 0 || height <= 0 || samples.size() != size_t(width) * size_t(height))
        return Status(StatusCode::InvalidArgument, "sample count does not match the image size");
    bytes->clear();
    bytes->reserve(samples.size() * size_t(bits / 8));
    for (uint16_t s : samples) {
        if (bits == 16)
            bytes->push_back(uint8_t(s >> 8));
        bytes->push_back(uint8_t(s & 0xff));
    }
    return Status::ok();
}

}  // namespace

Status encodePngGray(int width, int height, int bits, const std::vector<uint16_t>& samples, std::string* png)
{
    std::vector<uint8_t> bytes;
    Status st = grayRows(width, height, bits, samples, &bytes);
    if (!st)
        return st;
    return encodePng(width, height, bits, 0, 1, bytes, png);
}

Status writePngGray(const std::filesystem::path& pathFile, int width, int height, int bits, const std::vector<uint16_t>& samples)
{
    const std::string path = pathFile.string();
    std::vector<uint8_t> bytes;
    if (Status st = grayRows(width, height, bits, samples, &bytes); !st)
        return Status(st.code(), path + ": " + st.message());
    return writePng(path, width, height, bits, 0, 1, bytes);
}

bool paletteOf(const std::vector<uint8_t>& rgba, std::vector<uint32_t>* colours)
{
    // An open-addressed set of 1,024 slots, given up at the 257th colour.
    constexpr size_t kSlots = 1024;
    std::vector<uint32_t> key(kSlots, 0);
    std::vector<uint8_t> used(kSlots, 0);
    colours->clear();
    uint32_t last = 0;
    for (size_t i = 0; i + 3 < rgba.size(); i += 4) {
        uint32_t c;
        std::memcpy(&c, &rgba[i], 4);
        if (i > 0 && c == last)
            continue;
        last = c;
        size_t h = size_t((c * 2654435761u) >> 22);  // the top 10 bits
        while (used[h] && key[h] != c)
            h = (h + 1) & (kSlots - 1);
        if (used[h])
            continue;
        if (colours->size() == 256) {
            colours->clear();
            return false;
        }
        used[h] = 1;
        key[h] = c;
        colours->push_back(c);
    }
    std::sort(colours->begin(), colours->end());
    return true;
}

namespace {

// An image of at most 256 colours (a palette of flat colours, as a
// low-poly character's texture is) as an indexed PNG: a byte a pixel where
// RGB takes three, its colours exact.  False, writing nothing, for more
// colours.
bool encodeIndexed(int width, int height, const std::vector<uint8_t>& rgba, std::string* png)
{
    std::vector<uint32_t> colours;
    if (!paletteOf(rgba, &colours))
        return false;
    std::string plte, trns;
    bool translucent = false;
    for (uint32_t c : colours) {
        uint8_t px[4];
        std::memcpy(px, &c, 4);
        plte.append(reinterpret_cast<const char*>(px), 3);
        trns += char(px[3]);
        translucent = translucent || px[3] != 255;
    }
    std::string chunks;
    chunk(chunks, "PLTE", plte);
    if (translucent)
        chunk(chunks, "tRNS", trns);
    std::vector<uint8_t> indices(rgba.size() / 4);
    uint32_t last = 0;
    uint8_t lastIndex = 0;
    for (size_t i = 0; i < indices.size(); ++i) {
        uint32_t c;
        std::memcpy(&c, &rgba[4 * i], 4);
        if (i == 0 || c != last)
            lastIndex = uint8_t(std::lower_bound(colours.begin(), colours.end(), c) - colours.begin());
        last = c;
        indices[i] = lastIndex;
    }
    return encodePng(width, height, 8, 3, 1, indices, png, chunks).isOk();
}

}  // namespace

Status encodePngRgba(int width, int height, const std::vector<uint8_t>& rgba, std::string* png, int level)
{
    if (rgba.size() != size_t(std::max(width, 0)) * size_t(std::max(height, 0)) * 4)
        return Status(StatusCode::InvalidArgument, "pixel count does not match the image size");
    if (encodeIndexed(width, height, rgba, png))
        return Status::ok();
    bool opaque = true;
    for (size_t i = 3; i < rgba.size() && opaque; i += 4)
        opaque = rgba[i] == 255;
    if (!opaque)
        return encodePng(width, height, 8, 6, 4, rgba, png, std::string(), level);
    std::vector<uint8_t> rgb(rgba.size() / 4 * 3);
    for (size_t i = 0, j = 0; i < rgba.size(); i += 4, j += 3)
        std::copy_n(&rgba[i], 3, &rgb[j]);
    return encodePng(width, height, 8, 2, 3, rgb, png, std::string(), level);
}

Status encodeColourImage(int width, int height, const std::vector<uint8_t>& rgba, int quality, std::string* bytes,
                         std::string* mimeType)
{
    if (width <= 0 || height <= 0 || rgba.size() != size_t(width) * size_t(height) * 4)
        return Status(StatusCode::InvalidArgument, "pixel count does not match the image size");
    bool opaque = true;
    for (size_t i = 3; i < rgba.size() && opaque; i += 4)
        opaque = rgba[i] == 255;
    if (!opaque) {
        *mimeType = "image/png";
        return encodePngRgba(width, height, rgba, bytes);
    }
    auto jpeg = [&](int h, const uint8_t* pixels, std::string* to) {
        return stbi_write_jpg_to_func(
                   [](void* context, void* data, int size) {
                       static_cast<std::string*>(context)->append(static_cast<const char*>(data), size_t(size));
                   },
                   to, width, h, 4, pixels, std::clamp(quality, 1, 100)) != 0 &&
               !to->empty();
    };
    std::string out;
    if (!jpeg(height, rgba.data(), &out))
        return Status(StatusCode::IoError, "JPEG encoding failed");
    // A texture of flat colours (a low-poly character's palette) is smaller
    // as a PNG, and lossless: the smaller of the two is kept.  A PNG costs
    // four times the JPEG's time (0.7 s at 2048x2048), so it is made only
    // where 8 bands of 16 rows across the image come within 20% of JPEG's.
    std::vector<uint8_t> bands;
    const int band = std::min(16, height), count = std::min(8, height / band);
    for (int b = 0; b < count; ++b) {
        const size_t row = size_t(height - band) * size_t(b) / size_t(std::max(1, count - 1));
        const uint8_t* from = rgba.data() + row * size_t(width) * 4;
        bands.insert(bands.end(), from, from + size_t(band) * size_t(width) * 4);
    }
    std::string bandsJpeg, bandsPng, png;
    const bool tryPng = jpeg(band * count, bands.data(), &bandsJpeg) &&
                        encodePngRgba(width, band * count, bands, &bandsPng) &&
                        double(bandsPng.size()) <= 1.2 * double(bandsJpeg.size());
    if (tryPng && encodePngRgba(width, height, rgba, &png) && png.size() <= out.size()) {
        *bytes = std::move(png);
        *mimeType = "image/png";
        return Status::ok();
    }
    *bytes = std::move(out);
    *mimeType = "image/jpeg";
    return Status::ok();
}

Status writePngRgb(const std::filesystem::path& pathFile, int width, int height, const std::vector<uint8_t>& rgb)
{
    const std::string path = pathFile.string();
    if (rgb.size() != size_t(width) * size_t(height) * 3)
        return Status(StatusCode::InvalidArgument, path + ": pixel count does not match the image size");
    return writePng(path, width, height, 8, 2, 3, rgb);
}

namespace {

// Reads a PNG file and its header: size (capped at 16384 per side) and
// channel count, leaving the bytes for decoding.
Status readPngHeader(const std::string& path, std::vector<unsigned char>* bytes, int* w, int* h, int* comp)
{
    Status st = readFile(path, bytes, size_t(1) << 30);
    if (!st)
        return st;
    if (!pngChunksFit(bytes->data(), bytes->size()) ||
        !stbi_info_from_memory(bytes->data(), int(bytes->size()), w, h, comp))
        return Status(StatusCode::InvalidData, path + ": not a readable PNG image");
    if (*w > 16384 || *h > 16384)
        return Status(StatusCode::InvalidData, path + ": image is larger than 16384 per side");
    return Status::ok();
}

}  // namespace

Status readPngRgb(const std::filesystem::path& pathFile, int* width, int* height, std::vector<uint8_t>* rgb)
{
    const std::string path = pathFile.string();
    std::vector<unsigned char> bytes;
    int w = 0, h = 0, comp = 0;
    if (Status st = readPngHeader(path, &bytes, &w, &h, &comp); !st)
        return st;
    stbi_uc* px = stbi_load_from_memory(bytes.data(), int(bytes.size()), &w, &h, &comp, 3);
    if (!px)
        return Status(StatusCode::InvalidData, path + ": PNG decoding failed");
    rgb->assign(px, px + size_t(w) * size_t(h) * 3);
    stbi_image_free(px);
    *width = w;
    *height = h;
    return Status::ok();
}

bool pngChunksFit(const unsigned char* data, size_t size)
{
    static const unsigned char kSignature[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
    if (size < 8 || std::memcmp(data, kSignature, 8) != 0)
        return false;
    size_t pos = 8;
    while (size - pos >= 12) {
        const size_t length = size_t(data[pos]) << 24 | size_t(data[pos + 1]) << 16 | size_t(data[pos + 2]) << 8 |
                              size_t(data[pos + 3]);
        if (length > size - pos - 12)
            return false;
        const bool end = std::memcmp(data + pos + 4, "IEND", 4) == 0;
        pos += 12 + length;
        if (end)
            return true;
    }
    return false;
}

Status decodePngGray(const unsigned char* data, size_t size, const std::string& what, int* width, int* height, int* bits,
                     std::vector<uint16_t>* samples, int expectWidth, int expectHeight)
{
    int w = 0, h = 0, comp = 0;
    if (size > size_t(1) << 30 || !pngChunksFit(data, size) || !stbi_info_from_memory(data, int(size), &w, &h, &comp))
        return Status(StatusCode::InvalidData, what + ": not a readable PNG image");
    if (w > 16384 || h > 16384)
        return Status(StatusCode::InvalidData, what + ": image is larger than 16384 per side");
    if (comp != 1)
        return Status(StatusCode::InvalidData, what + ": expected a greyscale image, found " + std::to_string(comp) +
                                                   " channels");
    const bool sixteen = stbi_is_16_bit_from_memory(data, int(size)) != 0;
    if ((expectWidth > 0 && w != expectWidth) || (expectHeight > 0 && h != expectHeight))
        return Status(StatusCode::InvalidData, what + ": image is " + std::to_string(w) + "x" + std::to_string(h) +
                                                   " but the rig declares " + std::to_string(expectWidth) + "x" +
                                                   std::to_string(expectHeight));
    // Refused before anything is allocated: more pixels than 256 per byte of
    // file (deflate's own limit is 1032:1; the decoder holds several copies).
    const double declared = double(w) * double(h) * (sixteen ? 2.0 : 1.0);
    if (declared > double(size) * 256.0 + 65536.0)
        return Status(StatusCode::InvalidData, what + ": declares " + std::to_string(w) + "x" + std::to_string(h) +
                                                   " pixels but holds only " + std::to_string(size) + " bytes");
    if (sixteen) {
        stbi_us* px = stbi_load_16_from_memory(data, int(size), &w, &h, &comp, 1);
        if (!px)
            return Status(StatusCode::InvalidData, what + ": PNG decoding failed");
        samples->resize(size_t(w) * size_t(h));
        std::copy(px, px + samples->size(), samples->begin());
        stbi_image_free(px);
    } else {
        stbi_uc* px = stbi_load_from_memory(data, int(size), &w, &h, &comp, 1);
        if (!px)
            return Status(StatusCode::InvalidData, what + ": PNG decoding failed");
        samples->resize(size_t(w) * size_t(h));
        std::copy(px, px + samples->size(), samples->begin());
        stbi_image_free(px);
    }
    *width = w;
    *height = h;
    *bits = sixteen ? 16 : 8;
    return Status::ok();
}

Status readPngGray(const std::filesystem::path& pathFile, int* width, int* height, int* bits, std::vector<uint16_t>* samples)
{
    const std::string path = pathFile.string();
    std::vector<unsigned char> bytes;
    Status st = readFile(path, &bytes, size_t(1) << 30);
    if (!st)
        return st;
    return decodePngGray(bytes.data(), bytes.size(), path, width, height, bits, samples);
}

}  // namespace io
}  // namespace strata
