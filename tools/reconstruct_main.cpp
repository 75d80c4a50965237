// strata-reconstruct: writes a rig's displaced surface at level N.
//
//   strata-reconstruct RIG.glb --level N [--scheme linear|smooth]
//       [--anim NAME|INDEX] [--time SECONDS] [--frames START:END:FPS]
//       [--skinning linear|dq|segments] [--skeleton JOINTS.json] [--scale S]
//       [--no-displacement]
//       [--view EX,EY,EZ:TX,TY,TZ:FOVY_DEGREES:HEIGHT_PX [--pixel-error P]]
//       -o OUT.{obj,ply,glb,gltf}
// With --frames, OUT gets a 4-digit frame number before its extension.
//
// Pipelines and tests script this interface: keep it stable.
#include "cli.h"

#include "strata/io/file.h"
#include "strata/io/joint_file.h"
#include "strata/io/mesh_io.h"
#include "strata/io/reconstruct.h"
#include "strata/io/rig_io.h"
#include "strata/segment_deformer.h"

#include <chrono>
#include <filesystem>
#include <cmath>
#include <cstring>
#include <vector>

using namespace strata;

static const char* kUsage =
    "usage: strata-reconstruct RIG.{glb,gltf}|CONTROL.obj [--level N] [--scheme linear|smooth] [--anim NAME|INDEX]\n"
    "                          [--time SECONDS] [--frames START:END:FPS] [--skinning linear|dq|segments]\n"
    "                          [--skeleton JOINTS.json] [--scale S] [--no-displacement] [--static]\n"
    "                          [--view EX,EY,EZ:TX,TY,TZ:FOVY_DEGREES:HEIGHT_PX [--pixel-error P]]\n"
    "                          [--max-memory MB] -o OUT.{obj,ply,glb,gltf} [--version]\n"
    "  -o OUT.glb of a rig made from glTF writes its whole scene at level N: materials, skin,\n"
    "     skeleton and animations kept, so the detailed character plays in any glTF viewer;\n"
    "     --static (or --anim/--time) writes one posed mesh instead\n"
    "  --view: the adaptive mesh for that camera (eye, target, vertical field of view, viewport\n"
    "     height): each control face at the lowest level within --pixel-error pixels (default 1)\n"
    "     of level N wherever it lies in front of the eye, on screen or off (the view has no\n"
    "     width), stitched without cracks; in model space, posed as --anim/--time\n"
    "  --skinning segments: the paper's point-to-line deformer (eq. 6) from the joints alone\n"
    "  --skeleton: a joint file (JSON) that replaces the rig's skin; implies --skinning segments\n";

int main(int argc, char** argv)
{
    return cli::run("strata-reconstruct", [&]() -> int {
        std::string rigPath, outPath, anim, skeletonPath;
        bool haveMethod = false;
        int level = -1;
        bool haveScheme = false, displace = true, staticMesh = false;
        double maxMemoryMB = 2048.0;
        Scheme scheme = Scheme::Linear;
        float scale = 1.0f, time = 0.0f;
        bool frames = false, haveTime = false;
        float frameStart = 0.0f, frameEnd = 0.0f, fps = 30.0f;
        SkinningMethod method = SkinningMethod::Linear;
        bool haveView = false, havePixelError = false;
        ViewSpec view;
        float pixelError = 1.0f;
        for (int i = 1; i < argc; ++i) {
            const std::string a = argv[i];
            auto value = [&] { return cli::flagValue(argc, argv, &i); };
            if (a == "-h" || a == "--help") {
                std::fputs(kUsage, stdout);
                return 0;
            } else if (a == "--version") {
                std::printf("strata-reconstruct %s\n", cli::kVersion);
                return 0;
            } else if (a == "--max-memory") {
                maxMemoryMB = double(cli::parseInt(a, value(), 16, 1 << 24));
            } else if (a == "--static") {
                staticMesh = true;
            } else if (a == "--level") {
                level = cli::parseInt(a, value(), 0, kMaxLevel);
            } else if (a == "--scheme") {
                if (!parseScheme(value(), &scheme))
                    throw cli::Error("--scheme expects linear or smooth");
                haveScheme = true;
            } else if (a == "--anim") {
                anim = value();
            } else if (a == "--time") {
                time = cli::parseFloat(a, value());
                haveTime = true;
            } else if (a == "--frames") {
                const std::string v = value();
                float s0, s1, f;
                char tail;
                if (std::sscanf(v.c_str(), "%f:%f:%f%c", &s0, &s1, &f, &tail) != 3 || !(f > 0.0f) || !(s1 >= s0) ||
                    (s1 - s0) * f > 100000.0f)
                    throw cli::Error("--frames expects START:END:FPS with END >= START and FPS > 0, got \"" + v + "\"");
                frames = true;
                frameStart = s0;
                frameEnd = s1;
                fps = f;
            } else if (a == "--skinning") {
                method = cli::parseChoice<SkinningMethod>(a, value(), {{"linear", SkinningMethod::Linear},
                                                                   {"dq", SkinningMethod::DualQuaternion},
                                                                   {"segments", SkinningMethod::Segments}});
                haveMethod = true;
            } else if (a == "--skeleton") {
                skeletonPath = value();
            } else if (a == "--scale") {
                scale = cli::parseFloat(a, value());
            } else if (a == "--view") {
                const std::string v = value();
                glm::vec3 e, t;
                float fov, height;
                char tail;
                if (std::sscanf(v.c_str(), "%f,%f,%f:%f,%f,%f:%f:%f%c", &e.x, &e.y, &e.z, &t.x, &t.y, &t.z, &fov, &height,
                                &tail) != 8)
                    throw cli::Error("--view expects EX,EY,EZ:TX,TY,TZ:FOVY_DEGREES:HEIGHT_PX, got \"" +
                                     cli::printable(v, 80) + "\"");
                view.eye = e;
                view.target = t;
                view.fovYDegrees = fov;
                view.heightPx = height;
                if (!view.valid() || height > 1e6f)
                    throw cli::Error("--view " + cli::printable(v, 80) +
                                     ": the eye must differ from the target, the field of view lie in (0, 180) degrees "
                                     "and the height in (0, 1e6] pixels");
                haveView = true;
            } else if (a == "--pixel-error") {
                pixelError = cli::parseFloat(a, value());
                if (!(pixelError > 0.0f) || pixelError > 1e6f)
                    throw cli::Error("--pixel-error expects a number of pixels in (0, 1e6]");
                havePixelError = true;
            } else if (a == "--no-displacement") {
                displace = false;
            } else if (a == "-o" || a == "--output") {
                outPath = value();
            } else if (!a.empty() && a[0] == '-') {
                throw cli::Error("unknown option " + a + " (see --help)");
            } else if (rigPath.empty()) {
                rigPath = a;
            } else {
                throw cli::Error("more than one input rig given (" + rigPath + ", " + a + ")");
            }
        }
        if (rigPath.empty() || outPath.empty())
            throw cli::Error("an input rig and -o OUTPUT are required (see --help)");
        if (havePixelError && !haveView)
            throw cli::Error("--pixel-error needs --view (the camera the error is measured in)");
        if (haveView && frames)
            throw cli::Error("--view writes one frame: pass --time instead of --frames");

        Rig rig;
        Status st;
        if (io::extensionOf(rigPath) == ".obj") {
            // A bare control mesh (no displacement): with --skeleton, the
            // paper's deformer animates it directly.
            io::ObjReadInfo info;
            if (!(st = io::readObj(rigPath, &rig.mesh, &info)) || !(st = validateControlMesh(rig.mesh)))
                throw cli::Error(st.message().rfind(rigPath, 0) == 0 ? st.message() : rigPath + ": " + st.message());
            if (info.degenerate)
                rig.warnings.push_back(std::to_string(info.degenerate) +
                                       " triangles repeat a vertex (zero area) and are left out");
        } else {
            io::LoadOptions options;
            options.maxMemoryMB = maxMemoryMB;
            if (!(st = io::loadRig(rigPath, &rig, options)))
                throw cli::Error(st.message());
        }
        // What the surface would refuse (a dropped layer, another scheme),
        // before the map is read or a folder made.
        SurfaceOptions options;
        options.level = level;
        options.displace = displace;
        options.scheme = scheme;
        options.schemeGiven = haveScheme;
        options.scale = scale;
        if (Status c = Surface::check(rig, options); !c) {
            const bool otherScheme = haveScheme && displace && rig.hasDisplacement;
            throw cli::Error((otherScheme ? std::string("--scheme ") + schemeName(scheme) + ": " : std::string()) +
                             rigPath + ": " + c.message() +
                             (otherScheme ? " (pass --no-displacement to refine the bare cage in it)"
                                          : ": bake again, or pass --no-displacement for the plain mesh"));
        }
        if (!skeletonPath.empty()) {
            if (!(st = io::loadJointFile(skeletonPath, &rig.skeleton)))
                throw cli::Error(st.message());
            if (!(st = bindSkeletonWeights(&rig.skeleton, rig.mesh)))
                throw cli::Error(skeletonPath + ": " + st.message());
            if (!haveMethod)
                method = SkinningMethod::Segments;
        }
        if (std::filesystem::is_symlink(outPath))
            throw cli::Error(outPath + ": is a symbolic link; refusing to replace it (write to its target)");
        // By file identity, for the output and every frame of a sequence,
        // before any folder is made.
        std::vector<std::string> outputs = {outPath};
        if (frames) {
            const std::string e = io::extensionOf(outPath), stem = outPath.substr(0, outPath.size() - e.size());
            const int count = int(std::floor((frameEnd - frameStart) * fps + 1e-4f)) + 1;
            for (int f = 0; f < count; ++f) {
                char suffix[16];
                std::snprintf(suffix, sizeof(suffix), "_%04d", f);
                outputs.push_back(stem + suffix + e);
            }
        }
        for (const std::string& output : outputs)
            for (const std::string& input : {rigPath, skeletonPath})
                if (io::sameFile(output, input))
                    throw cli::Error(output + ": the output would overwrite the input " + input);
        // Memory before work: the plan, the map's texels and the output as
        // it is staged (measured peaks, io::reconstructionPeakBytes).
        {
            const int lvl = Surface::levelFor(rig, options);
            const Scheme s = Surface::schemeFor(rig, options);
            const bool posedOut = !rig.skeleton.empty() && (!anim.empty() || haveTime || frames);
            const std::string ext = io::extensionOf(outPath);
            const bool sceneOut = !frames && !posedOut && !staticMesh && !haveView && rig.source && skeletonPath.empty() &&
                                  (ext == ".glb" || ext == ".gltf");
            const double texels = rig.hasDisplacement && displace && rigNeedsMap(rig)
                                      ? double(rig.displacement.width) * double(rig.displacement.height)
                                      : 0.0;
            const double needMB = io::reconstructionPeakBytes(rig, s, lvl, ext, sceneOut, texels) / (1024.0 * 1024.0);
            if (needMB > maxMemoryMB)
                throw cli::Error(rigPath + ": level " + std::to_string(lvl) + " needs about " +
                                 std::to_string(long(needMB)) + " MB, over the " + std::to_string(long(maxMemoryMB)) +
                                 " MB budget (raise it with --max-memory MB)");
        }
        DisplacementMap map;
        const bool useMap = displace && rig.hasDisplacement;
        if (useMap && rigNeedsMap(rig) && !(st = io::loadRigDisplacementMap(rigPath, rig, &map)))
            throw cli::Error(st.message());
        scheme = Surface::schemeFor(rig, options);
        level = Surface::levelFor(rig, options);
        io::Pose pose;
        pose.time = time;
        pose.method = method;
        const bool skinned = !rig.skeleton.empty();
        if (!anim.empty()) {
            if (!skinned)
                throw cli::Error(rigPath + ": --anim given but the rig has no skin");
            pose.animation = findAnimation(rig.skeleton, anim);
            if (pose.animation < 0) {
                std::string names;
                for (const Animation& a : rig.skeleton.animations)
                    names += (names.empty() ? "" : ", ") + cli::printable(a.name, 40);
                throw cli::Error(rigPath + ": no animation \"" + cli::printable(anim, 40) + "\" (it has: " +
                                 (names.empty() ? "none" : cli::printable(names, 200)) + ")");
            }
        } else if (skinned && (haveTime || frames) && !rig.skeleton.animations.empty()) {
            pose.animation = 0;
        } else if (!skinned && (haveTime || frames)) {
            std::fprintf(stderr, "strata-reconstruct: note: %s is not skinned; writing its bind pose\n", rigPath.c_str());
        }
        for (const std::string& w : rig.warnings)
            std::fprintf(stderr, "strata-reconstruct: warning: %s: %s\n", rigPath.c_str(), cli::printable(w).c_str());

        const auto t0 = std::chrono::steady_clock::now();
        io::Reconstruction rec;
        // Without --anim/--time/--frames: the bind pose, in mesh space, as stored.
        const bool posed = skinned && (!anim.empty() || haveTime || frames);
        options.method = method;
        if (!(st = io::reconstruct(&rec, rig, useMap ? &map : nullptr, options, posed ? &pose : nullptr)))
            throw cli::Error(rigPath + ": " + st.message());
        const auto t1 = std::chrono::steady_clock::now();
        const std::string outExt = io::extensionOf(outPath);
        const bool scene = !frames && !posed && !staticMesh && !haveView && rig.source && skeletonPath.empty() &&
                           (outExt == ".glb" || outExt == ".gltf");
        // glTF draws a mesh without NORMAL with face normals: a rig whose
        // capture was drawn so (every part flat) keeps none in a glTF mesh.
        const bool normals = !(outExt == ".glb" || outExt == ".gltf") || !allPartsFlat(rig);
        std::error_code mkdirError;
        if (!io::directoryOf(outPath).empty())
            std::filesystem::create_directories(io::directoryOf(outPath), mkdirError);
        if (mkdirError)
            throw cli::Error(io::directoryOf(outPath) + ": cannot create the output folder (" + mkdirError.message() + ")");
        // Never write NaN or Inf: name the joint whose pose produced it.
        auto checkFinite = [&](const io::Pose* at) {
            for (const glm::vec3& p : rec.positions)
                if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z)) {
                    std::string culprit = "the control mesh or the map";
                    const std::vector<glm::mat4>& skin = rec.surface->skinMatrices();
                    if (skinned && at)
                        for (size_t j = 0; j < skin.size(); ++j) {
                            const glm::mat4& m = skin[j];
                            bool finite = true;
                            for (int k = 0; k < 16; ++k)
                                finite = finite && std::isfinite(m[k / 4][k % 4]);
                            if (!finite) {
                                const int node = rig.skeleton.skin.joints[j];
                                culprit = "joint " + std::to_string(j) + " (node " + std::to_string(node) + " \"" +
                                          cli::printable(rig.skeleton.nodes[size_t(node)].name, 40) +
                                          "\"), whose posed transform overflows";
                                break;
                            }
                        }
                    throw cli::Error(rigPath + ": the reconstruction is not finite" +
                                     (at ? " at time " + std::to_string(at->time) : std::string()) + ": caused by " +
                                     culprit + "; nothing written");
                }
        };
        if (haveView) {
            checkFinite(posed ? &pose : nullptr);
            const auto v0 = std::chrono::steady_clock::now();
            io::AdaptiveView adaptive;
            if (!(st = io::reconstructView(&adaptive, rec, view, pixelError)))
                throw cli::Error(rigPath + ": --view: " + st.message());
            const auto v1 = std::chrono::steady_clock::now();
            if (!(st = io::writeAdaptiveView(outPath, rec, adaptive, normals)))
                throw cli::Error(st.message());
            std::string levels;
            for (size_t l = 0; l < adaptive.facesPerLevel.size(); ++l)
                if (adaptive.facesPerLevel[l])
                    levels += (levels.empty() ? "" : ", ") + std::to_string(adaptive.facesPerLevel[l]) + " at " +
                              std::to_string(l);
            if (adaptive.splitFaces)
                levels += " (" + std::to_string(adaptive.splitFaces) + " of them as quarters, counted at their finest)";
            const AdaptiveFrame& frame = rec.surface->adaptiveFrame();
            std::fprintf(stderr,
                         "strata-reconstruct: %s adaptive to level %d (%s) within %g px: %zu vertices, %zu triangles "
                         "(level %d everywhere: %zu vertices); control faces %s; largest deviation from level %d in "
                         "front of the eye %.3f px; %.1f ms -> %s\n",
                         rigPath.c_str(), level, schemeName(scheme), double(pixelError), frame.vertexCount(),
                         frame.triangleCount(), level, rec.positions.size(), levels.c_str(), level,
                         double(adaptive.maxPixelError), std::chrono::duration<double, std::milli>(v1 - v0).count(),
                         outPath.c_str());
            return 0;
        }
        if (!frames) {
            checkFinite(posed ? &pose : nullptr);
            std::vector<std::string> notes;
            if (!(st = scene ? io::writeReconstructedScene(outPath, rig, rec, &notes)
                             : io::writeReconstruction(outPath, rec, normals)))
                throw cli::Error(st.message());
            for (const std::string& n : notes)
                std::fprintf(stderr, "strata-reconstruct: note: %s: %s\n", outPath.c_str(), n.c_str());
            std::fprintf(stderr, "strata-reconstruct: %s level %d (%s): %zu vertices, %zu triangles in %.1f ms -> %s\n",
                         rigPath.c_str(), level, schemeName(scheme), rec.positions.size(), rec.surface->triangleCount(),
                         std::chrono::duration<double, std::milli>(t1 - t0).count(), outPath.c_str());
            return 0;
        }
        // Frame sequence: one plan, one animator, a file per frame.
        const std::string ext = io::extensionOf(outPath);
        const std::string base = outPath.substr(0, outPath.size() - ext.size());
        const int count = int(std::floor((frameEnd - frameStart) * fps + 1e-4f)) + 1;
        std::vector<std::string> written;
        for (int f = 0; f < count; ++f) {
            pose.time = frameStart + float(f) / fps;
            if (skinned && !(st = io::reconstructPose(&rec, pose)))
                throw cli::Error(rigPath + ": " + st.message());
            checkFinite(&pose);
            char suffix[16];
            std::snprintf(suffix, sizeof(suffix), "_%04d", f);
            const std::string framePath = base + suffix + ext;
            if (!(st = io::writeReconstruction(framePath, rec, normals))) {
                for (const std::string& p : written)
                    std::remove(p.c_str());
                throw cli::Error(st.message());
            }
            written.push_back(framePath);
        }
        std::fprintf(stderr, "strata-reconstruct: %s level %d: %d frames %.3f..%.3f s at %.3g fps -> %s_NNNN%s\n",
                     rigPath.c_str(), level, count, double(frameStart), double(frameEnd), double(fps), base.c_str(),
                     ext.c_str());
        return 0;
    });
}
