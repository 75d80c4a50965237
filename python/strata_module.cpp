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
#include "strata/baker/bake_options.h"
#include "strata/baker/bake_rig.h"
#include "strata/io/reconstruct.h"
#include "strata/io/rig_io.h"

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <array>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <memory>
#include <mutex>
#include <thread>
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

    py::tuple reconstruct(py::object level, py::object animation, py::object time, bool displacement, py::object view,
                          float pixelError) const
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
        // view=(eye, target, fov_y_degrees, height_px): the adaptive mesh for that camera.
        ViewSpec viewSpec;
        const bool adaptive = !view.is_none();
        if (adaptive) {
            const py::tuple v = view.cast<py::tuple>();
            if (v.size() != 4)
                throw StrataError("view must be (eye, target, fov_y_degrees, height_px)");
            const auto eye = v[0].cast<std::array<float, 3>>(), target = v[1].cast<std::array<float, 3>>();
            viewSpec.eye = glm::vec3(eye[0], eye[1], eye[2]);
            viewSpec.target = glm::vec3(target[0], target[1], target[2]);
            viewSpec.fovYDegrees = v[2].cast<float>();
            viewSpec.heightPx = v[3].cast<float>();
        }
        // The arrays view the reconstruction (and adaptive frame), which a capsule keeps alive.
        struct Owner {
            io::Reconstruction rec;
            io::AdaptiveView view;
        };
        auto owned = std::make_unique<Owner>();
        {
            py::gil_scoped_release unlocked;
            check(io::reconstruct(&owned->rec, rig, &map, options, posed ? &pose : nullptr));
            if (adaptive) {
                Status st = io::reconstructView(&owned->view, owned->rec, viewSpec, pixelError, /*measure=*/false);
                if (!st)
                    throw StrataError(path + ": view: " + st.message());
            }
        }
        Owner* owner = owned.release();
        py::capsule keep(owner, [](void* p) { delete static_cast<Owner*>(p); });
        const std::vector<glm::vec3>& points = adaptive ? owner->view.positions : owner->rec.positions;
        const std::vector<uint32_t>& tris =
            adaptive ? owner->rec.surface->adaptiveFrame().triangles() : owner->rec.surface->triangles();
        const py::ssize_t n = py::ssize_t(points.size()), m = py::ssize_t(tris.size() / 3);
        py::array_t<float> vertices({n, py::ssize_t(3)}, {py::ssize_t(3 * sizeof(float)), py::ssize_t(sizeof(float))},
                                    reinterpret_cast<const float*>(points.data()), keep);
        py::array_t<uint32_t> triangles({m, py::ssize_t(3)},
                                        {py::ssize_t(3 * sizeof(uint32_t)), py::ssize_t(sizeof(uint32_t))},
                                        tris.data(), keep);
        return py::make_tuple(vertices, triangles);
    }
};

std::unique_ptr<PyRig> loadRig(const py::object& where)
{
    const std::string path = py::str(py::module_::import("os").attr("fspath")(where)).cast<std::string>();
    auto r = std::make_unique<PyRig>();
    r->path = path;
    check(io::loadRig(path, &r->rig));
    if (rigNeedsMap(r->rig))
        check(io::loadRigDisplacementMap(path, r->rig, &r->map));
    return r;
}

// A keyword's value as the option table's text: bools as true/false, a
// pair of levels as A:B, numbers as Python prints them.
std::string optionText(const py::handle& v)
{
    if (py::isinstance<py::bool_>(v))
        return v.cast<bool>() ? "true" : "false";
    if (py::isinstance<py::tuple>(v) || py::isinstance<py::list>(v)) {
        const py::sequence t = v.cast<py::sequence>();
        if (t.size() != 2)
            throw StrataError("a pair of levels (from, to) is expected, not " + py::str(v).cast<std::string>());
        return py::str(t[0]).cast<std::string>() + ":" + py::str(t[1]).cast<std::string>();
    }
    if (py::isinstance<py::str>(v) || py::isinstance<py::int_>(v) || py::isinstance<py::float_>(v))
        return py::str(v).cast<std::string>();
    if (py::hasattr(v, "__fspath__"))
        return py::str(v.attr("__fspath__")()).cast<std::string>();
    throw StrataError("a value of type " + py::str(py::type::of(v).attr("__name__")).cast<std::string>() +
                      " is not an option value");
}

py::dict bake(const py::object& high, const py::object& control, const py::object& out, const py::kwargs& kw)
{
    // strata-bake's option table: the same names, checks and defaults.
    baker::BakeRequest req = baker::defaultBakeRequest();
    const std::pair<const char*, const py::object*> positional[] = {{"high", &high}, {"control", &control},
                                                                     {"out", &out}};
    for (const auto& p : positional)
        check(baker::applyBakeOption(&req, *baker::findBakeOption(p.first), p.first, optionText(*p.second)));
    py::object progress = py::none();
    for (const auto& item : kw) {
        const std::string key = item.first.cast<std::string>();
        if (key == "progress") {  // Python's own: a callable, not a strata-bake flag
            progress = py::reinterpret_borrow<py::object>(item.second);
            if (!progress.is_none() && !py::isinstance<py::function>(progress) && !py::hasattr(progress, "__call__"))
                throw StrataError("progress expects a callable progress(stage, seconds) or None");
            continue;
        }
        const baker::BakeOption* option = baker::findBakeOption(key);
        if (!option || !option->keyword || key != option->keyword || option->required)
            throw StrataError("bake() got an unknown option \"" + key + "\" (see help(strata.bake))");
        check(baker::applyBakeOption(&req, *option, key, optionText(item.second)));
    }
    // The bake runs on its own thread with the GIL released (other Python
    // threads run, and bake at once); this thread wakes every 100 ms to pass
    // progress events to Python and to look for Ctrl-C, which cancels the
    // bake at its next stage boundary: nothing is written, and
    // KeyboardInterrupt is raised once it has stopped.
    if (progress.is_none() && py::module_::import("sys").attr("stderr").attr("isatty")().cast<bool>())
        progress = py::cpp_function([](const std::string& stage, double seconds) {
            py::print(seconds < 0.0 ? "strata.bake: " + stage + "..."
                                    : "strata.bake: " + stage + " done in " + std::to_string(seconds).substr(0, 4) +
                                          " s",
                      py::arg("file") = py::module_::import("sys").attr("stderr"), py::arg("flush") = true);
        });
    struct Shared {
        std::mutex m;
        std::condition_variable cv;
        std::vector<std::pair<std::string, double>> events;
        bool done = false;
        std::atomic<bool> cancel{false};
        baker::BakeResult result;
        Status status;
    };
    auto shared = std::make_shared<Shared>();
    req.cancel = &shared->cancel;
    const baker::BakeProgress onStage = [shared](const char* stage, double seconds) {
        std::lock_guard<std::mutex> lock(shared->m);
        shared->events.emplace_back(stage, seconds);
        shared->cv.notify_all();
    };
    std::thread worker([shared, req, onStage] {
        Status st;
        try {
            st = baker::bakeRig(req, &shared->result, &onStage);
        } catch (const std::exception& e) {
            st = Status(StatusCode::InvalidData, std::string("unexpected failure: ") + e.what());
        }
        std::lock_guard<std::mutex> lock(shared->m);
        shared->status = st;
        shared->done = true;
        shared->cv.notify_all();
    });
    bool interrupted = false;
    py::object interruptError;
    // A progress callback that raises cancels the bake too: the worker is
    // always joined before this function leaves.
    auto stopWorker = [&] {
        shared->cancel = true;
        py::gil_scoped_release unlocked;
        if (worker.joinable())
            worker.join();
    };
    try {
    for (;;) {
        std::vector<std::pair<std::string, double>> events;
        bool done = false;
        {
            py::gil_scoped_release unlocked;
            std::unique_lock<std::mutex> lock(shared->m);
            shared->cv.wait_for(lock, std::chrono::milliseconds(100),
                                [&] { return shared->done || !shared->events.empty(); });
            events.swap(shared->events);
            done = shared->done;
        }
        for (const auto& e : events)
            if (!progress.is_none() && !interrupted)
                progress(e.first, e.second);
        if (done)
            break;
        if (!interrupted && PyErr_CheckSignals() != 0) {
            interrupted = true;
            shared->cancel = true;
            // Keep the exception (KeyboardInterrupt) to raise once the bake has stopped.
            PyObject *type, *value, *trace;
            PyErr_Fetch(&type, &value, &trace);
            PyErr_NormalizeException(&type, &value, &trace);
            if (trace)
                PyException_SetTraceback(value, trace);
            interruptError = py::reinterpret_steal<py::object>(value);
            Py_XDECREF(type);
            Py_XDECREF(trace);
        }
    }
    } catch (...) {
        stopWorker();
        throw;
    }
    {
        py::gil_scoped_release unlocked;
        worker.join();
    }
    if (interrupted) {
        PyErr_SetObject(reinterpret_cast<PyObject*>(Py_TYPE(interruptError.ptr())), interruptError.ptr());
        throw py::error_already_set();
    }
    check(shared->status);
    baker::BakeResult& result = shared->result;
    py::dict report = py::module_::import("json").attr("loads")(result.report);
    report["warnings"] = result.warnings;
    report["written"] = result.written;
    report["summary"] = result.summary;
    report["rms"] = result.rms;  // closed-loop RMS / diagonal at the recommended level (-1: not measured)
    return report;
}

}  // namespace

PYBIND11_MODULE(_strata, m)
{
    m.doc() = "Strata: layered animation with displacement maps (bake, load, reconstruct)";
    // pybind11 looks numpy's C API up in a function-local static the first
    // time an array is made, importing numpy, which lets go of the GIL: a
    // second thread that holds the GIL then waits on the static's guard
    // forever.  Made here, under the import lock, before any thread can race.
    (void)py::array_t<float>(0);
    m.attr("__version__") = STRATA_VERSION;
    py::register_exception<StrataError>(m, "Error", PyExc_RuntimeError);
    static const std::string bakeDoc =
        "bake(high, control, out, **options) -> dict\n\n"
        "Bakes the capture HIGH onto CONTROL (a mesh, a rig, or \"auto\") into the rig OUT, as strata-bake "
        "does, and returns the bake report as a dict (with its warnings, the files written and the summary).  "
        "Paths may be str or os.PathLike.  Raises strata.Error with strata-bake's one-line message.  "
        "progress (callable(stage: str, seconds: float) or None, default: stage lines on stderr when it is a "
        "terminal): called when a stage has run a second (seconds < 0) and when it ends.  Ctrl-C (KeyboardInterrupt) "
        "cancels the bake at its next stage boundary and writes nothing.  The GIL is released while it runs.\n\n"
        "Options (keyword (type, default; the strata-bake flag): meaning):\n" +
        baker::bakeOptionsDocstring();
    m.def("bake", &bake, py::arg("high"), py::arg("control"), py::arg("out"), bakeDoc.c_str());
    py::class_<PyRig>(m, "Rig")
        .def_readonly("path", &PyRig::path)
        .def_property_readonly("joint_names", &PyRig::jointNames)
        .def_property_readonly("animations", &PyRig::animations)
        .def_property_readonly("recommended_level",
                               [](const PyRig& r) { return r.rig.hasDisplacement ? r.rig.displacement.recommendedLevel : 0; })
        .def_property_readonly("scheme", [](const PyRig& r) { return std::string(schemeName(r.rig.displacement.scheme)); })
        .def_property_readonly(
            "shading",
            [](const PyRig& r) {
                const size_t flat = flatPartCount(r.rig);
                return std::string(flat == 0 ? "smooth" : flat == r.rig.parts.size() ? "flat" : "mixed");
            },
            "\"flat\" when the surface is drawn with face normals (a glTF capture without NORMAL, which glTF "
            "draws so), \"smooth\" with the surface's normals, \"mixed\" when only some primitives are flat.")
        .def_property_readonly("control_vertex_count", [](const PyRig& r) { return r.rig.mesh.positions.size(); })
        .def_property_readonly("warnings", [](const PyRig& r) { return r.rig.warnings; })
        .def("reconstruct", &PyRig::reconstruct, py::arg("level") = py::none(), py::arg("animation") = py::none(),
             py::arg("time") = py::none(), py::arg("displacement") = true, py::arg("view") = py::none(),
             py::arg("pixel_error") = 1.0f,
             "Refined, displaced vertices (float32 [N, 3]) and triangles (uint32 [M, 3]) at `level` (default: the "
             "rig's recommended one), in the bind pose or posed by `animation` at `time` seconds.  With "
             "view=(eye, target, fov_y_degrees, height_px), the adaptive mesh for that camera instead: each control "
             "face at the lowest level within `pixel_error` pixels of `level` wherever it lies in front of the eye, stitched without cracks.  "
             "A glTF without the STRATA_layered_displacement layer raises strata.Error naming the tool that dropped "
             "it, unless displacement=False asks for the plain mesh refined.");
    m.def(
        "bake_options",
        [] {
            py::list out;
            for (const baker::BakeOption& o : baker::bakeOptions())
                if (o.keyword)
                    out.append(py::dict(py::arg("keyword") = o.keyword, py::arg("flag") = o.flag,
                                        py::arg("type") = o.type, py::arg("default") = o.defaultText,
                                        py::arg("help") = o.help, py::arg("required") = o.required));
            return out;
        },
        "strata-bake's option table: keyword, flag, type, default, help and whether it is required, per option.");
    m.def("load_rig", &loadRig, py::arg("path"), "Loads a Strata rig (or any glTF scene with triangles).");
}
