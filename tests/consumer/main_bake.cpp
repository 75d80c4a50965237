// Uses the installed baker library: bakes a capture given on the command
// line onto its own cage chosen automatically, as strata-bake --control auto.
#include <strata/baker/bake_rig.h>

#include <cstdio>

int main(int argc, char** argv)
{
    if (argc < 3)
        return 2;
    strata::baker::BakeRequest request;
    request.high = argv[1];
    request.control = "auto";
    request.output = argv[2];
    strata::baker::BakeResult result;
    const strata::Status st = strata::baker::bakeRig(request, &result);
    if (!st) {
        std::fprintf(stderr, "%s\n", st.message().c_str());
        return 1;
    }
    std::printf("baked %s: level %d, %zu files\n", argv[2], result.recommendedLevel, result.written.size());
    return result.recommendedLevel >= 0 && !result.written.empty() ? 0 : 1;
}
