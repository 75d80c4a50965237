// Strata baker: the whole bake as one library call.
//
// bakeRig() owns the pipeline strata-bake runs: read the capture and the
// control mesh (or simplify the capture when the control is "auto"), lay
// out UVs, choose the map size, level and scheme from the tolerance by
// measuring the closed loop, bake the map, encode the rig and measure it as
// a loader reads it (all in memory), then write it (and any extra outputs)
// atomically.  Tools and the Python
// module parse their arguments into a BakeRequest, call it and print the
// result; nothing here prints.
#pragma once

#include "strata/baker/bake.h"
#include "strata/plan.h"
#include "strata/status.h"

#include <atomic>
#include <functional>
#include <string>
#include <vector>

namespace strata {
namespace baker {

/// What to bake.  Defaults are strata-bake's: a compact rig that reaches
/// 0.01% of the diagonal where the inputs allow.
struct BakeRequest {
    std::string high;        ///< captured mesh: .obj .ply .stl .off .glb .gltf
    std::string control;     ///< control mesh or rig (.obj .glb .gltf), or "auto"
    std::string output;      ///< RIG.glb or RIG.gltf
    /// "auto" control: face count (0: from the tolerance, the smallest rig of 200.. a fifth of the
    /// capture's faces that reaches it, predicted from a first try at a fiftieth; none: the capture itself)
    size_t controlFaces = 0;
    std::string uv;          ///< "keep", "auto", or "" (keep the control's UVs when they can carry a map)
    BakeOptions options;     ///< map size (0: from the tolerance), scheme, overlap policy, threads
    bool schemeGiven = false;  ///< options.scheme was chosen; else the bake measures both
    double tolerance = 1e-4; ///< RMS distance / diagonal the map size and level aim for (0: the paper's rules)
    int errorFrom = -2, errorTo = -2;  ///< closed-loop levels to report; -2: around the recommended one, -1: none
    std::string skeleton;    ///< optional joint file (paper 2.4) that becomes the rig's skin
    std::string mapCoding = "vertex";  ///< "vertex" (per refined vertex) or "png"
    bool compress = true;    ///< false: plain accessors whatever meshCoding says (--no-compress)
    /// The control mesh's coding in a .glb: "plain" accessors (the default:
    /// every glTF tool opens them, Blender 3.4 and gltfpack included),
    /// "meshopt" (EXT_meshopt_compression) or "draco" (a bare cage as
    /// KHR_draco_mesh_compression, other vertex data meshopt-coded): smaller
    /// files that three.js, Babylon.js and Strata read, but Debian's Blender
    /// 3.4 and gltfpack do not.
    std::string meshCoding = "plain";
    bool exr = false;        ///< also write RIG.exr (half, or float with floatExr)
    bool floatExr = false;
    int pngBits = 0;         ///< 8 or 16: also write the eq. 12 quantised PNG beside the rig
    bool layers = false;     ///< also write RIG_layers.png (surface layers per texel)
    double maxMemoryMB = 2048.0;  ///< refuse work estimated past this
    bool closeHoles = true;  ///< close a plain control mesh's holes where the capture is closed
    bool fitCage = true;     ///< move a bare cage's vertices so its base surface fits the capture (a glTF control's never move)
    std::string report;      ///< also write the JSON report here ("" none, "-" only into BakeResult::report)
    /// When it becomes true (from any thread), the bake stops at its next
    /// stage boundary and returns StatusCode::Cancelled, writing nothing
    /// (Python sets it on Ctrl-C).  Null: not cancellable.
    const std::atomic<bool>* cancel = nullptr;
};

/// What came out.
struct BakeResult {
    std::string summary;              ///< the human-readable summary strata-bake prints
    std::string report;               ///< the JSON report (always filled on success)
    std::vector<std::string> warnings;  ///< tolerated problems, one line each
    std::vector<std::string> written;   ///< files written, in order
    int recommendedLevel = -1;
    Scheme scheme = Scheme::Linear;
    double rms = -1.0;                ///< closed-loop RMS / diagonal at the recommended level (-1: not measured)
};

/// Called with a stage name when it has run for a second (seconds < 0), and
/// again when it ends (seconds >= 0).  Called from a helper thread.
using BakeProgress = std::function<void(const char* stage, double seconds)>;

/// Called as each phase of the bake ends, from the bake's own thread, with
/// an estimate of the fraction done (0..1, never decreasing): each phase
/// weighs what it took on the 100k scan, and --control auto's search
/// counts on three tries until it knows better.  For a percentage and an
/// ETA (elapsed * (1 - f) / f).
using BakeFraction = std::function<void(double fraction)>;

/// Runs the bake.  Outputs are staged beside their targets and renamed into
/// place only when everything succeeded: a failure leaves no file behind
/// and never touches one that existed before.  Errors are one line naming
/// the file and the problem.
Status bakeRig(const BakeRequest& request, BakeResult* result, const BakeProgress* progress = nullptr,
               const BakeFraction* fraction = nullptr);

}  // namespace baker
}  // namespace strata
