// Strata io: PNG images (the paper's quantised displacement maps, eq. 12,
// and diagnostic images).
#pragma once

#include <filesystem>

#include "strata/status.h"

#include <cstdint>
#include <string>
#include <vector>

namespace strata {
namespace io {

/// Writes a greyscale PNG, 8 or 16 bits per sample, row-major (row 0 first).
Status writePngGray(const std::filesystem::path& path, int width, int height, int bits, const std::vector<uint16_t>& samples);

/// Encodes a greyscale PNG in memory (adaptive per-row filters, zlib level 9).
Status encodePngGray(int width, int height, int bits, const std::vector<uint16_t>& samples, std::string* png);
/// Decodes a greyscale PNG of 8 or 16 bits from memory; `what` names it in
/// errors.  Sizes are checked from the header before anything is decoded:
/// against expectWidth/Height when positive (the rig's), and against the
/// bytes (at most 256 bytes of pixels per byte of file: a map that
/// compresses further is all but constant, and hostile headers could
/// otherwise buy gigabytes of decoder memory).
Status decodePngGray(const unsigned char* data, size_t size, const std::string& what, int* width, int* height, int* bits,
                     std::vector<uint16_t>* samples, int expectWidth = 0, int expectHeight = 0);
/// Whether `data` is a PNG whose every chunk lies inside its `size` bytes,
/// the last IEND.  stb_image grows its buffer to a chunk's declared length
/// before it reads the chunk, so a hostile length (a few bytes) would buy
/// gigabytes: every PNG Strata decodes is checked so first.
bool pngChunksFit(const unsigned char* data, size_t size);
/// The distinct colours of an RGBA image (4 bytes a pixel, each read as one
/// native uint32), sorted, when there are at most 256 (a palette); false,
/// `colours` empty, when there are more.
bool paletteOf(const std::vector<uint8_t>& rgba, std::vector<uint32_t>* colours);
/// Encodes an 8-bit colour PNG in memory from 4 bytes per pixel: indexed
/// when the image has at most 256 colours, else RGB when every alpha is
/// 255, else RGBA; deflated at zlib's `level` (9: the smallest; 6 is 8
/// times as fast on a noisy 1024^2 image, for 3% more bytes).
Status encodePngRgba(int width, int height, const std::vector<uint8_t>& rgba, std::string* png, int level = 9);
/// A colour texture for glTF from 4 bytes per pixel: when every alpha is
/// 255, JPEG at `quality` (1..100) or a PNG (encodePngRgba's), whichever is
/// smaller (a texture of flat colours is smaller as a lossless PNG); else
/// encodePngRgba's PNG.  *mimeType says which.
Status encodeColourImage(int width, int height, const std::vector<uint8_t>& rgba, int quality, std::string* bytes,
                         std::string* mimeType);
/// Writes an 8-bit RGB PNG (3 bytes per pixel).
Status writePngRgb(const std::filesystem::path& path, int width, int height, const std::vector<uint8_t>& rgb);

/// Reads any 8-bit PNG as RGB (3 bytes per pixel, row 0 first).
Status readPngRgb(const std::filesystem::path& path, int* width, int* height, std::vector<uint8_t>* rgb);

/// Reads a greyscale PNG of 8 or 16 bits; *bits receives which.
Status readPngGray(const std::filesystem::path& path, int* width, int* height, int* bits, std::vector<uint16_t>* samples);

}  // namespace io
}  // namespace strata
