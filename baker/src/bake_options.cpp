// The one table of bake options (bake_options.h).
#include "strata/baker/bake_options.h"

#include <algorithm>
#include <cstdlib>
#include <cstring>
#include <thread>

namespace strata {
namespace baker {

namespace {

Status bad(const std::string& name, const std::string& expects, const std::string& text)
{
    return Status(StatusCode::InvalidArgument, name + " expects " + expects + ", got \"" + text + "\"");
}

bool parseInt(const std::string& text, long lo, long hi, long* out)
{
    char* end = nullptr;
    const long v = std::strtol(text.c_str(), &end, 10);
    if (text.empty() || *end || v < lo || v > hi)
        return false;
    *out = v;
    return true;
}

bool parseNumber(const std::string& text, double* out)
{
    char* end = nullptr;
    const double v = std::strtod(text.c_str(), &end);
    if (text.empty() || *end || !(v == v) || v > 1e300 || v < -1e300)
        return false;
    *out = v;
    return true;
}

bool parseBool(const std::string& text, bool* out)
{
    if (text == "true" || text == "True" || text == "1") {
        *out = true;
        return true;
    }
    if (text == "false" || text == "False" || text == "0") {
        *out = false;
        return true;
    }
    return false;
}

const std::vector<BakeOption> kOptions = {
    {"--high", "high", "str", "HIGH.{obj,ply,stl,off,glb,gltf}", nullptr, "required",
     "The captured high-resolution mesh to bake.", true},
    {"--control", "control", "str", "CONTROL.{obj,glb,gltf}|auto", nullptr, "required",
     "The control mesh or rig (a skinned glTF keeps its skin and animations), or auto to simplify the capture "
     "into one.", true},
    {"-o", "out", "str", "RIG.{glb,gltf}", nullptr, "required",
     "The rig to write: one self-contained file (control mesh, UVs, skin, animations, the displacement layer).",
     true},
    {"--tolerance", "tolerance", "float | str", "E|P%", nullptr, "0.0001 (0.01%)",
     "RMS distance over the diagonal, both directions, that the smallest map size and level must reach in the "
     "closed loop (and, for --control auto, the smallest rig's cage faces); a fraction or a percentage; 0: the "
     "paper's rules.", false},
    {"--control-faces", "control_faces", "int", "K", nullptr, "from the tolerance",
     "--control auto: the cage's face count (4..10000000), instead of the smallest rig's that reaches the "
     "tolerance.", false},
    {"--uv", "uv", "str", "keep|auto", nullptr, "keep the control's UVs when they can carry a map",
     "auto: lay out an atlas even when the control has UVs.", false},
    {"--size", "size", "int | str", "auto|N", nullptr, "auto (from the tolerance)",
     "Force the map's side, 16..8192 texels.", false},
    {"--scheme", "scheme", "str", "linear|smooth", nullptr, "measured: the one that reaches the tolerance smaller",
     "The subdivision scheme the displacement is baked against: linear (the paper's) or smooth (Loop limit).",
     false},
    {"--overlap", "overlap", "str", "max|nearest", nullptr, "max",
     "Where several surface layers map to one texel: the largest distance (the paper's rule) or the nearest.",
     false},
    {"--threads", "threads", "int", "N", nullptr, "all cores", "Threads to bake on, 1..256.", false},
    {"--error-levels", "error_levels", "tuple[int, int] | int | str", "N|A:B|none", nullptr,
     "around the recommended level", "Closed-loop levels to report: 0..N, A..B, or none.", false},
    {"--skeleton", "skeleton", "str", "JOINTS.json", nullptr, "none",
     "A joint file (paper 2.4) that becomes the rig's skin.", false},
    {"--map-coding", "map_coding", "str", "vertex|png", nullptr, "vertex",
     "How the rig stores the map: its samples at the recommended level's refined vertices, quantised and "
     "zstd-coded, or an embedded grey PNG (paper eq. 12).", false},
    {"--mesh-coding", "mesh_coding", "str", "plain|meshopt|draco", nullptr, "plain",
     "The control mesh's coding: plain accessors (every glTF tool opens them, Blender 3.4 and gltfpack "
     "included), or meshopt / draco, smaller files that three.js, Babylon.js and Strata read.", false},
    {"--no-compress", "compress", "bool", nullptr, "false", "true",
     "false: plain accessors whatever --mesh-coding says.", false},
    {"--exr", "exr", "bool", nullptr, "true", "false", "Also write the map as RIG.exr (half) for pipelines.",
     false},
    {"--float", "float_exr", "bool", nullptr, "true", "false", "The EXR's texels as 32-bit floats.", false},
    {"--png8", "png", "int", nullptr, "8", "0 (none)",
     "Also write the map as an 8- or 16-bit grey PNG beside the rig (paper eq. 12).", false},
    {"--png16", nullptr, "int", nullptr, "16", "", "", false},
    {"--layers", "layers", "bool", nullptr, "true", "false",
     "Also write RIG_layers.png: the surface layers that map to each texel.", false},
    {"--keep-holes", "close_holes", "bool", nullptr, "false", "true",
     "false: leave a plain control mesh's holes open where the capture is closed.", false},
    {"--no-fit", "fit", "bool", nullptr, "false", "true",
     "false: keep a bare cage's vertices where they are instead of fitting its base surface to the capture.",
     false},
    {"--max-memory", "max_memory", "int", "MB", nullptr, "2048",
     "Refuse, before the work, a bake estimated to need more memory than this (16..16777216 MB).", false},
    {"--report", "report", "str", "REPORT.json|-", nullptr, "none",
     "Also write the JSON report (- : to standard output).", false},
};

}  // namespace

const std::vector<BakeOption>& bakeOptions()
{
    return kOptions;
}

BakeRequest defaultBakeRequest()
{
    BakeRequest r;
    r.options.threads = int(std::clamp(std::thread::hardware_concurrency(), 1u, 256u));
    return r;
}

const BakeOption* findBakeOption(const std::string& name)
{
    for (const BakeOption& o : kOptions)
        if (name == o.flag || (o.keyword && name == o.keyword))
            return &o;
    if (name == "--output")
        return findBakeOption("-o");
    return nullptr;
}

Status applyBakeOption(BakeRequest* r, const BakeOption& option, const std::string& name, const std::string& text)
{
    const std::string flag = option.flag;
    long i = 0;
    double x = 0.0;
    bool b = false;
    auto choice = [&](std::string* field, std::initializer_list<const char*> words) {
        std::string expects;
        size_t k = 0;
        for (const char* w : words) {
            if (text == w) {
                *field = text;
                return Status::ok();
            }
            expects += (k == 0 ? "" : k + 1 == words.size() ? " or " : ", ") + std::string(w);
            ++k;
        }
        return bad(name, expects, text);
    };
    if (flag == "--high") {
        r->high = text;
    } else if (flag == "--control") {
        r->control = text;
    } else if (flag == "-o") {
        r->output = text;
    } else if (flag == "--tolerance") {
        const bool percent = !text.empty() && text.back() == '%';
        if (!parseNumber(percent ? text.substr(0, text.size() - 1) : text, &x) ||
            !((percent ? x / 100.0 : x) >= 0.0 && (percent ? x / 100.0 : x) < 1.0))
            return bad(name, "a fraction of the diagonal in [0, 1) or a percentage (0.01%)", text);
        r->tolerance = percent ? x / 100.0 : x;
    } else if (flag == "--control-faces") {
        if (!parseInt(text, 4, 10000000, &i))
            return bad(name, "an integer in 4..10000000", text);
        r->controlFaces = size_t(i);
    } else if (flag == "--uv") {
        return choice(&r->uv, {"keep", "auto"});
    } else if (flag == "--size") {
        if (text == "auto" || text == "0")
            r->options.size = 0;
        else if (parseInt(text, 16, 8192, &i))
            r->options.size = int(i);
        else
            return bad(name, "auto or an integer in 16..8192", text);
    } else if (flag == "--scheme") {
        if (!parseScheme(text, &r->options.scheme))
            return bad(name, "linear or smooth", text);
        r->schemeGiven = true;
    } else if (flag == "--overlap") {
        std::string v;
        if (Status st = choice(&v, {"max", "nearest"}); !st)
            return st;
        r->options.overlap = v == "max" ? OverlapPolicy::Max : OverlapPolicy::Nearest;
    } else if (flag == "--threads") {
        if (!parseInt(text, 1, 256, &i))
            return bad(name, "an integer in 1..256", text);
        r->options.threads = int(i);
    } else if (flag == "--error-levels") {
        const size_t colon = text.find(':');
        long from = 0, to = 0;
        if (text == "none") {
            r->errorFrom = r->errorTo = -1;
        } else if (colon == std::string::npos && parseInt(text, -1, kMaxLevel, &to)) {
            r->errorFrom = 0;
            r->errorTo = int(to);
        } else if (colon != std::string::npos && parseInt(text.substr(0, colon), 0, kMaxLevel, &from) &&
                   parseInt(text.substr(colon + 1), from, kMaxLevel, &to)) {
            r->errorFrom = int(from);
            r->errorTo = int(to);
        } else {
            return bad(name, "N, A:B (levels 0.." + std::to_string(kMaxLevel) + ") or none", text);
        }
    } else if (flag == "--skeleton") {
        r->skeleton = text;
    } else if (flag == "--map-coding") {
        return choice(&r->mapCoding, {"vertex", "png"});
    } else if (flag == "--mesh-coding") {
        return choice(&r->meshCoding, {"plain", "meshopt", "draco"});
    } else if (flag == "--png8" || flag == "--png16") {
        if (!parseInt(text, 0, 16, &i) || (i != 0 && i != 8 && i != 16))
            return bad(name, "0, 8 or 16", text);
        r->pngBits = int(i);
    } else if (flag == "--max-memory") {
        if (!parseInt(text, 16, 1L << 24, &i))
            return bad(name, "an integer in 16..16777216 (MB)", text);
        r->maxMemoryMB = double(i);
    } else if (flag == "--report") {
        r->report = text;
    } else {
        // The switches: a bool keyword.
        if (!parseBool(text, &b))
            return bad(name, "true or false", text);
        if (flag == "--no-compress")
            r->compress = b;
        else if (flag == "--exr")
            r->exr = b;
        else if (flag == "--float")
            r->floatExr = b;
        else if (flag == "--layers")
            r->layers = b;
        else if (flag == "--keep-holes")
            r->closeHoles = b;
        else if (flag == "--no-fit")
            r->fitCage = b;
        else
            return Status(StatusCode::InvalidArgument, "unknown option " + name);
    }
    return Status::ok();
}

std::string bakeUsage()
{
    std::string out = "usage: strata-bake", line;
    const size_t indent = 19, width = 100;
    size_t column = out.size();
    for (size_t k = 0; k < kOptions.size(); ++k) {
        const BakeOption& o = kOptions[k];
        std::string item = o.flag;
        // An alias joins the entry before it: [--png8|--png16].
        while (k + 1 < kOptions.size() && !kOptions[k + 1].keyword)
            item += std::string("|") + kOptions[++k].flag;
        if (o.value)
            item += std::string(" ") + o.value;
        if (!o.required)
            item = "[" + item + "]";
        if (column + 1 + item.size() > width) {
            out += "\n" + std::string(indent, ' ');
            column = indent;
        } else {
            out += " ";
            column += 1;
        }
        out += item;
        column += item.size();
    }
    return out + " [--version]\n";
}

std::string bakeOptionsMarkdown()
{
    std::string out = "| flag | Python keyword | type | default | what it does |\n|---|---|---|---|---|\n";
    for (size_t k = 0; k < kOptions.size(); ++k) {
        const BakeOption& o = kOptions[k];
        std::string flag = std::string("`") + o.flag + (o.value ? std::string(" ") + o.value : std::string()) + "`";
        while (k + 1 < kOptions.size() && !kOptions[k + 1].keyword)
            flag += std::string(", `") + kOptions[++k].flag + "`";
        std::string help = o.help;
        for (size_t p = help.find('|'); p != std::string::npos; p = help.find('|', p + 2))
            help.replace(p, 1, "\\|");
        std::string type = o.type;
        for (size_t p = type.find('|'); p != std::string::npos; p = type.find('|', p + 2))
            type.replace(p, 1, "\\|");
        out += "| " + flag + " | `" + o.keyword + "` | " + type + " | " + o.defaultText + " | " + help + " |\n";
    }
    return out;
}

std::string bakeOptionsDocstring()
{
    std::string out;
    for (const BakeOption& o : kOptions) {
        if (!o.keyword || o.required)
            continue;
        out += std::string("    ") + o.keyword + " (" + o.type + ", default " + o.defaultText + "; " + o.flag +
               "): " + o.help + "\n";
    }
    return out;
}

}  // namespace baker
}  // namespace strata
