// Strata io: whole-file reads and atomic writes.
//
// Every output the project writes goes through writeFileAtomic: the bytes go
// to a temporary file beside the target, which is renamed over the target
// only once complete, so a failed or interrupted write never leaves a
// half-written file under the final name.
#pragma once

#include <filesystem>

#include "strata/status.h"

#include <functional>
#include <string>
#include <vector>

namespace strata {
namespace io {

/// Reads a whole file.  Fails with a message naming the path when it is
/// missing, unreadable, a directory, empty, or larger than maxBytes.
Status readFile(const std::filesystem::path& path, std::vector<unsigned char>* out, size_t maxBytes = size_t(1) << 31);

/// Writes bytes to path atomically (temporary file + rename).
Status writeFileAtomic(const std::filesystem::path& path, const void* data, size_t size);

/// Whether writing `output` would replace `input`, judged by the file and not
/// by its spelling: the same device and inode where both exist, else the
/// same path once `.`, `..` and the links of its existing part are resolved
/// (so `x/../in.glb` is `in.glb` even while `x` does not exist).
bool sameFile(const std::string& output, const std::string& input);

/// For libraries that insist on writing a file by name themselves (OpenEXR):
/// calls write(tempPath), then renames tempPath over path; removes the
/// temporary file on failure.  write returns an empty string on success or a
/// message.
Status writeViaTempFile(const std::string& path, const std::function<std::string(const std::string& tempPath)>& write);

/// True when path names an existing regular file (not a folder, FIFO or device).
bool isRegularFile(const std::filesystem::path& path);

/// Lower-case extension including the dot (".glb"), or "" when none.
std::string extensionOf(const std::string& path);
/// The directory part of path ("" when none), without a trailing slash.
std::string directoryOf(const std::string& path);
/// The file name without directory and extension.
std::string stemOf(const std::string& path);

}  // namespace io
}  // namespace strata
