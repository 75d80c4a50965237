// Python bindings: the asset pipeline's view of Strata.
//
//   import strata
//   report = strata.bake("scan.obj", "cage.obj", "rig.glb", tolerance=1e-4)
//   rig = strata.load_rig("rig.glb")
//   vertices, triangles = rig.reconstruct(level=3)
//
// Errors raise strata.Error (a RuntimeError) carrying the tools' one-line
// message.  Arrays are numpy float32 [N, 3] and uint32 [M, 3] that own the
// reconstruction's buffers (no copy).
#include "strata/baker/bake_rig.h"
#include "strata/io/reconstruct.h"
#include "strata/io/rig_io.h"

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <memory>
#include <string>
#include <vector>

namespace py = pybind11;
using namespace strata;

namespace {

struct StrataError : std::runtime_error {
    using std::runtime_error::runtime_error;
};

void check(const Status& st)
{
    if (!st)
        throw StrataError(st.message());
}

// A loaded rig and its map, ready to reconstruct.
struct PyRig {
    std::string path;
    Rig rig;
    DisplacementMap map;

    std::vector<std::string> jointNames() const
    {
        std::vector<std::string> names;
        for (int node : rig.skeleton.skin.joints)
            names.push_back(node >= 0 && size_t(node) < rig.skeleton.nodes.size() ? rig.skeleton.nodes[size_t(node)].name
                                                                                : std::string());
        return names;
    }
    std::vector<std::string> animations() const
    {
        std::vector<std::string> names;
        for (const Animation& a : rig.skeleton.animations)
            names.push_back(a.name);
        return names;
    }

    py::tuple reconstruct(py::object level, py::object animation, py::object time, bool displacement) const
    {
        // As strata-reconstruct: what the surface refuses (a glTF whose layer
        // a tool dropped), refused before any work, with this binding's advice.
        SurfaceOptions options;
        options.level = level.is_none() ? -1 : level.cast<int>();
        options.displace = displacement;
        if (Status c = Surface::check(rig, options); !c)
            throw StrataError(path + ": " + c.message() +
                              (c.code() == StatusCode::InvalidData
                                   ? ": bake again, or pass displacement=False for the plain mesh"
                                   : ""));
        io::Pose pose;
        bool posed = false;
        if (!animation.is_none()) {
            const std::string name = animation.cast<std::string>();
            pose.animation = findAnimation(rig.skeleton, name);
            if (pose.animation < 0)
                throw StrataError(path + ": no animation \"" + name + "\"");
            posed = true;
        }
        if (!time.is_none()) {
            pose.time = time.cast<float>();
            if (pose.animation < 0 && !rig.skeleton.animations.empty())
                pose.animation = 0;
            posed = true;
        }
        if (posed && rig.skeleton.empty())
            throw StrataError(path + ": the rig has no skin to animate");
        auto rec = std::make_unique<io::Reconstruction>();
        {
            py::gil_scoped_release unlocked;
            check(io::reconstruct(rec.get(), rig, &map, options, posed ? &pose : nullptr));
        }
        // The arrays view the reconstruction, which a capsule keeps alive.
        io::Reconstruction* owner = rec.release();
        py::capsule keep(owner, [](void* p) { delete static_cast<io::Reconstruction*>(p); });
        const py::ssize_t n = py::ssize_t(owner->positions.size()), m = py::ssize_t(owner->surface->triangleCount());
        py::array_t<float> vertices({n, py::ssize_t(3)}, {py::ssize_t(3 * sizeof(float)), py::ssize_t(sizeof(float))},
                                    reinterpret_cast<const float*>(owner->positions.data()), keep);
        py::array_t<uint32_t> triangles({m, py::ssize_t(3)},
                                        {py::ssize_t(3 * sizeof(uint32_t)), py::ssize_t(sizeof(uint32_t))},
                                        owner->surface->triangles().data(), keep);
        return py::make_tuple(vertices, triangles);
    }
};

std::unique_ptr<PyRig> loadRig(const std::string& path)
{
    auto r = std::make_unique<PyRig>();
    r->path = path;
    check(io::loadRig(path, &r->rig));
    if (rigNeedsMap(r->rig))
        check(io::loadRigDisplacementMap(path, r->rig, &r->map));
    return r;
}

py::dict bake(const std::string& high, const std::string& control, const std::string& out, const py::kwargs& kw)
{
    baker::BakeRequest req;
    req.high = high;
    req.control = control;
    req.output = out;
    for (const auto& item : kw) {
        const std::string key = item.first.cast<std::string>();
        const py::handle v = item.second;
        if (key == "control_faces")
            req.controlFaces = v.cast<size_t>();
        else if (key == "uv")
            req.uv = v.cast<std::string>();
        else if (key == "scheme") {
            if (!parseScheme(v.cast<std::string>(), &req.options.scheme))
                throw StrataError("scheme expects \"linear\" or \"smooth\"");
            req.schemeGiven = true;
        } else if (key == "threads") {
            req.options.threads = v.cast<int>();
            if (req.options.threads < 1 || req.options.threads > 256)  // as strata-bake --threads
                throw StrataError("threads expects 1..256, not " + std::to_string(req.options.threads));
        } else if (key == "tolerance") {
            req.tolerance = v.cast<double>();
            if (!(req.tolerance >= 0.0 && req.tolerance < 1.0))  // as strata-bake --tolerance
                throw StrataError("tolerance expects a fraction of the diagonal in [0, 1)");
        } else if (key == "size") {
            req.options.size = v.cast<int>();
            if (req.options.size != 0 && (req.options.size < 16 || req.options.size > 8192))  // as --size
                throw StrataError("size expects 0 (automatic) or 16..8192, not " + std::to_string(req.options.size));
        }
        else if (key == "map_coding")
            req.mapCoding = v.cast<std::string>();
        else if (key == "mesh_coding")
            req.meshCoding = v.cast<std::string>();
        else if (key == "compress")
            req.compress = v.cast<bool>();
        else if (key == "exr")
            req.exr = v.cast<bool>();
        else if (key == "skeleton")
            req.skeleton = v.cast<std::string>();
        else if (key == "close_holes")
            req.closeHoles = v.cast<bool>();
        else if (key == "fit")
            req.fitCage = v.cast<bool>();
        else if (key == "max_memory")
            req.maxMemoryMB = v.cast<double>();
        else if (key == "report")
            req.report = v.cast<std::string>();
        else if (key == "error_levels") {
            const py::tuple t = v.cast<py::tuple>();
            req.errorFrom = t[0].cast<int>();
            req.errorTo = t[1].cast<int>();
        } else
            throw StrataError("bake() got an unknown option \"" + key + "\"");
    }
    baker::BakeResult result;
    Status st;
    {
        py::gil_scoped_release unlocked;
        st = baker::bakeRig(req, &result);
    }
    check(st);
    py::dict report = py::module_::import("json").attr("loads")(result.report);
    report["warnings"] = result.warnings;
    report["written"] = result.written;
    report["summary"] = result.summary;
    return report;
}

}  // namespace

PYBIND11_MODULE(strata, m)
{
    m.doc() = "Strata: layered animation with displacement maps (bake, load, reconstruct)";
    // pybind11 looks numpy's C API up in a function-local static the first
    // time an array is made, importing numpy, which lets go of the GIL: a
    // second thread that holds the GIL then waits on the static's guard
    // forever.  Made here, under the import lock, before any thread can race.
    (void)py::array_t<float>(0);
    m.attr("__version__") = STRATA_VERSION;
    py::register_exception<StrataError>(m, "Error", PyExc_RuntimeError);
    m.def("bake", &bake, py::arg("high"), py::arg("control"), py::arg("out"),
          "Bakes HIGH onto CONTROL (a mesh, a rig, or \"auto\") into the rig OUT; options mirror strata-bake's flags "
          "(tolerance, control_faces, uv, size, scheme, threads, map_coding, mesh_coding, compress, exr, skeleton, close_holes, fit, max_memory, "
          "report, error_levels=(from, to)).  Returns the bake report as a dict.");
    py::class_<PyRig>(m, "Rig")
        .def_readonly("path", &PyRig::path)
        .def_property_readonly("joint_names", &PyRig::jointNames)
        .def_property_readonly("animations", &PyRig::animations)
        .def_property_readonly("recommended_level",
                               [](const PyRig& r) { return r.rig.hasDisplacement ? r.rig.displacement.recommendedLevel : 0; })
        .def_property_readonly("scheme", [](const PyRig& r) { return std::string(schemeName(r.rig.displacement.scheme)); })
        .def_property_readonly("control_vertex_count", [](const PyRig& r) { return r.rig.mesh.positions.size(); })
        .def_property_readonly("warnings", [](const PyRig& r) { return r.rig.warnings; })
        .def("reconstruct", &PyRig::reconstruct, py::arg("level") = py::none(), py::arg("animation") = py::none(),
             py::arg("time") = py::none(), py::arg("displacement") = true,
             "Refined, displaced vertices (float32 [N, 3]) and triangles (uint32 [M, 3]) at `level` (default: the "
             "rig's recommended one), in the bind pose or posed by `animation` at `time` seconds.  A glTF without "
             "the STRATA_layered_displacement layer raises strata.Error naming the tool that dropped it, unless "
             "displacement=False asks for the plain mesh refined.");
    m.def("load_rig", &loadRig, py::arg("path"), "Loads a Strata rig (or any glTF scene with triangles).");
}
