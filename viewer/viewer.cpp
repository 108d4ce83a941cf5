#include "viewer.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <iterator>
#include <memory>
#include <ostream>
#include <stdexcept>
#include <string>
#include <vector>

#include <GL/glew.h>
#include <GLFW/glfw3.h>
#include <imgui.h>
#include <backends/imgui_impl_glfw.h>
#include <backends/imgui_impl_opengl3.h>

#include "pipeline/pipeline.h"
#include "render/image.h"
#include "render/render.h"
#include "render/screen_space.h"
#include "io/scene.h"
#include "sphray_shaders.h"
#if defined(SPHRAY_HAVE_CUDA)
#include "interop.h"
#endif

namespace sphray {

bool viewer_built() { return true; }

namespace {

GLuint compile(GLenum type, const char* src) {
  const GLuint s = glCreateShader(type);
  glShaderSource(s, 1, &src, nullptr);
  glCompileShader(s);
  GLint ok = 0;
  glGetShaderiv(s, GL_COMPILE_STATUS, &ok);
  if (!ok) {
    char log[2048];
    glGetShaderInfoLog(s, sizeof log, nullptr, log);
    throw std::runtime_error(std::string("viewer: shader does not compile: ") + log);
  }
  return s;
}

GLuint display_program() {
  const GLuint p = glCreateProgram();
  const GLuint v = compile(GL_VERTEX_SHADER, shaders::display_vert), f = compile(GL_FRAGMENT_SHADER, shaders::display_frag);
  glAttachShader(p, v);
  glAttachShader(p, f);
  glLinkProgram(p);
  glDeleteShader(v);
  glDeleteShader(f);
  GLint ok = 0;
  glGetProgramiv(p, GL_LINK_STATUS, &ok);
  if (!ok) throw std::runtime_error("viewer: shader program does not link");
  return p;
}

// Mouse orbit around a target: yaw and pitch in radians, distance in metres.
struct Orbit {
  Vec3d target;
  double yaw = 0, pitch = 0, dist = 1;
  static Orbit from(Vec3d eye, Vec3d target) {
    Orbit o;
    o.target = target;
    const Vec3d d = eye - target;
    o.dist = length(d);
    o.yaw = std::atan2(d.y, d.x);
    o.pitch = std::asin(std::clamp(d.z / o.dist, -1.0, 1.0));
    return o;
  }
  Vec3d eye() const {
    return target + Vec3d{std::cos(pitch) * std::cos(yaw), std::cos(pitch) * std::sin(yaw), std::sin(pitch)} * dist;
  }
};

struct Window {
  GLFWwindow* w = nullptr;
  ~Window() {
    if (w) glfwDestroyWindow(w);
    glfwTerminate();
  }
};

struct Controls {
  bool paused = false, step_once = false, reset = false;
  Orbit orbit;
  double last_x = 0, last_y = 0;
  bool dragging = false;
};

void key_callback(GLFWwindow* w, int key, int, int action, int) {
  if (action != GLFW_PRESS || ImGui::GetIO().WantCaptureKeyboard) return;
  auto* c = static_cast<Controls*>(glfwGetWindowUserPointer(w));
  if (key == GLFW_KEY_SPACE) c->paused = !c->paused;
  if (key == GLFW_KEY_N) { c->paused = true; c->step_once = true; }
  if (key == GLFW_KEY_R) c->reset = true;
  if (key == GLFW_KEY_ESCAPE) glfwSetWindowShouldClose(w, 1);
}

void scroll_callback(GLFWwindow* w, double, double dy) {
  if (ImGui::GetIO().WantCaptureMouse) return;
  auto* c = static_cast<Controls*>(glfwGetWindowUserPointer(w));
  c->orbit.dist *= std::pow(0.9, dy);
}

void mouse_move(GLFWwindow* w, Controls& c) {
  double x, y;
  glfwGetCursorPos(w, &x, &y);
  const bool down = glfwGetMouseButton(w, GLFW_MOUSE_BUTTON_LEFT) == GLFW_PRESS && !ImGui::GetIO().WantCaptureMouse;
  if (down && c.dragging) {
    c.orbit.yaw -= 0.005 * (x - c.last_x);
    c.orbit.pitch = std::clamp(c.orbit.pitch + 0.005 * (y - c.last_y), -1.5, 1.5);
  }
  c.dragging = down;
  c.last_x = x;
  c.last_y = y;
}

// GLFW and an OpenGL 3.3 core context with GLEW's functions loaded.
void open_window(Window& win, int w, int h, const std::string& title, bool vsync, std::ostream& log) {
  if (!glfwInit()) throw std::runtime_error("viewer: cannot initialise GLFW (is there a display? try xvfb-run)");
  glfwWindowHint(GLFW_CONTEXT_VERSION_MAJOR, 3);
  glfwWindowHint(GLFW_CONTEXT_VERSION_MINOR, 3);
  glfwWindowHint(GLFW_OPENGL_PROFILE, GLFW_OPENGL_CORE_PROFILE);
  win.w = glfwCreateWindow(w, h, title.c_str(), nullptr, nullptr);
  if (!win.w) throw std::runtime_error("viewer: cannot open an OpenGL 3.3 window (no display, or no GL 3.3)");
  glfwMakeContextCurrent(win.w);
  glfwSwapInterval(vsync ? 1 : 0);
  glewExperimental = GL_TRUE;
  if (glewInit() != GLEW_OK) throw std::runtime_error("viewer: GLEW cannot load the OpenGL functions");
  log << "viewer: OpenGL " << glGetString(GL_VERSION) << " (" << glGetString(GL_RENDERER) << ")\n";
}

// Dear ImGui on the window, for the panel; the controls' callbacks first
// (ImGui chains to the callbacks it finds).
struct Gui {
  Gui(GLFWwindow* w, Controls& ctl) {
    glfwSetWindowUserPointer(w, &ctl);
    glfwSetKeyCallback(w, key_callback);
    glfwSetScrollCallback(w, scroll_callback);
    IMGUI_CHECKVERSION();
    ImGui::CreateContext();
    ImGui::GetIO().IniFilename = nullptr;
    ImGui_ImplGlfw_InitForOpenGL(w, true);
    ImGui_ImplOpenGL3_Init("#version 330");
  }
  ~Gui() {
    ImGui_ImplOpenGL3_Shutdown();
    ImGui_ImplGlfw_Shutdown();
    ImGui::DestroyContext();
  }
};

// The image on screen: one texture the size of the raycast image, drawn
// over the window; on CUDA a GL pixel buffer the raycaster writes into
// (CUDA-OpenGL interop). Both follow the framebuffer's size, so the image is
// never stretched.
class Display {
 public:
  Display(Backend b, std::ostream& log) : backend_(b), log_(log), program_(display_program()) {
    glGenVertexArrays(1, &vao_);
    glGenTextures(1, &tex_);
    glBindTexture(GL_TEXTURE_2D, tex_);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_LINEAR);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
#if defined(SPHRAY_HAVE_CUDA)
    try_interop_ = b == Backend::Cuda;
#endif
  }
  ~Display() {
#if defined(SPHRAY_HAVE_CUDA)
    interop_.reset();
#endif
    glDeleteBuffers(1, &pbo_);
    glDeleteTextures(1, &tex_);
    glDeleteVertexArrays(1, &vao_);
    glDeleteProgram(program_);
  }
  bool interop() const {
#if defined(SPHRAY_HAVE_CUDA)
    return interop_ != nullptr;
#else
    return false;  // built without CUDA: the image goes through the host
#endif
  }

  void allocate(int w, int h) {
    w_ = w;
    h_ = h;
    glBindTexture(GL_TEXTURE_2D, tex_);
    glTexImage2D(GL_TEXTURE_2D, 0, GL_RGBA8, w, h, 0, GL_RGBA, GL_UNSIGNED_BYTE, nullptr);
#if defined(SPHRAY_HAVE_CUDA)
    if (!try_interop_) return;
    interop_.reset();  // unregistered before its buffer is resized
    if (!pbo_) glGenBuffers(1, &pbo_);
    glBindBuffer(GL_PIXEL_UNPACK_BUFFER, pbo_);
    glBufferData(GL_PIXEL_UNPACK_BUFFER, GLsizeiptr(w) * h * 4, nullptr, GL_STREAM_DRAW);
    glBindBuffer(GL_PIXEL_UNPACK_BUFFER, 0);
    try {
      interop_ = std::make_unique<GlPixelBufferCuda>(pbo_);
    } catch (const std::exception& e) {
      // e.g. a GL that is not on the CUDA device (Mesa under Xvfb): still show the image, through the host
      log_ << "viewer: " << e.what() << "; the image goes through the host instead\n";
      glDeleteBuffers(1, &pbo_);
      pbo_ = 0;
      try_interop_ = false;
    }
#endif
  }

  // Renders the field or the particles (by rs.method) into the texture.
  void render(Renderer& r, const RenderInput& in, const Camera& cam, const Environment& env,
              const RenderSettings& rs) {
    glBindTexture(GL_TEXTURE_2D, tex_);
#if defined(SPHRAY_HAVE_CUDA)
    if (interop_) {  // the CUDA raycaster writes into the GL buffer; GL copies it into the texture on the device
      r.set_target(interop_->map());
      r.render(in, cam, env, rs);
      interop_->unmap();
      glBindBuffer(GL_PIXEL_UNPACK_BUFFER, pbo_);
      glTexSubImage2D(GL_TEXTURE_2D, 0, 0, 0, w_, h_, GL_RGBA, GL_UNSIGNED_BYTE, nullptr);
      glBindBuffer(GL_PIXEL_UNPACK_BUFFER, 0);
      return;
    }
#endif
    // CPU: texture upload; CUDA without interop: the image through the host
    r.render(in, cam, env, rs);
    if (backend_ == Backend::Cpu) {
      glTexSubImage2D(GL_TEXTURE_2D, 0, 0, 0, w_, h_, GL_RGBA, GL_UNSIGNED_BYTE, r.pixels());
    } else {
      const Image img = r.download();
      glTexSubImage2D(GL_TEXTURE_2D, 0, 0, 0, w_, h_, GL_RGBA, GL_UNSIGNED_BYTE, img.rgba.data());
    }
  }

  void draw(int fw, int fh) const {
    glViewport(0, 0, fw, fh);
    glClear(GL_COLOR_BUFFER_BIT);
    glUseProgram(program_);
    glBindVertexArray(vao_);
    glDrawArrays(GL_TRIANGLES, 0, 3);
  }

 private:
  Backend backend_;
  std::ostream& log_;
  GLuint program_, vao_ = 0, tex_ = 0, pbo_ = 0;
  int w_ = 0, h_ = 0;
#if defined(SPHRAY_HAVE_CUDA)
  std::unique_ptr<GlPixelBufferCuda> interop_;
  bool try_interop_ = false;
#endif
};

// What the panel shows and sets.
struct PanelState {
  bool realtime = true;  // real-time playback, or `substeps` steps per frame
  int substeps = 2, builder_index = 1;
  FieldKind kind = FieldKind::Presence;
  FieldKernel kernel = FieldKernel::Isotropic;  // spheres, ellipsoids or Zhu & Bridson's surface
  bool draws_field = true;   // the render method draws the field (screen_space draws the particles)
  double sim_ms = 0, field_ms = 0, render_ms = 0, fps = 0;
  int steps = 0;                  // SPH steps in the last frame
  double frame_wall_s = 0;        // the last frame's wall time
  double sim_advance_s = 0;       // simulated time the last frame advanced
  double realtime_factor = 0;     // simulated seconds per wall second, smoothed
  std::string status;
};

// Real-time playback far below real speed under WCSPH, whose step is the
// acoustic one (docs/rendering.md, "The viewer"): the panel and the closing
// line name the solver that plays a scene faster; "" otherwise.
std::string slow_motion_hint(const PanelState& s, SolverKind kind) {
  constexpr double kSlowMotion = 0.5;  // x real time
  if (!s.realtime || kind != SolverKind::Wcsph || s.realtime_factor <= 0 || s.realtime_factor >= kSlowMotion) return "";
  return "slow motion: WCSPH steps at the speed of sound; --set sph.solver=pbf (position-based fluids) takes far "
         "larger steps";
}

void draw_panel(PanelState& s, RenderSettings& rs, const Solver& solver, Backend b, bool paused, int w, int h) {
  ImGui_ImplOpenGL3_NewFrame();
  ImGui_ImplGlfw_NewFrame();
  ImGui::NewFrame();
  ImGui::SetNextWindowPos(ImVec2(8, 8), ImGuiCond_Once);
  ImGui::SetNextWindowCollapsed(w < 900, ImGuiCond_Once);  // a small window starts with the panel folded
  ImGui::Begin("sphray", nullptr, ImGuiWindowFlags_AlwaysAutoResize);
  ImGui::Text("%s backend, %zu particles, t = %.3f s", backend_name(b), solver.num_fluid(), solver.time());
  ImGui::Text("solver %s, %d steps this frame, x%.3f real time", solver_name(solver.kind()), s.steps, s.realtime_factor);
  const std::string hint = slow_motion_hint(s, solver.kind());
  if (!hint.empty()) ImGui::TextWrapped("%s", hint.c_str());
  ImGui::Checkbox("real-time playback", &s.realtime);
  if (!s.realtime) ImGui::SliderInt("substeps / frame", &s.substeps, 1, 20);
  const char* methods[] = {"raycast", "screen_space", "slices"};
  int method = int(rs.method);
  if (ImGui::Combo("render method", &method, methods, 3)) rs.method = RenderMethod(method);
  if (rs.method == RenderMethod::ScreenSpace) {  // the particles' spheres: no field
    ImGui::SliderInt("filter width", &rs.filter_width, 1, BilateralDepth::kMaxWidth);
    ImGui::SliderInt("filter passes", &rs.filter_iterations, 0, 64);
  } else {
    const char* builders[] = {"naive", "presence", "gather"};
    if (ImGui::Combo("field builder", &s.builder_index, builders, 3))
      s.kind = parse_field_kind(builders[s.builder_index]);
    const char* kernels[std::size(kFieldKernels)];
    for (size_t k = 0; k < std::size(kFieldKernels); ++k) kernels[k] = field_kernel_name(kFieldKernels[k]);
    int kernel = int(s.kernel);
    if (ImGui::Combo("field kernel", &kernel, kernels, int(std::size(kernels)))) s.kernel = kFieldKernels[kernel];
    if (rs.method == RenderMethod::Slices) ImGui::SliderInt("slices", &rs.slices, 8, 4096);
    ImGui::SliderInt("interfaces", &rs.interfaces, 1, 8);
    ImGui::Checkbox("reflections traced", &rs.reflections);
    if (rs.reflections) ImGui::SliderInt("branch budget", &rs.budget, 1, 64);
  }
  ImGui::Text("sim %.2f ms  field %.2f ms  render %.2f ms", s.sim_ms, s.field_ms, s.render_ms);
  ImGui::Text("%.1f fps (%dx%d)", s.fps, w, h);
  ImGui::Text("drag: orbit  wheel: zoom  space: pause  N: step  R: reset");
  if (paused) ImGui::Text("paused");
  if (!s.status.empty()) ImGui::TextWrapped("%s", s.status.c_str());
  ImGui::End();
  ImGui::Render();
  ImGui_ImplOpenGL3_RenderDrawData(ImGui::GetDrawData());
}

// The field builder the panel asks for (builder and kernel), or the one in
// use with the reason in the status line where the scene cannot take it.
std::unique_ptr<FieldBuilder> switch_field(const ResolvedScene& rscene, Backend b, const FieldBuilder& current,
                                           PanelState& s) {
  const FieldSetup* setup = &current.setup();
  FieldSetup other;
  if (current.setup().kernel != s.kernel) {
    ResolvedScene r = rscene;
    r.scene.field.kernel = s.kernel;
    try {
      other = make_field_setup(r);
      setup = &other;
    } catch (const std::exception& e) {
      s.kernel = current.setup().kernel;
      s.status = e.what();
    }
  }
  if (setup->kernel == FieldKernel::Anisotropic && s.kind == FieldKind::Gather) {
    s.status = "the gather builder takes no ellipsoids: presence instead";
    s.kind = FieldKind::Presence;
    s.builder_index = int(s.kind);
  }
  if (setup->kernel == FieldKernel::ZhuBridson && s.kind != FieldKind::Gather) {
    s.status = "Zhu & Bridson's surface is built by the gather builder";
    s.kind = FieldKind::Gather;
    s.builder_index = int(s.kind);
  }
  return make_field_builder(b, *setup, s.kind);
}

// One displayed frame of simulation unless paused (or N: one step while
// paused): the steps that bring it to the previous frame's wall time (real-
// time playback, at most `max_sim` seconds), or `substeps` steps. A run
// stopped by a guard pauses with its message.
void simulate(const Scene& scene, Solver& solver, PanelState& s, Controls& ctl, double max_sim) {
  const double end_time = scene.run.end_time;
  s.steps = 0;
  s.sim_advance_s = 0;
  if ((ctl.paused && !ctl.step_once) || solver.time() >= end_time) return;
  const bool presence = s.draws_field && field_needs_presence_step(scene, s.kind, s.kernel == FieldKernel::Anisotropic);
  const double t0 = solver.time();
  try {
    if (s.realtime && !ctl.step_once) {
      const FrameAdvance a =
          advance_to(solver, playback_target(t0, s.frame_wall_s, max_sim, end_time), presence, max_sim);
      s.sim_ms = a.ms;
      s.steps = a.steps;
    } else {
      const uint64_t before = solver.steps();
      s.sim_ms = advance_frame(solver, ctl.step_once ? 1 : s.substeps, presence, end_time);
      s.steps = int(solver.steps() - before);
    }
  } catch (const SimulationError& e) {
    s.status = std::string("stopped: ") + e.what();
    ctl.paused = true;
  }
  ctl.step_once = false;
}

// The window's back buffer as a PNG (GL's row 0 is the bottom).
void screenshot(const std::string& path, int fw, int fh) {
  Image img;
  img.width = fw;
  img.height = fh;
  img.rgba.resize(size_t(fw) * size_t(fh));
  std::vector<uint32_t> rows(img.rgba.size());
  glPixelStorei(GL_PACK_ALIGNMENT, 4);
  glReadBuffer(GL_BACK);
  glReadPixels(0, 0, fw, fh, GL_RGBA, GL_UNSIGNED_BYTE, rows.data());
  for (int y = 0; y < fh; ++y) std::copy_n(rows.data() + size_t(fh - 1 - y) * fw, fw, img.rgba.data() + size_t(y) * fw);
  write_png(path, img);
}

}  // namespace

int run_viewer(const ViewOptions& opt, std::ostream& log) {
  const auto t_start = std::chrono::steady_clock::now();
  const ResolvedScene rscene = resolve_view_scene(opt);
  const Scene& scene = rscene.scene;
  const Backend b = choose_backend(opt.backend, log);
  if (const std::string note = cpu_scale_note(rscene, b); !note.empty()) log << "viewer: " << note << "\n";
  int W = scene.render.width, H = scene.render.height;  // the raycast image: the window's framebuffer
  Window win;
  open_window(win, W, H, "sphray view: " + scene.name, opt.frames == 0, log);
  Controls ctl;
  const Gui gui(win.w, ctl);
  Display display(b, log);
  display.allocate(W, H);
  if (display.interop()) log << "viewer: CUDA raycast straight into a GL pixel buffer (CUDA-OpenGL interop)\n";

  // The pipeline: every stage is needed here.
  PanelState s;
  s.realtime = opt.substeps == 0;
  s.substeps = opt.substeps > 0 ? opt.substeps : 2;
  s.kind = scene.field.builder;
  s.builder_index = int(s.kind);
  s.kernel = scene.field.kernel;
  const StageNeeds needs{PresenceMode::Off, true};
  auto new_solver = [&] { return opt.make_solver ? opt.make_solver(rscene, b) : make_solver(rscene, b, needs); };
  std::unique_ptr<Solver> solver = new_solver();
  bool gather = true;  // the particles moved since the last gather (a run over several ranks)
  std::unique_ptr<FieldBuilder> field = make_field(rscene, b, needs);
  std::unique_ptr<Renderer> renderer = make_renderer(b);
  renderer->set_obstacles(drawn_obstacles(obstacle_meshes(scene), *solver));
  RenderSettings rs = scene.render;
  {
    Vec3d eye, target;
    camera_points(scene.tank, rs, eye, target);
    ctl.orbit = Orbit::from(eye, target);
  }
  int frame = 0;
  auto last = std::chrono::steady_clock::now();
  while (!glfwWindowShouldClose(win.w)) {
    glfwPollEvents();
    if (opt.resize_w > 0 && frame == 1) glfwSetWindowSize(win.w, opt.resize_w, opt.resize_h);
    int fw = 0, fh = 0;
    glfwGetFramebufferSize(win.w, &fw, &fh);
    if (fw > 0 && fh > 0 && (fw != W || fh != H)) display.allocate(W = fw, H = fh);  // resized (not minimised)
    mouse_move(win.w, ctl);
    if (ctl.reset) {
      solver.reset();  // its buffers first
      solver = new_solver();
      gather = true;
      ctl.reset = false;
      s.status.clear();
    }
    const double t_before = solver->time();
    s.draws_field = method_needs_field(rs.method);
    simulate(scene, *solver, s, ctl, opt.max_sim_per_frame);
    s.sim_advance_s = solver->time() - t_before;
    if (gather || s.steps > 0) solver->gather_frame();
    gather = false;
    const ParticleView pv = solver->view();
    if (field->kind() != s.kind || field->setup().kernel != s.kernel)  // switched in the panel
      field = switch_field(rscene, b, *field, s);
    if (s.draws_field) field->build(pv);
    s.field_ms = s.draws_field ? field->last_ms() : 0.0;
    const Camera cam = look_at(ctl.orbit.eye(), ctl.orbit.target, rs.fov, W, H);
    show_skins(*solver, *renderer);
    display.render(*renderer,
                   RenderInput{s.draws_field ? field->data() : nullptr, &field->setup(), pv, scene.sph.spacing,
                               solver->time()},
                   cam, make_environment(scene.tank, field->setup().geom, cam), rs);
    s.render_ms = renderer->last_ms();
    display.draw(fw, fh);
    draw_panel(s, rs, *solver, b, ctl.paused, W, H);
    if (++frame == 1)
      log << "viewer: first frame after "
          << std::chrono::duration<double>(std::chrono::steady_clock::now() - t_start).count() << " s\n";
    if (opt.frames > 0 && frame >= opt.frames) {
      if (!opt.screenshot.empty()) {
        screenshot(opt.screenshot, fw, fh);
        log << "viewer: wrote " << opt.screenshot << " after " << frame << " frames\n";
      }
      log << "viewer: " << frame << " frames, " << s.fps << " fps at the end (sim " << s.sim_ms << " ms, field "
          << s.field_ms << " ms, render " << s.render_ms << " ms in the last frame); "
          << (s.realtime ? "real-time playback, x" + std::to_string(s.realtime_factor) + " real time, "
                         : "fixed substeps, ")
          << s.steps << " steps in the last frame, t = " << solver->time() << " s\n";
      const std::string hint = slow_motion_hint(s, solver->kind());
      if (!hint.empty()) log << "viewer: " << hint << "\n";
      break;
    }
    glfwSwapBuffers(win.w);
    const auto now = std::chrono::steady_clock::now();
    const double dt = std::chrono::duration<double>(now - last).count();
    last = now;
    s.fps = s.fps == 0 ? 1.0 / dt : 0.9 * s.fps + 0.1 / dt;
    s.frame_wall_s = dt;
    const double x = s.sim_advance_s / dt;
    s.realtime_factor = s.realtime_factor == 0 ? x : 0.9 * s.realtime_factor + 0.1 * x;
  }
  return 0;
}

}  // namespace sphray
