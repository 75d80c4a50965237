// Strata baker: the one table of bake options.
//
// strata-bake's flags, the Python module's keywords, their types, defaults
// and meanings, and the checks on their values are this table: the CLI
// parses argv through it, Python parses its keywords through it and builds
// its docstring from it, `strata-bake --help` prints its usage from it and
// docs/CLI.md is generated from it (a test compares them), so none of them
// can drift from the others.
#pragma once

#include "strata/baker/bake_rig.h"
#include "strata/status.h"

#include <string>
#include <vector>

namespace strata {
namespace baker {

struct BakeOption {
    const char* flag;      ///< "--tolerance"
    const char* keyword;   ///< Python's name ("tolerance"); null: the flag is an alias of the entry before it
    const char* type;      ///< the Python type, for docs ("float | str")
    const char* value;     ///< the flag's value in the usage line ("E|P%"); null: the flag is a switch
    const char* fixed;     ///< a switch: the value it gives its keyword ("true", "false", "8"); else null
    const char* defaultText;  ///< the default, as a reader would write it
    const char* help;      ///< what it does, one sentence
    bool required;         ///< --high, --control, -o
};

/// A request with the defaults strata-bake and Python use (threads: every
/// core, at most 256).
BakeRequest defaultBakeRequest();

/// Every option, in the order of the usage line.
const std::vector<BakeOption>& bakeOptions();

/// The option with this flag ("--no-fit") or keyword ("fit"), or null.
const BakeOption* findBakeOption(const std::string& flagOrKeyword);

/// Sets `option` in `request` from its text (a flag's value, a switch's
/// fixed value, or a keyword's value written as text: "true"/"false" for a
/// bool, "A:B" for a pair of levels).  Messages name the option as `name`
/// (the flag in the CLI, the keyword in Python) and say what it expects.
Status applyBakeOption(BakeRequest* request, const BakeOption& option, const std::string& name,
                       const std::string& text);

/// strata-bake's usage lines, built from the table.
std::string bakeUsage();

/// The table as Markdown (docs/CLI.md) and as a Python docstring.
std::string bakeOptionsMarkdown();
std::string bakeOptionsDocstring();

}  // namespace baker
}  // namespace strata
