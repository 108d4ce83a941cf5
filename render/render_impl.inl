// The renderer's driver, written once for both backends. Included by
// render_cpu.cpp and render_cuda.cu inside their backend namespace (which
// supplies Vector, raw, parallel_for, download, StageClock, kBackend).

class RendererImpl final : public Renderer {
 public:
  Backend backend() const override { return kBackend; }
  double last_ms() const override { return ms_; }
  const uint32_t* pixels() const override { return target_ ? target_ : raw(image_); }
  void set_target(uint32_t* p) override { target_ = p; }
  void set_obstacles(const std::vector<MeshInput>& meshes) override {
    obstacles_ = make_obstacle_set(kBackend, meshes, 0.0f);
  }
  void set_obstacle_vertices(uint32_t k, const std::vector<Vec3f>& vertices) override {
    if (k >= obstacles_.trees.size()) throw std::out_of_range("renderer: no obstacle " + std::to_string(k));
    obstacles_.trees[k]->refit(vertices);
    obstacles_.view.mesh[k] = obstacles_.trees[k]->view();
  }

  Image download() const override {
    Image img;
    img.width = width_;
    img.height = height_;
    if (target_) throw std::logic_error("renderer: download() of an external target");
    img.rgba = sphray::SPHRAY_BK::download(image_, size_t(width_) * size_t(height_));
    return img;
  }

  using Renderer::render;
  void render(const RenderInput& in, const Camera& cam, const Environment& env, const RenderSettings& rs) override {
    if (cam.width <= 0 || cam.height <= 0) throw std::invalid_argument("renderer: empty image");
    if (!in.setup) throw std::logic_error("renderer: no field setup");
    width_ = cam.width;
    height_ = cam.height;
    const uint32_t n_pix = uint32_t(width_) * uint32_t(height_);
    if (!target_ && image_.size() < n_pix) image_.resize(n_pix);
    uint32_t* out = target_ ? target_ : raw(image_);
    clock_.start();
    stage_names_.clear();
    if (rs.method == RenderMethod::ScreenSpace) {
      screen_space(in, cam, env, rs, out);
    } else {
      if (!in.field) throw std::logic_error("renderer: the raycast and slices methods need the field");
      march(in.field, *in.setup, cam, env, rs, out, in.time);
    }
    clock_.finish();
    stages_.clear();
    for (const char* s : stage_names_) stages_.emplace_back(s, clock_.ms(s));
    ms_ = 0;
    for (const auto& s : stages_) ms_ += s.second;
  }

  std::vector<std::pair<std::string, double>> last_stages() const override { return stages_; }

 private:
  void mark(const char* stage) {
    clock_.end_of(stage);
    stage_names_.push_back(stage);
  }

  // raycast and slices: the tracer through the field.
  void march(const float* field, const FieldSetup& fs, const Camera& cam, const Environment& env,
             const RenderSettings& rs, uint32_t* out, double time) {
    const VolumeGeom& vol = fs.geom;
    const int brick = 1 << vol.refine;  // bricks as wide as the SPH cells: 1 voxel at refine 0, 4 at refine 2
    Occupancy occ{nullptr, (vol.nx + brick - 1) / brick, (vol.ny + brick - 1) / brick, (vol.nz + brick - 1) / brick,
                  brick};
    if (rs.skip_empty) {
      const uint32_t bricks = uint32_t(occ.cx) * uint32_t(occ.cy) * uint32_t(occ.cz);
      if (occupancy_.size() < bricks) occupancy_.resize(bricks);
      parallel_for("render_occupancy", bricks,
                   BuildOccupancy{field, vol.nx, vol.ny, vol.nz, brick, fs.shape.iso, raw(occupancy_)});
      occ.occ = raw(occupancy_);
    }
    mark("occupancy");
    const TrilinearField tri{field, vol.nx, vol.ny, vol.nz};
    const Vec3f box{float(vol.nx), float(vol.ny), float(vol.nz)};
    const TraceSettings ts = make_trace_settings(rs, fs, cam);
    const char* name = rs.method == RenderMethod::Slices ? "render_slices" : "render_raycast";
    const uint32_t items = PixelTiles{width_, height_}.items();
    if (obstacles_.view.count > 0) {
      MeshHits meshes;
      meshes.obstacles = obstacles_.view;
      meshes.origin = vol.origin;
      meshes.voxel = vol.voxel;
      meshes.at_time(float(time));
      const Tracer<TrilinearField, 16, MeshHits> tracer{tri, occ, box, env, ts, meshes};
      parallel_for(name, items, RaycastPixels<TrilinearField, MeshHits>{cam, tracer, vol.origin, 1.0f / vol.voxel, out});
    } else {
      const Tracer<TrilinearField, 16, NoMeshes> tracer{tri, occ, box, env, ts};
      parallel_for(name, items, RaycastPixels<TrilinearField, NoMeshes>{cam, tracer, vol.origin, 1.0f / vol.voxel, out});
    }
    mark("trace");
  }

  // screen_space: depth of the spheres, bilateral filter, two-sided shading.
  void screen_space(const RenderInput& in, const Camera& cam, const Environment& env, const RenderSettings& rs,
                    uint32_t* out) {
    if (in.particles.n > 0 && !in.particles.pos) throw std::logic_error("renderer: screen_space needs the particles");
    if (!(in.spacing > 0)) throw std::logic_error("renderer: screen_space needs the particle spacing");
    const uint32_t n_pix = uint32_t(width_) * uint32_t(height_);
    for (auto* v : {&front_, &back_, &front2_, &back2_})
      if (v->size() < n_pix) v->resize(n_pix);
    const float r = float(rs.sphere_radius * in.spacing);
    const ViewFrame view{cam};
    parallel_for("screen_clear", n_pix, ClearDepth{raw(front_), raw(back_)});
    if (in.particles.n > 0)
      parallel_for("screen_depth", in.particles.n, SplatSpheres{view, in.particles.pos, r, raw(front_), raw(back_)});
    mark("depth");
    BilateralDepth f = BilateralDepth::weights(width_, height_, rs.filter_width, r);
    uint32_t *fa = raw(front_), *ba = raw(back_), *fb = raw(front2_), *bb = raw(back2_);
    for (int it = 0; it < rs.filter_iterations; ++it) {
      f.in_front = fa;
      f.in_back = ba;
      f.out_front = fb;
      f.out_back = bb;
      parallel_for("screen_filter", n_pix, f);
      std::swap(fa, fb);
      std::swap(ba, bb);
    }
    mark("filter");
    const ShadeTwoSided shade{view,
                              env,
                              in.setup->geom,
                              fa,
                              ba,
                              r,
                              rs.ior,
                              Rgb{float(rs.absorption.x), float(rs.absorption.y), float(rs.absorption.z)},
                              Rgb{float(rs.tint.x), float(rs.tint.y), float(rs.tint.z)},
                              rs.secant_steps,
                              out};
    parallel_for("screen_shade", PixelTiles{width_, height_}.items(), shade);
    mark("shade");
  }

  ObstacleSet obstacles_;  // set_obstacles
  Vector<uint32_t> image_;
  Vector<uint8_t> occupancy_;
  Vector<uint32_t> front_, back_, front2_, back2_;  // screen_space depth maps (float bits), ping-pong
  std::vector<const char*> stage_names_;
  std::vector<std::pair<std::string, double>> stages_;
  uint32_t* target_ = nullptr;
  int width_ = 0, height_ = 0;
  StageClock clock_;
  double ms_ = 0;
};
