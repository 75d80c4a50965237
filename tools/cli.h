// Shared command-line plumbing for Strata's tools: errors become one line on
// stderr and exit code 2 (gltfpack's convention); never a stack trace.
#pragma once

#include <cstdio>
#include <cstdlib>
#include <stdexcept>
#include <initializer_list>
#include <string>
#include <utility>

namespace strata {
namespace cli {

/// The project version every tool's --version prints.
#ifndef STRATA_VERSION
#error "tools define STRATA_VERSION (the project version) on the compile line"
#endif
constexpr const char* kVersion = STRATA_VERSION;

/// Thrown inside a tool for any user-facing failure; main prints it.
struct Error : std::runtime_error {
    using std::runtime_error::runtime_error;
};

inline int parseInt(const std::string& flag, const std::string& text, int lo, int hi)
{
    char* end = nullptr;
    const long v = std::strtol(text.c_str(), &end, 10);
    if (text.empty() || *end || v < lo || v > hi)
        throw Error(flag + " expects an integer in " + std::to_string(lo) + ".." + std::to_string(hi) + ", got \"" +
                    text + "\"");
    return int(v);
}

inline float parseFloat(const std::string& flag, const std::string& text)
{
    char* end = nullptr;
    const float v = std::strtof(text.c_str(), &end);
    if (text.empty() || *end || !(v == v) || v > 3.0e38f || v < -3.0e38f)
        throw Error(flag + " expects a finite number, got \"" + text + "\"");
    return v;
}

/// The value after argv[*i] (a flag that takes one), advancing *i; an error
/// naming the flag when the command line ends first.
inline std::string flagValue(int argc, char** argv, int* i)
{
    if (*i + 1 >= argc)
        throw Error(std::string(argv[*i]) + " needs a value");
    return argv[++*i];
}

/// One of a fixed set of words, e.g. --overlap max|nearest: the value paired
/// with `text`, else an error naming the flag and every choice ("--overlap
/// expects max or nearest").
template <typename T>
T parseChoice(const std::string& flag, const std::string& text,
              std::initializer_list<std::pair<const char*, T>> choices)
{
    std::string expected;
    size_t k = 0;
    for (const auto& c : choices) {
        if (text == c.first)
            return c.second;
        expected += (k == 0 ? "" : k + 1 == choices.size() ? " or " : ", ") + std::string(c.first);
        ++k;
    }
    throw Error(flag + " expects " + expected);
}

/// One printable line: control characters become '?', long text is cut.
inline std::string printable(std::string text, size_t maxLength = 600)
{
    for (char& c : text)
        if ((unsigned char)c < 0x20 || c == 0x7f)
            c = '?';
    if (text.size() > maxLength)
        text = text.substr(0, maxLength) + "...";
    return text;
}

/// Runs body, turning exceptions into "tool: error: message" and exit 2.
template <typename F>
int run(const char* tool, F&& body)
{
    try {
        return body();
    } catch (const Error& e) {
        std::fprintf(stderr, "%s: error: %s\n", tool, printable(e.what()).c_str());
    } catch (const std::bad_alloc&) {
        std::fprintf(stderr, "%s: error: out of memory\n", tool);
    } catch (const std::exception&) {
        // A library's own text (std::vector::_M_range_check and the like)
        // means nothing to the user; a validation is missing if this shows.
        std::fprintf(stderr, "%s: error: unexpected internal failure on this input (please report it with the file)\n",
                     tool);
    }
    return 2;
}

}  // namespace cli
}  // namespace strata
