#include "render/shaders.h"

#include <string>

#include "engine/util/error.h"
#include "render/gl.h"

namespace incise {
namespace {

const char* kVertex = R"(#version 330 core
layout(location = 0) in vec3 a_pos;
layout(location = 1) in vec3 a_nrm;
uniform mat4 u_mvp;
out vec3 v_nrm;
void main() {
  v_nrm = a_nrm;
  gl_Position = u_mvp * vec4(a_pos, 1.0);
}
)";

const char* kFragment = R"(#version 330 core
in vec3 v_nrm;
uniform vec3 u_color;
uniform vec3 u_light;    // unit direction the light travels
uniform float u_ambient;
out vec4 frag;
void main() {
  vec3 n = normalize(v_nrm);
  if (!gl_FrontFacing) n = -n;
  float diffuse = max(dot(n, -u_light), 0.0);
  frag = vec4(u_color * (u_ambient + (1.0 - u_ambient) * diffuse), 1.0);
}
)";

GLuint compile(GLenum type, const char* src, const char* name) {
  GLuint s = glCreateShader(type);
  glShaderSource(s, 1, &src, nullptr);
  glCompileShader(s);
  GLint ok = 0;
  glGetShaderiv(s, GL_COMPILE_STATUS, &ok);
  if (!ok) {
    char log[2048] = {0};
    glGetShaderInfoLog(s, sizeof log, nullptr, log);
    glDeleteShader(s);
    throw Error(std::string("render: ") + name + " shader does not compile: " + log);
  }
  return s;
}

}  // namespace

unsigned build_shading_program() {
  GLuint vs = compile(GL_VERTEX_SHADER, kVertex, "vertex");
  GLuint fs = compile(GL_FRAGMENT_SHADER, kFragment, "fragment");
  GLuint p = glCreateProgram();
  glAttachShader(p, vs);
  glAttachShader(p, fs);
  glLinkProgram(p);
  glDeleteShader(vs);
  glDeleteShader(fs);
  GLint ok = 0;
  glGetProgramiv(p, GL_LINK_STATUS, &ok);
  if (!ok) {
    char log[2048] = {0};
    glGetProgramInfoLog(p, sizeof log, nullptr, log);
    glDeleteProgram(p);
    throw Error(std::string("render: shading program does not link: ") + log);
  }
  return p;
}

}  // namespace incise
