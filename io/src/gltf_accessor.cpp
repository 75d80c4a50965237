// Accessor reading for untrusted glTF: nothing is read before its extent has
// been checked against the bufferView and the buffer.
#include "gltf_accessor.h"

#include <tiny_gltf.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>

namespace strata {
namespace io {
namespace {

int componentCount(int type)
{
    switch (type) {
    case TINYGLTF_TYPE_SCALAR: return 1;
    case TINYGLTF_TYPE_VEC2: return 2;
    case TINYGLTF_TYPE_VEC3: return 3;
    case TINYGLTF_TYPE_VEC4: return 4;
    case TINYGLTF_TYPE_MAT4: return 16;
    default: return 0;
    }
}

int componentBytes(int componentType)
{
    switch (componentType) {
    case TINYGLTF_COMPONENT_TYPE_BYTE:
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE: return 1;
    case TINYGLTF_COMPONENT_TYPE_SHORT:
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: return 2;
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT:
    case TINYGLTF_COMPONENT_TYPE_FLOAT: return 4;
    default: return 0;
    }
}

// Resolves accessor `index` to a base pointer and stride after checking
// that count elements of elementBytes fit inside the buffer.
Status locate(const tinygltf::Model& model, int index, int components, const std::string& what,
              const unsigned char** base, size_t* stride, size_t* count, int* componentType)
{
    if (index < 0 || size_t(index) >= model.accessors.size())
        return Status(StatusCode::InvalidData, what + ": accessor " + std::to_string(index) + " does not exist");
    const tinygltf::Accessor& acc = model.accessors[size_t(index)];
    if (acc.sparse.isSparse)
        return Status(StatusCode::Unsupported, what + ": sparse accessors are not supported");
    if (componentCount(acc.type) != components)
        return Status(StatusCode::InvalidData, what + ": accessor " + std::to_string(index) + " has " +
                                                   std::to_string(componentCount(acc.type)) +
                                                   " components per element, expected " + std::to_string(components));
    const int cbytes = componentBytes(acc.componentType);
    if (cbytes == 0)
        return Status(StatusCode::InvalidData, what + ": unknown component type " + std::to_string(acc.componentType));
    if (acc.bufferView < 0 || size_t(acc.bufferView) >= model.bufferViews.size())
        return Status(StatusCode::InvalidData, what + ": accessor " + std::to_string(index) + " has no valid bufferView");
    const tinygltf::BufferView& view = model.bufferViews[size_t(acc.bufferView)];
    if (view.buffer < 0 || size_t(view.buffer) >= model.buffers.size())
        return Status(StatusCode::InvalidData, what + ": bufferView " + std::to_string(acc.bufferView) +
                                                   " references a missing buffer");
    const std::vector<unsigned char>& data = model.buffers[size_t(view.buffer)].data;
    const size_t elementBytes = size_t(cbytes) * size_t(components);
    const size_t s = view.byteStride ? size_t(view.byteStride) : elementBytes;
    if (s < elementBytes)
        return Status(StatusCode::InvalidData, what + ": byteStride " + std::to_string(view.byteStride) +
                                                   " is smaller than an element");
    if (view.byteOffset > data.size() || view.byteLength > data.size() - view.byteOffset)
        return Status(StatusCode::InvalidData, what + ": bufferView " + std::to_string(acc.bufferView) +
                                                   " extends past the end of its buffer");
    const size_t n = acc.count;
    if (n > 0) {
        // Last byte touched: byteOffset + stride * (n - 1) + elementBytes, overflow-checked.
        if (n - 1 > (view.byteLength) / s + 1 || acc.byteOffset > view.byteLength ||
            s * (n - 1) + elementBytes > view.byteLength - acc.byteOffset)
            return Status(StatusCode::InvalidData, what + ": accessor " + std::to_string(index) + " (" +
                                                       std::to_string(n) +
                                                       " elements) reads past the end of its bufferView");
    }
    *base = data.data() + view.byteOffset + acc.byteOffset;
    *stride = s;
    *count = n;
    *componentType = acc.componentType;
    return Status::ok();
}

}  // namespace

Status readFloatAccessor(const tinygltf::Model& model, int index, int components, const std::string& what,
                         std::vector<float>* out)
{
    const unsigned char* base = nullptr;
    size_t stride = 0, count = 0;
    int ctype = 0;
    Status st = locate(model, index, components, what, &base, &stride, &count, &ctype);
    if (!st)
        return st;
    // Any component type: floats as they are, normalized integers mapped to
    // [0, 1] or [-1, 1], plain integers as their values (KHR_mesh_quantization).
    const bool normalized = model.accessors[size_t(index)].normalized;
    out->resize(count * size_t(components));
    for (size_t i = 0; i < count; ++i) {
        const unsigned char* e = base + i * stride;
        for (int c = 0; c < components; ++c) {
            float v = 0.0f;
            switch (ctype) {
            case TINYGLTF_COMPONENT_TYPE_FLOAT: std::memcpy(&v, e + 4 * c, 4); break;
            case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE: v = normalized ? float(e[c]) / 255.0f : float(e[c]); break;
            case TINYGLTF_COMPONENT_TYPE_BYTE: {
                const float b = float(int8_t(e[c]));
                v = normalized ? std::max(b / 127.0f, -1.0f) : b;
                break;
            }
            case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: {
                uint16_t u;
                std::memcpy(&u, e + 2 * c, 2);
                v = normalized ? float(u) / 65535.0f : float(u);
                break;
            }
            case TINYGLTF_COMPONENT_TYPE_SHORT: {
                int16_t u;
                std::memcpy(&u, e + 2 * c, 2);
                v = normalized ? std::max(float(u) / 32767.0f, -1.0f) : float(u);
                break;
            }
            default:
                return Status(StatusCode::Unsupported, what + ": component type " + std::to_string(ctype) +
                                                           " cannot be read as numbers");
            }
            if (!std::isfinite(v))
                return Status(StatusCode::InvalidData, what + ": element " + std::to_string(i) + " is not finite");
            (*out)[i * size_t(components) + size_t(c)] = v;
        }
    }
    return Status::ok();
}

Status readUintAccessor(const tinygltf::Model& model, int index, int components, const std::string& what,
                        std::vector<uint32_t>* out)
{
    const unsigned char* base = nullptr;
    size_t stride = 0, count = 0;
    int ctype = 0;
    Status st = locate(model, index, components, what, &base, &stride, &count, &ctype);
    if (!st)
        return st;
    if (ctype != TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE && ctype != TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT &&
        ctype != TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT)
        return Status(StatusCode::InvalidData, what + ": component type " + std::to_string(ctype) +
                                                   " is not an unsigned integer");
    out->resize(count * size_t(components));
    for (size_t i = 0; i < count; ++i) {
        const unsigned char* e = base + i * stride;
        for (int c = 0; c < components; ++c) {
            uint32_t v;
            if (ctype == TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE) {
                v = e[c];
            } else if (ctype == TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT) {
                uint16_t u;
                std::memcpy(&u, e + 2 * c, 2);
                v = u;
            } else {
                std::memcpy(&v, e + 4 * c, 4);
            }
            (*out)[i * size_t(components) + size_t(c)] = v;
        }
    }
    return Status::ok();
}

double jsonFloat(float v)
{
    if (!std::isfinite(v))
        return double(v);
    char text[32];
    for (int digits = 1; digits < 9; ++digits) {
        std::snprintf(text, sizeof(text), "%.*g", digits, double(v));
        if (std::strtof(text, nullptr) == v)
            return std::strtod(text, nullptr);
    }
    return double(v);  // nine digits always read back
}

void jsonFloats(std::vector<double>* values)
{
    for (double& v : *values)
        v = jsonFloat(float(v));
}

}  // namespace io
}  // namespace strata
