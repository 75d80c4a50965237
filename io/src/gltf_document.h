// Internal: the source glTF document a rig keeps so that saving it loses
// nothing, and the confined loader every glTF read goes through.
#pragma once

#include "strata/rig.h"
#include "strata/status.h"

#include <tiny_gltf.h>

#include <string>
#include <vector>

namespace strata {

struct SourceDocument {
    tinygltf::Model model;
    /// Encoded bytes of every image that is not in a bufferView (external
    /// file or data URI), by image index; empty where none was readable.
    std::vector<std::vector<unsigned char>> imageBytes;
};

namespace io {

/// Parses a .glb/.gltf.  External buffers and images resolve only inside
/// the file's folder (no absolute paths, no "..", no URI schemes but data:,
/// regular files only).  Image pixels are not decoded; their encoded bytes
/// are kept in doc->imageBytes.
Status loadGltfDocument(const std::string& path, SourceDocument* doc);

}  // namespace io
}  // namespace strata
