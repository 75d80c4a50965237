#include "strata/io/file.h"

#include "text.h"

#include <filesystem>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <random>
#include <sys/stat.h>
#include <unistd.h>

namespace strata {
namespace io {

Status readFile(const std::filesystem::path& pathFile, std::vector<unsigned char>* out, size_t maxBytes)
{
    const std::string path = pathFile.string();
    struct stat st;
    if (::stat(path.c_str(), &st) != 0)
        return Status(StatusCode::IoError, path + ": " + std::strerror(errno));
    if (S_ISDIR(st.st_mode))
        return Status(StatusCode::IoError, path + ": is a directory");
    if (st.st_size == 0)
        return Status(StatusCode::InvalidData, path + ": file is empty");
    if (size_t(st.st_size) > maxBytes)
        return Status(StatusCode::InvalidData, path + ": file is " + std::to_string(st.st_size) +
                                                   " bytes, more than the " + std::to_string(maxBytes) + " accepted");
    std::ifstream in(path, std::ios::binary);
    if (!in)
        return Status(StatusCode::IoError, path + ": cannot open for reading");
    out->resize(size_t(st.st_size));
    in.read(reinterpret_cast<char*>(out->data()), std::streamsize(out->size()));
    if (!in || in.gcount() != std::streamsize(out->size()))
        return Status(StatusCode::IoError, path + ": read failed");
    return Status::ok();
}

namespace {

std::string temporaryNameFor(const std::string& path)
{
    std::random_device rd;
    char suffix[32];
    std::snprintf(suffix, sizeof(suffix), ".tmp%d.%08x", int(::getpid()), unsigned(rd()));
    // Keep the extension last: some writers (OpenEXR, tinygltf) look at it.
    const std::string ext = extensionOf(path);
    return path.substr(0, path.size() - ext.size()) + suffix + ext;
}

}  // namespace

Status writeViaTempFile(const std::string& path, const std::function<std::string(const std::string&)>& write)
{
    struct stat link;
    if (::lstat(path.c_str(), &link) == 0 && S_ISLNK(link.st_mode))
        return Status(StatusCode::InvalidArgument, path + ": is a symbolic link; refusing to replace it (write to its target)");
    const std::string tmp = temporaryNameFor(path);
    std::string err;
    try {
        err = write(tmp);
    } catch (const std::exception& e) {
        err = e.what();
    } catch (...) {
        err = "unknown error";
    }
    if (!err.empty()) {
        std::remove(tmp.c_str());
        // Libraries name the file they were given: the temporary name means
        // nothing to the user.
        for (size_t at; (at = err.find(tmp)) != std::string::npos;)
            err.replace(at, tmp.size(), path);
        return Status(StatusCode::IoError, path + ": " + err);
    }
    if (std::rename(tmp.c_str(), path.c_str()) != 0) {
        const std::string reason = std::strerror(errno);
        std::remove(tmp.c_str());
        return Status(StatusCode::IoError, path + ": " + reason);
    }
    return Status::ok();
}

bool sameFile(const std::string& output, const std::string& input)
{
    if (output.empty() || input.empty())
        return false;
    struct stat a, b;
    if (::stat(output.c_str(), &a) == 0 && ::stat(input.c_str(), &b) == 0)
        return a.st_dev == b.st_dev && a.st_ino == b.st_ino;
    std::error_code ea, eb;
    const std::filesystem::path pa = std::filesystem::weakly_canonical(std::filesystem::absolute(output), ea);
    const std::filesystem::path pb = std::filesystem::weakly_canonical(std::filesystem::absolute(input), eb);
    return !ea && !eb && pa == pb;
}

Status writeFileAtomic(const std::filesystem::path& pathFile, const void* data, size_t size)
{
    const std::string path = pathFile.string();
    return writeViaTempFile(path, [&](const std::string& tmp) -> std::string {
        FILE* f = std::fopen(tmp.c_str(), "wb");
        if (!f)
            return std::string("cannot create file: ") + std::strerror(errno);
        const bool ok = std::fwrite(data, 1, size, f) == size;
        const bool flushed = std::fflush(f) == 0 && ::fsync(::fileno(f)) == 0;
        const bool closed = std::fclose(f) == 0;
        if (!ok || !flushed || !closed)
            return std::string("write failed: ") + std::strerror(errno);
        return std::string();
    });
}

std::string extensionOf(const std::string& path)
{
    const size_t slash = path.find_last_of('/');
    const size_t dot = path.find_last_of('.');
    if (dot == std::string::npos || (slash != std::string::npos && dot < slash))
        return std::string();
    std::string ext = path.substr(dot);
    for (char& c : ext)
        c = char(std::tolower(static_cast<unsigned char>(c)));
    return ext;
}

std::string directoryOf(const std::string& path)
{
    const size_t slash = path.find_last_of('/');
    return slash == std::string::npos ? std::string() : path.substr(0, slash);
}

std::string stemOf(const std::string& path)
{
    const size_t slash = path.find_last_of('/');
    std::string name = slash == std::string::npos ? path : path.substr(slash + 1);
    const size_t dot = name.find_last_of('.');
    return dot == std::string::npos || dot == 0 ? name : name.substr(0, dot);
}

bool isRegularFile(const std::filesystem::path& pathFile)
{
    const std::string path = pathFile.string();
    struct stat st;
    return ::stat(path.c_str(), &st) == 0 && S_ISREG(st.st_mode);
}

namespace {

// The digits at text[*at...], advancing *at; empty when there are none.
std::string digitsAt(const std::string& text, size_t* at)
{
    const size_t from = *at;
    while (*at < text.size() && text[*at] >= '0' && text[*at] <= '9')
        ++*at;
    return text.substr(from, *at - from);
}

}  // namespace

// Plain string matching, not std::regex: GCC 12's <regex> trips
// -Wmaybe-uninitialized under the sanitizers, and these run on hostile text.
std::string plainJsonError(const std::string& what)
{
    const std::string lineKey = "parse error at line ", columnKey = ", column ";
    size_t at = what.find(lineKey);
    if (at != std::string::npos) {
        at += lineKey.size();
        const std::string line = digitsAt(what, &at);
        if (!line.empty() && what.compare(at, columnKey.size(), columnKey) == 0) {
            at += columnKey.size();
            const std::string column = digitsAt(what, &at);
            if (!column.empty())
                return "not valid JSON (line " + line + ", column " + column + ")";
        }
    }
    at = what.find("type_error");
    if (at != std::string::npos && (at = what.find(' ', at)) != std::string::npos)
        return "a value of the wrong type (" + printable(what.substr(at + 1), 80) + ")";
    at = what.find("[json.exception.");
    if (at != std::string::npos && (at = what.find("] ", at)) != std::string::npos)
        return printable(what.substr(at + 2), 120);
    return printable(what, 120);
}

std::string plainExrError(const std::string& what)
{
    if (what.find("end of file") != std::string::npos || what.find("Unexpected end") != std::string::npos ||
        what.find("premature") != std::string::npos)
        return "the file ends early (truncated)";
    if (what.find("magic number") != std::string::npos || what.find("is not an image file") != std::string::npos)
        return "not an OpenEXR file";
    // "Cannot read image file \"/long/path.exr\". <reason>": the reason.
    if (what.rfind("Cannot ", 0) == 0) {
        const size_t open = what.find(" file \"");
        const size_t close = open == std::string::npos ? open : what.find("\".", open + 7);
        if (close != std::string::npos) {
            size_t reason = close + 2;
            while (reason < what.size() && what[reason] == ' ')
                ++reason;
            if (reason < what.size())
                return printable(what.substr(reason), 160);
        }
    }
    return printable(what, 160);
}

// One line, printable: control bytes become '?', long text is cut.
std::string printable(std::string text, size_t maxLength)
{
    while (!text.empty() && (text.back() == '\n' || text.back() == '\r'))
        text.pop_back();
    for (char& c : text)
        if ((unsigned char)c < 0x20 || c == 0x7f)
            c = c == '\n' ? ' ' : '?';
    if (text.size() > maxLength)
        text = text.substr(0, maxLength) + "...";
    return text;
}

}  // namespace io
}  // namespace strata
