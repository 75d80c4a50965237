#include "strata/gl/shaders.h"

namespace strata {
namespace gl {

namespace embedded {
extern const char* const displacementMath;
extern const char* const sampleMap;
extern const char* const refineComp;
extern const char* const displaceComp;
extern const char* const normalsComp;
}  // namespace embedded

std::string samplingPrelude(const std::string& defines)
{
    return "#version 450 core\n" + defines + "\n" + embedded::displacementMath + "\n" + embedded::sampleMap + "\n";
}

std::string shaderSource(ShaderId id, const std::string& defines)
{
    switch (id) {
    case ShaderId::Refine:
        return "#version 450 core\n" + defines + "\n" + embedded::displacementMath + "\n" + embedded::refineComp;
    case ShaderId::Displace: return samplingPrelude(defines) + embedded::displaceComp;
    case ShaderId::Normals: return "#version 450 core\n" + defines + "\n" + embedded::normalsComp;
    }
    return std::string();
}

namespace {

std::string shaderLog(GLuint shader)
{
    GLint length = 0;
    glGetShaderiv(shader, GL_INFO_LOG_LENGTH, &length);
    std::string log(size_t(std::max(length, 1)), '\0');
    glGetShaderInfoLog(shader, length, nullptr, &log[0]);
    return log.c_str();
}

std::string programLog(GLuint program)
{
    GLint length = 0;
    glGetProgramiv(program, GL_INFO_LOG_LENGTH, &length);
    std::string log(size_t(std::max(length, 1)), '\0');
    glGetProgramInfoLog(program, length, nullptr, &log[0]);
    return log.c_str();
}

}  // namespace

Status buildProgram(GLuint* out, const std::string& label, const std::vector<StageSource>& stages,
                    const std::vector<const char*>& feedbackVaryings)
{
    const GLuint program = glCreateProgram();
    std::vector<GLuint> shaders;
    Status st;
    for (const StageSource& s : stages) {
        const GLuint shader = glCreateShader(s.stage);
        const char* text = s.source.c_str();
        glShaderSource(shader, 1, &text, nullptr);
        glCompileShader(shader);
        GLint ok = 0;
        glGetShaderiv(shader, GL_COMPILE_STATUS, &ok);
        shaders.push_back(shader);
        if (!ok) {
            st = Status(StatusCode::Unsupported, label + ": shader does not compile: " + shaderLog(shader));
            break;
        }
        glAttachShader(program, shader);
    }
    if (st.isOk()) {
        if (!feedbackVaryings.empty())
            glTransformFeedbackVaryings(program, GLsizei(feedbackVaryings.size()), feedbackVaryings.data(),
                                        GL_INTERLEAVED_ATTRIBS);
        glLinkProgram(program);
        GLint ok = 0;
        glGetProgramiv(program, GL_LINK_STATUS, &ok);
        if (!ok)
            st = Status(StatusCode::Unsupported, label + ": program does not link: " + programLog(program));
    }
    for (GLuint shader : shaders)
        glDeleteShader(shader);
    if (!st.isOk()) {
        glDeleteProgram(program);
        return st;
    }
    *out = program;
    return Status::ok();
}

}  // namespace gl
}  // namespace strata
