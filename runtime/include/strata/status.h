// Strata runtime: error reporting without exceptions.
//
// Every runtime entry point that can fail returns a Status.  A default
// Status is success; a failed one carries a code and a one-line message that
// names the offending input.  The runtime never throws across its API.
#pragma once

#include <string>
#include <utility>

namespace strata {

enum class StatusCode {
    Ok = 0,
    InvalidArgument,  ///< a caller-supplied value is out of range or inconsistent
    InvalidData,      ///< baked or loaded data is malformed (never trusted)
    Unsupported,      ///< valid input the runtime does not handle (e.g. a newer format version)
    IoError,          ///< a file could not be read or written (io layer only)
    Cancelled,        ///< the caller cancelled the work (a bake's cancel flag); nothing was written
};

class Status {
public:
    Status() = default;
    Status(StatusCode code, std::string message) : code_(code), message_(std::move(message)) {}

    static Status ok() { return Status(); }

    bool isOk() const { return code_ == StatusCode::Ok; }
    explicit operator bool() const { return isOk(); }
    StatusCode code() const { return code_; }
    const std::string& message() const { return message_; }

private:
    StatusCode code_ = StatusCode::Ok;
    std::string message_;
};

}  // namespace strata
