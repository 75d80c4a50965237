// Gutter dilation by linear extrapolation.
#include "strata/baker/dilate.h"
#include "parallel.h"

#include <algorithm>
#include <cstddef>

namespace strata {
namespace baker {

void dilate(std::vector<float>* values, std::vector<uint8_t>* valid, int size, int passes, float fill, int threads)
{
    std::vector<float>& v = *values;
    std::vector<uint8_t>& ok = *valid;
    static const int dx[8] = {1, -1, 0, 0, 1, 1, -1, -1}, dy[8] = {0, 0, 1, -1, 1, -1, 1, -1};
    auto at = [&](int x, int y) { return size_t(y) * size_t(size) + size_t(x); };
    // Candidates: unset texels next to a set one.  Each pass only visits
    // those, so the cost follows the gutter area, not the image.  Found per
    // row band and joined in band order: the serial scan's order.
    threads = std::max(1, threads);
    std::vector<std::vector<size_t>> found(static_cast<size_t>(threads));
    std::vector<uint8_t> queued(v.size(), 0);
    parallelChunks(size_t(size), threads, [&](int band, size_t rowBegin, size_t rowEnd) {
        for (int y = int(rowBegin); y < int(rowEnd); ++y)
            for (int x = 0; x < size; ++x) {
                if (ok[at(x, y)])
                    continue;
                for (int k = 0; k < 8; ++k) {
                    const int x1 = x + dx[k], y1 = y + dy[k];
                    if (x1 >= 0 && y1 >= 0 && x1 < size && y1 < size && ok[at(x1, y1)]) {
                        found[size_t(band)].push_back(at(x, y));
                        queued[at(x, y)] = 1;
                        break;
                    }
                }
            }
    });
    std::vector<size_t> candidates, next;
    for (const std::vector<size_t>& f : found)
        candidates.insert(candidates.end(), f.begin(), f.end());
    found.clear();
    std::vector<float> newValues;
    for (int pass = 0; pass < passes && !candidates.empty(); ++pass) {
        newValues.assign(candidates.size(), 0.0f);
        parallelFor(candidates.size(), threads, [&](size_t cb, size_t ce) {
            for (size_t c = cb; c < ce; ++c) {
                const int x = int(candidates[c] % size_t(size)), y = int(candidates[c] / size_t(size));
                double sum = 0.0;
                int n = 0;
                for (int k = 0; k < 8; ++k) {
                    const int x1 = x + dx[k], y1 = y + dy[k];
                    if (x1 < 0 || y1 < 0 || x1 >= size || y1 >= size || !ok[at(x1, y1)])
                        continue;
                    const float v1 = v[at(x1, y1)];
                    const int x2 = x1 + dx[k], y2 = y1 + dy[k];
                    if (x2 >= 0 && y2 >= 0 && x2 < size && y2 < size && ok[at(x2, y2)])
                        sum += 2.0 * double(v1) - double(v[at(x2, y2)]);  // linear extrapolation
                    else
                        sum += double(v1);
                    ++n;
                }
                newValues[c] = float(sum / n);
            }
        });
        // Commit the pass (Jacobi: every value above read the previous state).
        next.clear();
        for (size_t c = 0; c < candidates.size(); ++c) {
            v[candidates[c]] = newValues[c];
            ok[candidates[c]] = 1;
        }
        for (size_t c = 0; c < candidates.size(); ++c) {
            const int x = int(candidates[c] % size_t(size)), y = int(candidates[c] / size_t(size));
            for (int k = 0; k < 8; ++k) {
                const int x1 = x + dx[k], y1 = y + dy[k];
                if (x1 < 0 || y1 < 0 || x1 >= size || y1 >= size)
                    continue;
                const size_t i = at(x1, y1);
                if (!ok[i] && !queued[i]) {
                    queued[i] = 1;
                    next.push_back(i);
                }
            }
        }
        std::sort(next.begin(), next.end());  // deterministic order
        candidates.swap(next);
    }
    for (size_t i = 0; i < v.size(); ++i)
        if (!ok[i])
            v[i] = fill;
}

}  // namespace baker
}  // namespace strata
