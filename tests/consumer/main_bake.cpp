// Uses the installed baker library: bakes a capture onto a control mesh or
// rig given on the command line, as strata-bake does.
#include <strata/baker/bake_rig.h>

#include <cstdio>

int main(int argc, char** argv)
{
    if (argc < 4)
        return 2;
    strata::baker::BakeRequest request;
    request.high = argv[1];
    request.control = argv[2];
    request.output = argv[3];
    strata::baker::BakeResult result;
    const strata::Status st = strata::baker::bakeRig(request, &result);
    if (!st) {
        std::fprintf(stderr, "%s\n", st.message().c_str());
        return 1;
    }
    std::printf("baked %s: level %d, %zu files\n", argv[3], result.recommendedLevel, result.written.size());
    return result.recommendedLevel >= 0 && !result.written.empty() ? 0 : 1;
}
