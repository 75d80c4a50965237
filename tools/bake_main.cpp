// strata-bake: captured high-resolution mesh + control mesh -> one
// self-contained control rig (paper 2.1-2.3, 3.2).  Parses the command line
// into a baker::BakeRequest, calls baker::bakeRig and prints what it
// returns; the pipeline itself lives in baker/src/bake_rig.cpp.
#include "cli.h"

#include "strata/baker/bake_options.h"
#include "strata/baker/bake_rig.h"

#include <algorithm>
#include <chrono>
#include <mutex>
#include <cstdio>
#include <string>
#include <thread>

#include <unistd.h>

using namespace strata;

namespace {

// What --help adds to the usage line the option table builds (every
// option's meaning, type and default: docs/CLI.md, or --help-options).
const char* kHelp =
    "--tolerance (default 0.01%: RMS distance over the diagonal, both directions) picks the\n"
    "smallest map size and level that reach it in the closed loop (--size forces a size), and\n"
    "for --control auto the cage faces of the smallest rig that does (--control-faces fixes\n"
    "the count).\n"
    "The rig is one self-contained file: control mesh, UVs, skin, animations and the\n"
    "displacement layer (STRATA_layered_displacement).  --exr, --png8/--png16 and --layers\n"
    "also write the map beside it for pipelines.  Every option: strata-bake --help-options\n"
    "(the same table as docs/CLI.md and Python's help(strata.bake)).\n";

// Fills the request from the command line through the option table; false
// when the run is done (--help, --version).  Bad flags throw cli::Error.
bool parseArgs(int argc, char** argv, baker::BakeRequest* r)
{
    *r = baker::defaultBakeRequest();
    for (int i = 1; i < argc; ++i) {
        const std::string a = argv[i];
        if (a == "-h" || a == "--help") {
            std::fputs((baker::bakeUsage() + kHelp).c_str(), stdout);
            return false;
        } else if (a == "--help-options") {
            std::fputs(baker::bakeOptionsMarkdown().c_str(), stdout);
            return false;
        } else if (a == "--version") {
            std::printf("strata-bake %s\n", cli::kVersion);
            return false;
        }
        const baker::BakeOption* option = a.size() > 1 && a[0] == '-' ? baker::findBakeOption(a) : nullptr;
        if (!option)
            throw cli::Error("unknown argument " + a + " (see --help)");
        const std::string text = option->value ? cli::flagValue(argc, argv, &i) : std::string(option->fixed);
        if (Status st = baker::applyBakeOption(r, *option, a, text); !st)
            throw cli::Error(st.message());
    }
    if (r->high.empty() || r->control.empty() || r->output.empty())
        throw cli::Error("--high, --control and -o are required (see --help)");
    return true;
}

}  // namespace

int main(int argc, char** argv)
{
    return cli::run("strata-bake", [&]() -> int {
        baker::BakeRequest request;
        if (!parseArgs(argc, argv, &request))
            return 0;
        // One line per stage (a log reads them as they are); on a terminal,
        // below them, the percentage done and an ETA, rewritten in place.
        const bool terminal = ::isatty(2) == 1;
        const auto start = std::chrono::steady_clock::now();
        std::mutex lines;
        double done = 0.0;
        auto status = [&]() {
            if (!terminal || !(done > 0.0))
                return;
            const double elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
            std::fprintf(stderr, "\r\033[Kstrata-bake: %3.0f%% done, about %.0f s left", 100.0 * done,
                         elapsed * (1.0 - done) / done);
            std::fflush(stderr);
        };
        const baker::BakeProgress progress = [&](const char* stage, double seconds) {
            std::lock_guard<std::mutex> lock(lines);
            if (terminal)
                std::fputs("\r\033[K", stderr);
            if (seconds < 0.0)
                std::fprintf(stderr, "strata-bake: %s...\n", stage);
            else
                std::fprintf(stderr, "strata-bake: %s done in %.1f s\n", stage, seconds);
            status();
        };
        const baker::BakeFraction fraction = [&](double f) {
            std::lock_guard<std::mutex> lock(lines);
            done = f;
            status();
        };
        baker::BakeResult result;
        const Status st = baker::bakeRig(request, &result, &progress, &fraction);
        if (terminal && done > 0.0)
            std::fputs("\r\033[K", stderr);
        for (const std::string& w : result.warnings)
            std::fprintf(stderr, "strata-bake: warning: %s\n", cli::printable(w).c_str());
        if (!st)
            throw cli::Error(st.message());
        // With --report -, stdout carries the JSON and the summary goes to stderr.
        std::fputs(result.summary.c_str(), request.report == "-" ? stderr : stdout);
        if (request.report == "-")
            std::fputs(result.report.c_str(), stdout);
        return 0;
    });
}
