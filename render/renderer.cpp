#include "render/renderer.h"

#include <algorithm>
#include <limits>

#include "engine/util/error.h"
#include "render/gl.h"
#include "render/shaders.h"

namespace incise {

struct Renderer::Gl {
  GLuint fbo = 0, color_rb = 0, depth_rb = 0;
  GLuint program = 0;
  GLint u_mvp = -1, u_color = -1, u_light = -1, u_ambient = -1;
  GLuint tissue_vao = 0, tissue_pos = 0, tissue_nrm = 0, tissue_ibo = 0;
  GLuint instr_vao = 0, instr_pos = 0, instr_nrm = 0;
  size_t tissue_bytes[2] = {0, 0}, instr_bytes[2] = {0, 0};  // capacity of the position, normal buffers
};

namespace {

void check_gl(const char* what) {
  const GLenum e = glGetError();
  if (e != GL_NO_ERROR) throw Error(std::string("render: OpenGL error 0x") + std::to_string(e) + " in " + what);
}

// A VAO reading positions (location 0) and normals (location 1) from two buffers.
void make_vao(GLuint& vao, GLuint& pos, GLuint& nrm) {
  glGenVertexArrays(1, &vao);
  glGenBuffers(1, &pos);
  glGenBuffers(1, &nrm);
  glBindVertexArray(vao);
  glBindBuffer(GL_ARRAY_BUFFER, pos);
  glEnableVertexAttribArray(0);
  glVertexAttribPointer(0, 3, GL_FLOAT, GL_FALSE, 0, nullptr);
  glBindBuffer(GL_ARRAY_BUFFER, nrm);
  glEnableVertexAttribArray(1);
  glVertexAttribPointer(1, 3, GL_FLOAT, GL_FALSE, 0, nullptr);
}

// Uploads into a buffer, growing it only when the data no longer fits.
void upload(GLuint buffer, const std::vector<float>& data, size_t& capacity, GLenum usage) {
  const size_t bytes = data.size() * sizeof(float);
  glBindBuffer(GL_ARRAY_BUFFER, buffer);
  if (bytes > capacity) {
    glBufferData(GL_ARRAY_BUFFER, static_cast<GLsizeiptr>(bytes), data.data(), usage);
    capacity = bytes;
  } else if (bytes > 0) {
    glBufferSubData(GL_ARRAY_BUFFER, 0, static_cast<GLsizeiptr>(bytes), data.data());
  }
}

}  // namespace

Renderer::Renderer(const RenderSettings& settings, EglPlatform platform)
    : settings_(settings), context_(std::make_unique<EglContext>(platform)), gl_(std::make_unique<Gl>()) {
  Gl& g = *gl_;
  const int w = settings_.width, h = settings_.height;
  glGenFramebuffers(1, &g.fbo);
  glBindFramebuffer(GL_FRAMEBUFFER, g.fbo);
  glGenRenderbuffers(1, &g.color_rb);
  glBindRenderbuffer(GL_RENDERBUFFER, g.color_rb);
  glRenderbufferStorage(GL_RENDERBUFFER, GL_RGBA8, w, h);
  glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_RENDERBUFFER, g.color_rb);
  glGenRenderbuffers(1, &g.depth_rb);
  glBindRenderbuffer(GL_RENDERBUFFER, g.depth_rb);
  glRenderbufferStorage(GL_RENDERBUFFER, GL_DEPTH_COMPONENT24, w, h);
  glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_DEPTH_ATTACHMENT, GL_RENDERBUFFER, g.depth_rb);
  const GLenum status = glCheckFramebufferStatus(GL_FRAMEBUFFER);
  if (status != GL_FRAMEBUFFER_COMPLETE)
    throw Error("render: framebuffer " + std::to_string(w) + "x" + std::to_string(h) + " incomplete (status 0x" +
                std::to_string(status) + ") on " + context_->description());
  g.program = build_shading_program();
  g.u_mvp = glGetUniformLocation(g.program, "u_mvp");
  g.u_color = glGetUniformLocation(g.program, "u_color");
  g.u_light = glGetUniformLocation(g.program, "u_light");
  g.u_ambient = glGetUniformLocation(g.program, "u_ambient");
  make_vao(g.tissue_vao, g.tissue_pos, g.tissue_nrm);
  glGenBuffers(1, &g.tissue_ibo);
  glBindBuffer(GL_ELEMENT_ARRAY_BUFFER, g.tissue_ibo);  // recorded in the tissue VAO
  make_vao(g.instr_vao, g.instr_pos, g.instr_nrm);
  glBindVertexArray(0);
  glViewport(0, 0, w, h);
  glEnable(GL_DEPTH_TEST);
  glDisable(GL_CULL_FACE);  // two-sided: cut and open surfaces show both sides
  check_gl("setup");
  camera_ = frame_camera(settings_, {-1, -1, -1}, {1, 1, 1});
}

Renderer::~Renderer() {
  if (!gl_) return;
  Gl& g = *gl_;
  try {
    context_->make_current();  // another renderer may have been current since
  } catch (const Error&) {
    return;  // objects die with the context
  }
  const GLuint buffers[] = {g.tissue_pos, g.tissue_nrm, g.tissue_ibo, g.instr_pos, g.instr_nrm};
  glDeleteBuffers(5, buffers);
  const GLuint vaos[] = {g.tissue_vao, g.instr_vao};
  glDeleteVertexArrays(2, vaos);
  const GLuint rbs[] = {g.color_rb, g.depth_rb};
  glDeleteRenderbuffers(2, rbs);
  glDeleteFramebuffers(1, &g.fbo);
  glDeleteProgram(g.program);
}

void Renderer::rebuild_topology(const DisplayMesh& mesh) {
  surface_ = extract_surface(mesh);
  tess_ = build_tessellation(surface_, mesh, settings_.subdivision);
  Gl& g = *gl_;
  glBindVertexArray(g.tissue_vao);
  glBindBuffer(GL_ELEMENT_ARRAY_BUFFER, g.tissue_ibo);
  glBufferData(GL_ELEMENT_ARRAY_BUFFER, static_cast<GLsizeiptr>(tess_.tris.size() * sizeof(unsigned)),
               tess_.tris.data(), GL_STATIC_DRAW);
  glBindVertexArray(0);
  g.tissue_bytes[0] = g.tissue_bytes[1] = 0;  // a fresh glBufferData of the vertex buffers
  ++stats_.topology_builds;
  stats_.nboundary = surface_.nboundary;
  stats_.ncut = surface_.ncut;
  stats_.ntriangle = static_cast<int>(tess_.tris.size() / 3);
  stats_.nvertex = tess_.nvert();
}

void Renderer::update(const DisplayMesh& mesh) {
  context_->make_current();
  const std::uint64_t sig = topology_signature(mesh);
  if (!have_mesh_ || sig != signature_) rebuild_topology(mesh);
  signature_ = sig;
  have_mesh_ = true;
  tessellate(surface_, tess_, mesh, pos_, nrm_, work_);
  if (!camera_set_) {
    Vec3 lo{}, hi{};
    for (int d = 0; d < 3; ++d) lo[d] = std::numeric_limits<double>::max(), hi[d] = -lo[d];
    for (int p = 0; p < mesh.npoint(); ++p)
      for (int d = 0; d < 3; ++d) lo[d] = std::min(lo[d], mesh.x(p, d)), hi[d] = std::max(hi[d], mesh.x(p, d));
    if (mesh.npoint() > 0) camera_ = frame_camera(settings_, lo, hi);
    camera_set_ = true;
  }
  Gl& g = *gl_;
  upload(g.tissue_pos, pos_, g.tissue_bytes[0], GL_DYNAMIC_DRAW);
  upload(g.tissue_nrm, nrm_, g.tissue_bytes[1], GL_DYNAMIC_DRAW);
  ++stats_.position_uploads;
  check_gl("update");
}

void Renderer::set_instruments(const std::vector<InstrumentShape>& instruments) {
  ipos_.clear();
  inrm_.clear();
  instrument_draws_.clear();
  for (const auto& s : instruments) {
    const size_t before = ipos_.size();
    instrument_triangles(s, ipos_, inrm_);
    instrument_draws_.push_back({static_cast<int>((ipos_.size() - before) / 3), s.color.value_or(settings_.color_instrument)});
  }
  context_->make_current();
  Gl& g = *gl_;
  upload(g.instr_pos, ipos_, g.instr_bytes[0], GL_DYNAMIC_DRAW);
  upload(g.instr_nrm, inrm_, g.instr_bytes[1], GL_DYNAMIC_DRAW);
  check_gl("set_instruments");
}

Image Renderer::render() {
  context_->make_current();
  Gl& g = *gl_;
  const int w = settings_.width, h = settings_.height;
  glBindFramebuffer(GL_FRAMEBUFFER, g.fbo);
  const Vec3& bg = settings_.color_background;
  glClearColor(static_cast<float>(bg[0]), static_cast<float>(bg[1]), static_cast<float>(bg[2]), 1.0f);
  glClear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);
  glUseProgram(g.program);
  const std::array<float, 16> mvp = view_projection(camera_, static_cast<double>(w) / h);
  glUniformMatrix4fv(g.u_mvp, 1, GL_FALSE, mvp.data());
  glUniform3f(g.u_light, static_cast<float>(camera_.light[0]), static_cast<float>(camera_.light[1]),
              static_cast<float>(camera_.light[2]));
  glUniform1f(g.u_ambient, static_cast<float>(settings_.ambient));
  auto color = [&](const Vec3& c) {
    glUniform3f(g.u_color, static_cast<float>(c[0]), static_cast<float>(c[1]), static_cast<float>(c[2]));
  };
  if (have_mesh_) {
    glBindVertexArray(g.tissue_vao);
    const GLsizei per_face = 3 * tess_.tris_per_face;
    color(settings_.color_tissue);
    glDrawElements(GL_TRIANGLES, per_face * surface_.nboundary, GL_UNSIGNED_INT, nullptr);
    color(settings_.color_interior);
    glDrawElements(GL_TRIANGLES, per_face * surface_.ncut, GL_UNSIGNED_INT,
                   reinterpret_cast<const void*>(sizeof(unsigned) * per_face * surface_.nboundary));
  }
  if (!instrument_draws_.empty()) {
    glBindVertexArray(g.instr_vao);
    GLint first = 0;
    for (const auto& [count, c] : instrument_draws_) {
      color(c);
      glDrawArrays(GL_TRIANGLES, first, count);
      first += count;
    }
  }
  glBindVertexArray(0);
  readback_.resize(4 * static_cast<size_t>(w) * h);
  glPixelStorei(GL_PACK_ALIGNMENT, 1);
  glReadPixels(0, 0, w, h, GL_RGBA, GL_UNSIGNED_BYTE, readback_.data());
  check_gl("render");
  Image img;
  img.width = w;
  img.height = h;
  img.rgb.resize(3 * static_cast<size_t>(w) * h);
  for (int y = 0; y < h; ++y) {  // GL rows start at the bottom
    const unsigned char* src = &readback_[4 * static_cast<size_t>(h - 1 - y) * w];
    unsigned char* dst = &img.rgb[3 * static_cast<size_t>(y) * w];
    for (int x = 0; x < w; ++x) dst[3 * x] = src[4 * x], dst[3 * x + 1] = src[4 * x + 1], dst[3 * x + 2] = src[4 * x + 2];
  }
  return img;
}

}  // namespace incise
