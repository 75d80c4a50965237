// Strata io: the displacement map as single-channel OpenEXR (docs/FORMAT.md).
#pragma once

#include <filesystem>

#include "strata/displacement_map.h"
#include "strata/status.h"

#include <cstddef>
#include <string>

namespace strata {
namespace io {

/// The channel Strata writes and reads: luminance "Y".
constexpr const char* kDisplacementChannel = "Y";

enum class ExrPixelType { Half, Float };

/// Reads a displacement map.  Rejects, with a message naming the file: a
/// missing or non-EXR file, a file without the "Y" channel (listing the
/// channels it has), a size over kMaxDisplacementMapSize, and NaN/inf texels.
/// The map's factor/offset are left at 1/0; the rig supplies them.
/// expectWidth/Height (when positive): the size the caller needs; another
/// size is an error found from the header, before any pixel is decoded.
Status readDisplacementExr(const std::filesystem::path& path, DisplacementMap* out, int expectWidth = 0, int expectHeight = 0);

/// readDisplacementExr from bytes in memory; `what` names them in messages.
/// The size checks run on the header, before any texel is allocated: a
/// header that declares more texels than its bytes could hold, or more than
/// maxTexels (when positive: a caller's memory budget), is refused.
Status decodeDisplacementExr(const unsigned char* data, size_t size, const std::string& what, DisplacementMap* out,
                             int expectWidth = 0, int expectHeight = 0, size_t maxTexels = 0);

/// Writes map's texels (not decoded: factor/offset live in the rig) as one
/// "Y" channel, ZIP-compressed, atomically.  threads > 1 compresses line
/// blocks on OpenEXR's global thread pool, which is grown to that size if
/// smaller (process-wide state of OpenEXR's; it is never shrunk).
Status writeDisplacementExr(const std::filesystem::path& path, const DisplacementMap& map,
                            ExrPixelType type = ExrPixelType::Half, int threads = 1);

}  // namespace io
}  // namespace strata
