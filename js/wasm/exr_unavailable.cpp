// The WebAssembly build reads rigs from bytes: their maps are embedded PNGs
// or per-vertex values.  An external OpenEXR map (a rig baked with --exr) is
// a file beside the rig, which a page cannot open, and OpenEXR is not
// compiled for the browser; these say so instead of linking it.
#include "strata/io/exr.h"

namespace strata {
namespace io {

namespace {

Status unavailable(const std::string& what)
{
    return Status(StatusCode::Unsupported,
                  what + ": OpenEXR maps are not read by the WebAssembly runtime; "
                         "bake without --exr (the map is then inside the rig)");
}

}  // namespace

Status readDisplacementExr(const std::filesystem::path& path, DisplacementMap*, int, int)
{
    return unavailable(path.string());
}

Status decodeDisplacementExr(const unsigned char*, size_t, const std::string& what, DisplacementMap*, int, int, size_t)
{
    return unavailable(what);
}

Status writeDisplacementExr(const std::filesystem::path& path, const DisplacementMap&, ExrPixelType, int)
{
    return unavailable(path.string());
}

}  // namespace io
}  // namespace strata
