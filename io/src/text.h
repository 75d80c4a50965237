// Strata io (private): text that reaches the user.
#pragma once

#include <cstddef>
#include <string>

namespace strata {
namespace io {

/// One line, printable: control bytes become '?', text past maxLength is cut.
/// Everything echoed from an input file (names, URIs, library messages)
/// passes through it.
std::string printable(std::string text, size_t maxLength = 200);

/// A JSON library message (nlohmann's "[json.exception.parse_error.101]
/// parse error at line 2, column 1: ...") in plain words: "not valid JSON
/// (line 2, column 1)", "a value of the wrong type (...)".
std::string plainJsonError(const std::string& what);

/// An OpenEXR library message in plain words: a truncated file, one that is
/// not OpenEXR, or the library's own text without the file name it repeats.
std::string plainExrError(const std::string& what);

}  // namespace io
}  // namespace strata
