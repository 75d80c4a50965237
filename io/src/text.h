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

}  // namespace io
}  // namespace strata
