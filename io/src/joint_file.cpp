#include "strata/io/joint_file.h"

#include "strata/io/file.h"
#include "text.h"

#include <filesystem>
#include <glm/gtc/matrix_transform.hpp>
#include <glm/gtc/quaternion.hpp>
#include <nlohmann/json.hpp>

#include <cmath>
#include <map>

namespace strata {
namespace io {

namespace {

using Json = nlohmann::json;

struct ParseError {
    std::string message;
};

[[noreturn]] void fail(const std::string& message)
{
    throw ParseError{message};
}

float number(const Json& j, const std::string& what)
{
    if (!j.is_number())
        fail(what + " is not a number");
    const double v = j.get<double>();
    if (!std::isfinite(v) || std::fabs(v) > 1e30)
        fail(what + " is not finite");
    return float(v);
}

glm::vec3 vec3(const Json& j, const std::string& what)
{
    if (!j.is_array() || j.size() != 3)
        fail(what + " is not an array of 3 numbers");
    return {number(j[0], what), number(j[1], what), number(j[2], what)};
}

// [x, y, z, w] (glTF order) or {"axis": [x, y, z], "degrees": a}.
glm::quat rotation(const Json& j, const std::string& what)
{
    if (j.is_object()) {
        if (!j.contains("axis") || !j.contains("degrees"))
            fail(what + " needs \"axis\" and \"degrees\"");
        const glm::vec3 axis = vec3(j["axis"], what + " axis");
        if (glm::length(axis) < 1e-6f)
            fail(what + " has a zero axis");
        return glm::angleAxis(glm::radians(number(j["degrees"], what + " degrees")), glm::normalize(axis));
    }
    if (!j.is_array() || j.size() != 4)
        fail(what + " is not [x, y, z, w] or {\"axis\", \"degrees\"}");
    glm::quat q(number(j[3], what), number(j[0], what), number(j[1], what), number(j[2], what));
    const float len = glm::length(q);
    if (len < 1e-6f)
        fail(what + " is a zero quaternion");
    return q / len;
}

void parse(const Json& root, Skeleton* out)
{
    if (!root.is_object())
        fail("the top level is not an object");
    if (root.contains("strataJoints") && (!root["strataJoints"].is_number_integer() || root["strataJoints"] != 1))
        fail("strataJoints version " + root["strataJoints"].dump() + " is not supported (this build reads 1)");
    if (!root.contains("joints") || !root["joints"].is_array() || root["joints"].empty())
        fail("\"joints\" is missing or empty");
    const Json& joints = root["joints"];
    if (joints.size() > 65535)
        fail("more than 65535 joints");

    Skeleton s;
    std::map<std::string, int> index;
    std::vector<glm::vec3> world;
    std::vector<std::string> parentNames;
    for (size_t i = 0; i < joints.size(); ++i) {
        const Json& j = joints[i];
        const std::string where = "joint " + std::to_string(i);
        if (!j.is_object() || !j.contains("name") || !j["name"].is_string() || j["name"].get<std::string>().empty())
            fail(where + " has no name");
        const std::string name = j["name"];
        if (!index.emplace(name, int(i)).second)
            fail("joint name '" + name + "' is used twice");
        if (!j.contains("position"))
            fail("joint '" + name + "' has no position");
        world.push_back(vec3(j["position"], "joint '" + name + "' position"));
        std::string parent;
        if (j.contains("parent") && !j["parent"].is_null()) {
            if (!j["parent"].is_string())
                fail("joint '" + name + "' parent is not a joint name");
            parent = j["parent"];
        }
        parentNames.push_back(parent);
        SkeletonNode node;
        node.name = name;
        s.nodes.push_back(node);
    }
    for (size_t i = 0; i < s.nodes.size(); ++i) {
        if (parentNames[i].empty())
            continue;
        const auto it = index.find(parentNames[i]);
        if (it == index.end())
            fail("joint '" + s.nodes[i].name + "' has unknown parent '" + parentNames[i] + "'");
        s.nodes[i].parent = it->second;
    }
    // A chain of parents longer than the joint count has looped.
    for (size_t i = 0; i < s.nodes.size(); ++i) {
        int v = int(i);
        for (size_t steps = 0; v >= 0; ++steps) {
            if (steps > s.nodes.size())
                fail("the joint hierarchy has a cycle through '" + s.nodes[i].name + "'");
            v = s.nodes[size_t(v)].parent;
        }
    }
    for (size_t i = 0; i < s.nodes.size(); ++i) {
        const int p = s.nodes[i].parent;
        const glm::vec3 offset = p >= 0 ? world[i] - world[size_t(p)] : world[i];
        if (p >= 0 && glm::length(offset) <= 1e-6f * (1.0f + glm::length(world[i])))
            fail("joint '" + s.nodes[i].name + "' coincides with its parent '" + s.nodes[size_t(p)].name + "'");
        s.nodes[i].rest.translation = offset;
        s.skin.joints.push_back(int(i));
        s.skin.inverseBindMatrices.push_back(glm::translate(glm::mat4(1.0f), -world[i]));
    }

    if (root.contains("animations")) {
        if (!root["animations"].is_array())
            fail("\"animations\" is not an array");
        for (size_t a = 0; a < root["animations"].size(); ++a) {
            const Json& aj = root["animations"][a];
            Animation anim;
            anim.name = aj.is_object() && aj.contains("name") && aj["name"].is_string()
                            ? aj["name"].get<std::string>()
                            : "animation" + std::to_string(a);
            const std::string where = "animation '" + anim.name + "'";
            AnimationInterpolation interpolation = AnimationInterpolation::Linear;
            if (aj.is_object() && aj.contains("interpolation")) {
                if (aj["interpolation"] == "linear")
                    interpolation = AnimationInterpolation::Linear;
                else if (aj["interpolation"] == "step")
                    interpolation = AnimationInterpolation::Step;
                else
                    fail(where + " interpolation is not \"linear\" or \"step\"");
            }
            if (!aj.is_object() || !aj.contains("keys") || !aj["keys"].is_array() || aj["keys"].empty())
                fail(where + " has no keys");
            // One channel per (joint, path), keyed where the joint appears.
            std::map<std::pair<int, int>, size_t> channelOf;
            float previous = -1e30f;
            for (const Json& key : aj["keys"]) {
                if (!key.is_object() || !key.contains("time"))
                    fail(where + " has a key without a time");
                const float time = number(key["time"], where + " key time");
                if (time < previous)
                    fail(where + " key times decrease at " + std::to_string(time));
                previous = time;
                for (const char* path : {"rotate", "translate"}) {
                    if (!key.contains(path))
                        continue;
                    if (!key[path].is_object())
                        fail(where + " key \"" + path + "\" is not an object of joint names");
                    for (auto it = key[path].begin(); it != key[path].end(); ++it) {
                        const auto found = index.find(it.key());
                        if (found == index.end())
                            fail(where + " keys unknown joint '" + it.key() + "'");
                        const bool rotate = path[0] == 'r';
                        const auto slot = channelOf.emplace(std::make_pair(found->second, rotate ? 1 : 0),
                                                            anim.channels.size());
                        if (slot.second) {
                            AnimationChannel c;
                            c.node = found->second;
                            c.path = rotate ? AnimationPath::Rotation : AnimationPath::Translation;
                            c.interpolation = interpolation;
                            anim.channels.push_back(c);
                        }
                        AnimationChannel& c = anim.channels[slot.first->second];
                        const std::string what = where + " '" + it.key() + "' " + path;
                        c.times.push_back(time);
                        if (rotate) {
                            const glm::quat q = rotation(it.value(), what);
                            c.values.insert(c.values.end(), {q.x, q.y, q.z, q.w});
                        } else {
                            // Offsets from the joint's rest place in its parent.
                            const glm::vec3 t = s.nodes[size_t(c.node)].rest.translation + vec3(it.value(), what);
                            c.values.insert(c.values.end(), {t.x, t.y, t.z});
                        }
                    }
                }
            }
            if (anim.channels.empty())
                fail(where + " keys no joint");
            s.animations.push_back(std::move(anim));
        }
    }
    s.weights.influences = 4;
    if (Status st = finalizeSkeleton(&s, 0); !st.isOk())
        fail(st.message());
    s.weights = VertexWeights();
    *out = std::move(s);
}

}  // namespace

Status parseJointFile(const std::string& text, const std::string& name, Skeleton* out)
{
    Json root;
    try {
        root = Json::parse(text);
    } catch (const std::exception& e) {
        return Status(StatusCode::InvalidData, name + ": not a JSON joint file (" + plainJsonError(e.what()) + ")");
    }
    try {
        parse(root, out);
    } catch (const ParseError& e) {
        return Status(StatusCode::InvalidData, name + ": " + e.message);
    } catch (const std::exception& e) {
        return Status(StatusCode::InvalidData, name + ": malformed joint file (" + plainJsonError(e.what()) + ")");
    }
    return Status::ok();
}

Status loadJointFile(const std::filesystem::path& pathFile, Skeleton* out)
{
    const std::string path = pathFile.string();
    std::vector<unsigned char> bytes;
    if (Status st = readFile(path, &bytes, size_t(256) << 20); !st.isOk())
        return st;
    return parseJointFile(std::string(bytes.begin(), bytes.end()), path, out);
}

}  // namespace io
}  // namespace strata
