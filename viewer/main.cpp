// strata-view: a standalone glTF viewer that plays layered rigs at any level.
//
//   strata-view FILE [--level N] [--scheme linear|smooth] [--anim NAME|INDEX]
//       [--time T] [--skinning linear|dq|segments] [--high HIGH] [--color shaded|displacement|error]
//       [--no-displacement] [--scale S] [--wireframe] [--cage] [--no-grid] [--yaw DEG] [--pitch DEG]
//       [--screenshot OUT.png [--headless]] [--size WxH]
//
// Windowed: GLFW + Dear ImGui, drag and drop a file to open it.  With
// --screenshot it renders one frame and exits: in a hidden GLFW window
// (under xvfb-run without a display) or, with --headless or when no display
// is available, through EGL with no window system at all.
#include "cli.h"
#include "scene.h"
#include "strata/gl/context.h"
#include "strata/gl/framebuffer.h"
#include "strata/io/file.h"
#include "strata/io/png.h"

#define GLFW_INCLUDE_NONE
#include <GLFW/glfw3.h>
#include <imgui.h>
#include <imgui_impl_glfw.h>
#include <imgui_impl_opengl3.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <string>

using namespace strata;

namespace {

const char* kUsage =
    "usage: strata-view FILE.{glb,gltf,obj} [--level N] [--scheme linear|smooth] [--anim NAME|INDEX]\n"
    "                   [--time T] [--skinning linear|dq|segments] [--high HIGH.{obj,ply,...}]\n"
    "                   [--color shaded|displacement|error] [--no-displacement] [--scale S]\n"
    "                   [--wireframe] [--cage] [--no-grid] [--yaw DEG] [--pitch DEG] [--camera TX,TY,TZ,D]\n"
    "                   [--no-materials] [--adaptive [--pixel-error P] [--no-level-colours]]\n"
    "                   [--screenshot OUT.png [--headless] [--ui]] [--size WxH] [--version]\n"
    "  --time without --anim plays animation 0; a screenshot frames the posed model and leaves\n"
    "  the panel out unless --ui (the displacement and error views draw their colour scale);\n"
    "  --camera gives the view instead (each screenshot prints the one it used)\n"
    "  --adaptive: each control face at the lowest level within P pixels (default 1) of --level\n"
    "     for the view, stitched without cracks, levels in false colour\n";

struct Options {
    std::string file, high, screenshot, anim;
    int width = 1280, height = 800;
    bool headless = false, ui = false, haveTime = false;
    float yaw = 30.0f, pitch = 14.0f;
    std::vector<float> camera;  // --camera TX,TY,TZ,DISTANCE (empty: frame the posed model)
    bool yawGiven = false;
};

Status writeScreenshot(const std::string& path, int width, int height, const std::vector<uint8_t>& rgb)
{
    return io::writePngRgb(path, width, height, rgb);
}

// Reads the default framebuffer (window) as top-row-first RGB.
std::vector<uint8_t> readWindow(int width, int height)
{
    std::vector<uint8_t> up(size_t(width) * size_t(height) * 3), out(up.size());
    glPixelStorei(GL_PACK_ALIGNMENT, 1);
    glReadBuffer(GL_BACK);
    glReadPixels(0, 0, width, height, GL_RGB, GL_UNSIGNED_BYTE, up.data());
    const size_t row = size_t(width) * 3;
    for (int y = 0; y < height; ++y)
        std::copy(up.begin() + std::ptrdiff_t(size_t(height - 1 - y) * row),
                  up.begin() + std::ptrdiff_t(size_t(height - y) * row), out.begin() + std::ptrdiff_t(size_t(y) * row));
    return out;
}

// --anim NAME|INDEX, or animation 0 when only --time was given.
void applyAnimation(viewer::Scene& scene, const std::string& anim, bool haveTime)
{
    if (!scene.rig())
        return;
    if (anim.empty()) {
        if (haveTime && !scene.rig()->skeleton.animations.empty())
            scene.settings.animation = 0;
        return;
    }
    const int a = findAnimation(scene.rig()->skeleton, anim);
    if (a < 0)
        throw cli::Error(scene.path() + ": no animation \"" + anim + "\"");
    scene.settings.animation = a;
}

int runHeadless(viewer::Scene& scene, const Options& o)
{
    std::unique_ptr<gl::HeadlessContext> ctx;
    Status st = gl::HeadlessContext::create(&ctx);
    if (!st)
        throw cli::Error("no OpenGL 4.5 context for --headless: " + st.message());
    if (!(st = scene.open(o.file)))
        throw cli::Error(st.message());
    if (!o.high.empty() && !(st = scene.openHigh(o.high)))
        throw cli::Error(st.message());
    applyAnimation(scene, o.anim, o.haveTime);
    scene.camera.yaw = glm::radians(o.yaw);
    scene.camera.pitch = glm::radians(o.pitch);
    gl::Framebuffer fb;
    if (!(st = fb.create(o.width, o.height)))
        throw cli::Error(st.message());
    scene.update(0.0f);
    if (!scene.lastError().empty())
        throw cli::Error(scene.lastError());
    if (o.camera.size() == 4) {
        // Another model's camera (a comparison of two renders at one view):
        // a user camera, which render does not reframe.
        scene.camera.target = glm::vec3(o.camera[0], o.camera[1], o.camera[2]);
        scene.camera.distance = o.camera[3];
        scene.userCamera_ = true;
    }
    fb.bind();
    scene.render(o.width, o.height);
    std::vector<uint8_t> rgb;
    fb.readRGB(&rgb);
    if (!(st = writeScreenshot(o.screenshot, o.width, o.height, rgb)))
        throw cli::Error(st.message());
    std::string adaptive;
    if (scene.settings.adaptive)
        adaptive = "; adaptive within " + std::to_string(scene.settings.pixelError).substr(0, 4) + " px: " +
                   std::to_string(scene.adaptiveVertexCount()) + " vertices, levels " +
                   std::to_string(scene.adaptiveLevelMin()) + ".." + std::to_string(scene.adaptiveLevelMax());
    std::fprintf(stderr, "strata-view: %s level %d, %zu vertices%s -> %s (%s; --camera %g,%g,%g,%g)\n", o.file.c_str(),
                 scene.currentLevel(), scene.vertexCount(), adaptive.c_str(), o.screenshot.c_str(), ctx->description().c_str(),
                 double(scene.camera.target.x), double(scene.camera.target.y), double(scene.camera.target.z),
                 double(scene.camera.distance));
    return 0;
}

struct Input {
    viewer::Scene* scene = nullptr;
    std::string dropped;
    double lastX = 0.0, lastY = 0.0;
};

void drawPanel(viewer::Scene& scene, double frameMs)
{
    viewer::Settings& s = scene.settings;
    ImGui::SetNextWindowPos(ImVec2(10, 10), ImGuiCond_FirstUseEver);
    ImGui::SetNextWindowSize(ImVec2(360, 0), ImGuiCond_FirstUseEver);
    ImGui::Begin("Strata");
    if (!scene.loaded()) {
        ImGui::TextWrapped("Drop a .glb, .gltf or .obj file on this window.");
    } else {
        ImGui::TextWrapped("%s", scene.description().c_str());
        ImGui::Text("%zu vertices, %zu triangles", scene.vertexCount(), scene.faceCount());
        ImGui::Text("frame %.2f ms", frameMs);
        ImGui::TextWrapped("CPU skin %.3f ms; GPU stencils %.3f, normals %.3f, draw %.3f ms", scene.cpuFrameMs(),
                    scene.gpuTimings().stencilMs, scene.gpuTimings().normalsMs, scene.gpuTimings().drawMs);
        ImGui::Separator();
        ImGui::SliderInt(s.adaptive ? "finest level" : "level", &s.level, 0, kMaxLevel);
        ImGui::Checkbox("adaptive", &s.adaptive);
        if (s.adaptive) {
            ImGui::SameLine();
            ImGui::Checkbox("level colours", &s.levelColours);
            ImGui::SliderFloat("pixel tolerance", &s.pixelError, 0.25f, 16.0f, "%.2f px", ImGuiSliderFlags_Logarithmic);
            ImGui::Text("adaptive: %zu vertices (uniform %zu), levels %d..%d", scene.adaptiveVertexCount(),
                        scene.vertexCount(), scene.adaptiveLevelMin(), scene.adaptiveLevelMax());
            ImGui::Text("level choice %.3f ms; blue level 0 .. red level %d", scene.adaptiveChooseMs(),
                        scene.currentLevel());
        }
        int scheme = int(s.scheme);
        if (ImGui::Combo("scheme", &scheme, "linear (paper)\0smooth (limit)\0"))
            s.scheme = Scheme(scheme);
        ImGui::Checkbox("displacement", &s.displacement);
        ImGui::SameLine();
        ImGui::SliderFloat("scale", &s.scale, 0.0f, 3.0f, "%.2f");
        int color = int(s.colorMode);
        if (ImGui::Combo("colour", &color, scene.hasHigh() ? "shaded\0displacement\0error to high-res\0"
                                                            : "shaded\0displacement\0"))
            s.colorMode = gl::ColorMode(color);
        if (s.colorMode == gl::ColorMode::Displacement)
            ImGui::Text("blue %.4g .. red %.4g", double(scene.displacementMin()), double(scene.displacementMax()));
        if (s.colorMode == gl::ColorMode::Error)
            ImGui::Text("blue 0 .. red %.4g", double(scene.errorMax()));
        ImGui::Checkbox("wireframe", &s.wireframe);
        ImGui::SameLine();
        ImGui::Checkbox("control cage", &s.cage);
        ImGui::SameLine();
        ImGui::Checkbox("grid", &s.grid);
        const Rig* rig = scene.rig();
        if (rig && !rig->skeleton.empty()) {
            ImGui::Separator();
            std::string items = "bind pose";
            items.push_back('\0');
            for (const Animation& a : rig->skeleton.animations) {
                items += a.name.empty() ? std::string("(unnamed)") : a.name;
                items.push_back('\0');
            }
            int anim = s.animation + 1;
            if (ImGui::Combo("animation", &anim, items.c_str()))
                s.animation = anim - 1;
            int method = int(s.skinning);
            ImGui::Combo("skinning", &method, "linear blend\0dual quaternion\0paper eq. 6 segments\0");
            s.skinning = SkinningMethod(method);
            if (s.animation >= 0) {
                ImGui::Checkbox("play", &s.playing);
                ImGui::SameLine();
                ImGui::SliderFloat("time", &s.time, 0.0f, std::max(scene.animationLength(), 1e-3f), "%.2f s");
            }
        }
        if (ImGui::Button("frame model"))
            scene.frameModel();
    }
    if (!scene.lastError().empty()) {
        ImGui::Separator();
        ImGui::PushStyleColor(ImGuiCol_Text, ImVec4(1.0f, 0.45f, 0.35f, 1.0f));
        ImGui::TextWrapped("%s", scene.lastError().c_str());
        ImGui::PopStyleColor();
    }
    ImGui::TextDisabled("drag: orbit  right-drag: pan  wheel: zoom");
    ImGui::End();
}

int runWindow(viewer::Scene& scene, const Options& o)
{
    glfwSetErrorCallback([](int, const char* message) { std::fprintf(stderr, "strata-view: GLFW: %s\n", message); });
    if (!glfwInit())
        throw cli::Error("cannot open a window (no display? use --headless, or run under xvfb-run)");
    glfwWindowHint(GLFW_CONTEXT_VERSION_MAJOR, 4);
    glfwWindowHint(GLFW_CONTEXT_VERSION_MINOR, 5);
    glfwWindowHint(GLFW_OPENGL_PROFILE, GLFW_OPENGL_CORE_PROFILE);
    glfwWindowHint(GLFW_OPENGL_FORWARD_COMPAT, GLFW_TRUE);
    glfwWindowHint(GLFW_SAMPLES, 4);
    if (!o.screenshot.empty())
        glfwWindowHint(GLFW_VISIBLE, GLFW_FALSE);
    GLFWwindow* window = glfwCreateWindow(o.width, o.height, "Strata viewer", nullptr, nullptr);
    if (!window) {
        glfwTerminate();
        throw cli::Error("cannot create an OpenGL 4.5 core window");
    }
    glfwMakeContextCurrent(window);
    glfwSwapInterval(1);
    Status st = gl::loadGL(reinterpret_cast<void* (*)(const char*)>(glfwGetProcAddress));
    if (!st) {
        glfwTerminate();
        throw cli::Error(st.message());
    }
    IMGUI_CHECKVERSION();
    ImGui::CreateContext();
    ImGui::GetIO().IniFilename = nullptr;
    ImGui::StyleColorsDark();
    ImGui_ImplGlfw_InitForOpenGL(window, true);
    ImGui_ImplOpenGL3_Init("#version 450 core");

    Input input;
    input.scene = &scene;
    glfwSetWindowUserPointer(window, &input);
    glfwSetDropCallback(window, [](GLFWwindow* w, int count, const char** paths) {
        if (count > 0)
            static_cast<Input*>(glfwGetWindowUserPointer(w))->dropped = paths[0];
    });
    glfwSetScrollCallback(window, [](GLFWwindow* w, double, double dy) {
        ImGui_ImplGlfw_ScrollCallback(w, 0.0, dy);
        if (ImGui::GetIO().WantCaptureMouse)
            return;
        viewer::Scene* s = static_cast<Input*>(glfwGetWindowUserPointer(w))->scene;
        s->camera.distance *= std::pow(0.9f, float(dy));
        s->userCamera_ = true;
    });

    if (!o.file.empty() && scene.open(o.file)) {
        if (!o.high.empty())
            scene.openHigh(o.high);
        applyAnimation(scene, o.anim, o.haveTime);
    }
    scene.camera.yaw = glm::radians(o.yaw);
    scene.camera.pitch = glm::radians(o.pitch);
    scene.setTiming(true);
    auto last = std::chrono::steady_clock::now();
    double frameMs = 0.0;
    int frames = 0;
    while (!glfwWindowShouldClose(window)) {
        glfwPollEvents();
        if (!input.dropped.empty()) {
            scene.open(input.dropped);  // a failure shows on screen
            input.dropped.clear();
        }
        double x, y;
        glfwGetCursorPos(window, &x, &y);
        if (!ImGui::GetIO().WantCaptureMouse) {
            const float dx = float(x - input.lastX), dy = float(y - input.lastY);
            if (glfwGetMouseButton(window, GLFW_MOUSE_BUTTON_LEFT) == GLFW_PRESS) {
                scene.userCamera_ = true;
                scene.camera.yaw -= dx * 0.008f;
                scene.camera.pitch = glm::clamp(scene.camera.pitch + dy * 0.008f, -1.5f, 1.5f);
            } else if (glfwGetMouseButton(window, GLFW_MOUSE_BUTTON_RIGHT) == GLFW_PRESS ||
                       glfwGetMouseButton(window, GLFW_MOUSE_BUTTON_MIDDLE) == GLFW_PRESS) {
                scene.userCamera_ = true;
                const float k = scene.camera.distance * 0.0015f;
                const glm::vec3 right(std::cos(scene.camera.yaw), 0.0f, -std::sin(scene.camera.yaw));
                scene.camera.target += -dx * k * right + dy * k * glm::vec3(0, 1, 0);
            }
        }
        input.lastX = x;
        input.lastY = y;
        const auto now = std::chrono::steady_clock::now();
        const float dt = std::chrono::duration<float>(now - last).count();
        frameMs = 0.9 * frameMs + 0.1 * double(dt) * 1000.0;
        last = now;
        scene.update(dt);
        int w, h;
        glfwGetFramebufferSize(window, &w, &h);
        glBindFramebuffer(GL_FRAMEBUFFER, 0);
        scene.render(w, h);
        ImGui_ImplOpenGL3_NewFrame();
        ImGui_ImplGlfw_NewFrame();
        ImGui::NewFrame();
        if (o.screenshot.empty() || o.ui)
            drawPanel(scene, frameMs);
        ImGui::Render();
        ImGui_ImplOpenGL3_RenderDrawData(ImGui::GetDrawData());
        // A screenshot waits two frames so the panel has its final layout.
        if (!o.screenshot.empty() && ++frames == 3) {
            if (!scene.lastError().empty())
                throw cli::Error(scene.lastError());
            st = writeScreenshot(o.screenshot, w, h, readWindow(w, h));
            if (!st)
                throw cli::Error(st.message());
            std::fprintf(stderr, "strata-view: %s level %d, %zu vertices -> %s\n", o.file.c_str(),
                         scene.currentLevel(), scene.vertexCount(), o.screenshot.c_str());
            break;
        }
        glfwSwapBuffers(window);
    }
    ImGui_ImplOpenGL3_Shutdown();
    ImGui_ImplGlfw_Shutdown();
    ImGui::DestroyContext();
    glfwDestroyWindow(window);
    glfwTerminate();
    return 0;
}

}  // namespace

int main(int argc, char** argv)
{
    return cli::run("strata-view", [&]() -> int {
        Options o;
        viewer::Scene scene;
        viewer::Settings& s = scene.settings;
        for (int i = 1; i < argc; ++i) {
            const std::string a = argv[i];
            auto value = [&] { return cli::flagValue(argc, argv, &i); };
            if (a == "-h" || a == "--help") {
                std::fputs(kUsage, stdout);
                return 0;
            } else if (a == "--level") {
                s.level = cli::parseInt(a, value(), 0, kMaxLevel);
            } else if (a == "--scheme") {
                if (!parseScheme(value(), &s.scheme))
                    throw cli::Error("--scheme expects linear or smooth");
                s.schemeGiven = true;
            } else if (a == "--anim") {
                o.anim = value();
            } else if (a == "--time") {
                s.time = cli::parseFloat(a, value());
                o.haveTime = true;
            } else if (a == "--version") {
                std::printf("strata-view %s\n", cli::kVersion);
                return 0;
            } else if (a == "--ui") {
                o.ui = true;
            } else if (a == "--no-materials") {
                s.materials = false;
            } else if (a == "--skinning") {
                s.skinning = cli::parseChoice<SkinningMethod>(a, value(), {{"linear", SkinningMethod::Linear},
                                                                   {"dq", SkinningMethod::DualQuaternion},
                                                                   {"segments", SkinningMethod::Segments}});
            } else if (a == "--high") {
                o.high = value();
            } else if (a == "--color") {
                s.colorMode = cli::parseChoice<gl::ColorMode>(a, value(), {{"shaded", gl::ColorMode::Shaded},
                                                                          {"displacement", gl::ColorMode::Displacement},
                                                                          {"error", gl::ColorMode::Error}});
            } else if (a == "--adaptive") {
                s.adaptive = true;
            } else if (a == "--pixel-error") {
                s.pixelError = cli::parseFloat(a, value());
                if (!(s.pixelError > 0.0f) || s.pixelError > 1e6f)
                    throw cli::Error("--pixel-error expects a number of pixels in (0, 1e6]");
            } else if (a == "--no-level-colours") {
                s.levelColours = false;
            } else if (a == "--no-displacement") {
                s.displacement = false;
            } else if (a == "--scale") {
                s.scale = cli::parseFloat(a, value());
            } else if (a == "--wireframe") {
                s.wireframe = true;
            } else if (a == "--no-grid") {
                s.grid = false;
            } else if (a == "--cage") {
                s.cage = true;
            } else if (a == "--camera") {
                const std::string text = value();
                o.camera.clear();
                size_t at = 0;
                while (at <= text.size() && o.camera.size() < 5) {
                    const size_t comma = std::min(text.find(',', at), text.size());
                    o.camera.push_back(cli::parseFloat(a, text.substr(at, comma - at)));
                    at = comma + 1;
                }
                if (o.camera.size() != 4 || !(o.camera[3] > 0.0f))
                    throw cli::Error("--camera expects TX,TY,TZ,DISTANCE (a positive distance), not " + text);
            } else if (a == "--yaw") {
                o.yaw = cli::parseFloat(a, value());
            } else if (a == "--pitch") {
                o.pitch = cli::parseFloat(a, value());
            } else if (a == "--screenshot") {
                o.screenshot = value();
            } else if (a == "--headless") {
                o.headless = true;
            } else if (a == "--size") {
                const std::string v = value();
                int w = 0, h = 0;
                char tail;
                if (std::sscanf(v.c_str(), "%dx%d%c", &w, &h, &tail) != 2 || w < 16 || h < 16 || w > 8192 || h > 8192)
                    throw cli::Error("--size expects WxH between 16 and 8192, got \"" + v + "\"");
                o.width = w;
                o.height = h;
            } else if (!a.empty() && a[0] == '-') {
                throw cli::Error("unknown option " + a + " (see --help)");
            } else if (o.file.empty()) {
                o.file = a;
            } else {
                throw cli::Error("more than one file given (" + o.file + ", " + a + ")");
            }
        }
        if (o.screenshot.empty() && o.headless)
            throw cli::Error("--headless needs --screenshot OUT.png");
        if (!o.screenshot.empty() && o.file.empty())
            throw cli::Error("--screenshot needs a FILE to show");
        if (o.screenshot.empty() && o.file.empty() && !std::getenv("DISPLAY") && !std::getenv("WAYLAND_DISPLAY"))
            throw cli::Error("no display; give FILE and --screenshot OUT.png --headless");
        const bool noDisplay = !std::getenv("DISPLAY") && !std::getenv("WAYLAND_DISPLAY");
        if (!o.screenshot.empty() && (o.headless || noDisplay))
            return runHeadless(scene, o);
        return runWindow(scene, o);
    });
}
