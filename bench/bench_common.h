// Shared timing helpers for Strata's benchmark programs: median of repeated
// runs, each run long enough to dwarf the clock's resolution.
#pragma once

#include "strata/adaptive.h"

#include <glm/geometric.hpp>
#include <glm/vec3.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <string>
#include <utility>
#include <vector>

namespace strata {
namespace bench {

inline double nowMs()
{
    return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

/// The median of some timings (the upper middle one of an even count).
inline double median(std::vector<double> v)
{
    std::sort(v.begin(), v.end());
    return v.empty() ? 0.0 : v[v.size() / 2];
}

/// Median over `runs` runs of the per-call time of f, in ms; each run
/// repeats f until it has taken at least minRunMs.
template <typename F>
double medianMs(F&& f, int runs = 7, double minRunMs = 30.0)
{
    f();  // warm caches and page in buffers
    std::vector<double> per;
    for (int r = 0; r < runs; ++r) {
        int calls = 0;
        const double t0 = nowMs();
        double t = t0;
        do {
            f();
            ++calls;
            t = nowMs();
        } while (t - t0 < minRunMs);
        per.push_back((t - t0) / calls);
    }
    return median(std::move(per));
}

/// A sphere around points: the centre of their box, the farthest point's distance.
inline void boundingSphere(const std::vector<glm::vec3>& points, glm::vec3* centre, float* radius)
{
    glm::vec3 lo(1e30f), hi(-1e30f);
    for (const glm::vec3& p : points) {
        lo = glm::min(lo, p);
        hi = glm::max(hi, p);
    }
    *centre = 0.5f * (lo + hi);
    *radius = 0.0f;
    for (const glm::vec3& p : points)
        *radius = std::max(*radius, glm::length(p - *centre));
}

/// A 45-degree camera, heightPx pixels tall, at the distance where a sphere
/// fills `fill` of its height, looking at the sphere's centre from the front
/// a little above and to the right (the adaptive tables' three distances).
inline ViewSpec viewFilling(glm::vec3 centre, float radius, float fill, float heightPx)
{
    ViewSpec view;
    view.fovYDegrees = 45.0f;
    view.heightPx = heightPx;
    const float distance = 2.0f * radius * view.pixelsPerUnitAtDistanceOne() / (fill * heightPx);
    view.target = centre;
    view.eye = centre + distance * glm::normalize(glm::vec3(0.35f, 0.25f, 1.0f));
    return view;
}

/// Frame f of `frames` of the adaptive benches' moving view: `view` dollied
/// 10% in and out and slid a tenth of the radius sideways, once round.
inline ViewSpec movingView(const ViewSpec& view, glm::vec3 centre, float radius, int f, int frames)
{
    const float s = std::sin(6.2831853f * float(f) / float(frames));
    ViewSpec v = view;
    v.eye = centre + (view.eye - centre) * (1.0f + 0.1f * s) + glm::vec3(0.1f * radius * s, 0.0f, 0.0f);
    return v;
}

/// Machine-readable rows for --json FILE: one object per table row, stable
/// field names (docs/RESULTS.md is made from them).
class JsonRows {
public:
    JsonRows& field(const char* name, double value)
    {
        char b[64];
        if (std::isfinite(value))
            std::snprintf(b, sizeof(b), "%.9g", value);  // counts up to 10^9 exactly
        else
            std::snprintf(b, sizeof(b), "null");
        return append(name, b);
    }
    JsonRows& field(const char* name, const std::string& value)
    {
        std::string quoted = "\"";
        for (char c : value)
            if (c == '"' || c == '\\')
                quoted += std::string("\\") + c;
            else if ((unsigned char)c >= 0x20)
                quoted += c;
        return append(name, quoted + "\"");
    }
    JsonRows& field(const char* name, const char* value) { return field(name, std::string(value)); }
    /// Closes the current row.
    void endRow()
    {
        rows_.push_back("{" + current_ + "}");
        current_.clear();
    }
    /// The rows as a JSON array.
    std::string text() const
    {
        std::string t = "[\n";
        for (size_t i = 0; i < rows_.size(); ++i)
            t += "  " + rows_[i] + (i + 1 < rows_.size() ? ",\n" : "\n");
        return t + "]";
    }
    /// Writes text() to a file; false when it cannot be written.
    bool write(const std::string& path) const
    {
        FILE* f = std::fopen(path.c_str(), "w");
        if (!f)
            return false;
        const std::string t = text() + "\n";
        std::fputs(t.c_str(), f);
        return std::fclose(f) == 0;
    }

private:
    JsonRows& append(const char* name, const std::string& value)
    {
        current_ += (current_.empty() ? "\"" : ", \"") + std::string(name) + "\": " + value;
        return *this;
    }
    std::vector<std::string> rows_;
    std::string current_;
};

}  // namespace bench
}  // namespace strata
