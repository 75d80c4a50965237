// Gutter dilation by linear extrapolation.
#include "strata/baker/dilate.h"

#include <cstddef>

namespace strata {
namespace baker {

void dilate(std::vector<float>* values, std::vector<uint8_t>* valid, int size, int passes, float fill)
{
    std::vector<float>& v = *values;
    std::vector<uint8_t>& ok = *valid;
    static const int dx[8] = {1, -1, 0, 0, 1, 1, -1, -1}, dy[8] = {0, 0, 1, -1, 1, -1, 1, -1};
    std::vector<size_t> frontier;
    std::vector<float> newValues;
    for (int pass = 0; pass < passes; ++pass) {
        frontier.clear();
        newValues.clear();
        for (int y = 0; y < size; ++y)
            for (int x = 0; x < size; ++x) {
                const size_t i = size_t(y) * size_t(size) + size_t(x);
                if (ok[i])
                    continue;
                double sum = 0.0;
                int n = 0;
                for (int k = 0; k < 8; ++k) {
                    const int x1 = x + dx[k], y1 = y + dy[k];
                    if (x1 < 0 || y1 < 0 || x1 >= size || y1 >= size || !ok[size_t(y1) * size_t(size) + size_t(x1)])
                        continue;
                    const float v1 = v[size_t(y1) * size_t(size) + size_t(x1)];
                    const int x2 = x1 + dx[k], y2 = y1 + dy[k];
                    if (x2 >= 0 && y2 >= 0 && x2 < size && y2 < size && ok[size_t(y2) * size_t(size) + size_t(x2)])
                        sum += 2.0 * double(v1) - double(v[size_t(y2) * size_t(size) + size_t(x2)]);
                    else
                        sum += double(v1);
                    ++n;
                }
                if (n > 0) {
                    frontier.push_back(i);
                    newValues.push_back(float(sum / n));
                }
            }
        if (frontier.empty())
            break;
        for (size_t k = 0; k < frontier.size(); ++k) {
            v[frontier[k]] = newValues[k];
            ok[frontier[k]] = 1;
        }
    }
    for (size_t i = 0; i < v.size(); ++i)
        if (!ok[i])
            v[i] = fill;
}

}  // namespace baker
}  // namespace strata
