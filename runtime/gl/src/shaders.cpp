#include "strata/gl/shaders.h"

namespace strata {
namespace gl {

namespace embedded {
extern const char* const displacementMath;
extern const char* const sampleMap;
extern const char* const refineComp;
extern const char* const displaceComp;
extern const char* const normalsComp;
extern const char* const surfaceVert;
extern const char* const surfaceFrag;
extern const char* const linesVert;
extern const char* const linesFrag;
}  // namespace embedded

std::string shaderSource(ShaderId id, const std::string& defines)
{
    std::string s = "#version 450 core\n" + defines + "\n";
    const bool sampler = id == ShaderId::Displace || id == ShaderId::SurfaceVertex;
    if (id == ShaderId::Refine || sampler) {
        s += embedded::displacementMath;
        s += "\n";
    }
    if (sampler) {
        s += embedded::sampleMap;
        s += "\n";
    }
    switch (id) {
    case ShaderId::Refine: s += embedded::refineComp; break;
    case ShaderId::Displace: s += embedded::displaceComp; break;
    case ShaderId::Normals: s += embedded::normalsComp; break;
    case ShaderId::SurfaceVertex: s += embedded::surfaceVert; break;
    case ShaderId::SurfaceFragment: s += embedded::surfaceFrag; break;
    case ShaderId::LinesVertex: s += embedded::linesVert; break;
    case ShaderId::LinesFragment: s += embedded::linesFrag; break;
    }
    return s;
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
