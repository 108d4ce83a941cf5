// The renderer's driver, written once for both backends. Included by
// render_cpu.cpp and render_cuda.cu inside their backend namespace (which
// supplies Vector, raw, parallel_for, download, StageClock, kBackend).

class RendererImpl final : public Renderer {
 public:
  Backend backend() const override { return kBackend; }
  double last_ms() const override { return ms_; }
  const uint32_t* pixels() const override { return target_ ? target_ : raw(image_); }
  void set_target(uint32_t* p) override { target_ = p; }

  Image download() const override {
    Image img;
    img.width = width_;
    img.height = height_;
    if (target_) throw std::logic_error("renderer: download() of an external target");
    img.rgba = sphray::SPHRAY_BK::download(image_, size_t(width_) * size_t(height_));
    return img;
  }

  void render(const float* field, const FieldSetup& fs, const Camera& cam, const Environment& env,
              const RenderSettings& rs) override {
    if (cam.width <= 0 || cam.height <= 0) throw std::invalid_argument("renderer: empty image");
    width_ = cam.width;
    height_ = cam.height;
    const uint32_t n_pix = uint32_t(width_) * uint32_t(height_);
    if (!target_ && image_.size() < n_pix) image_.resize(n_pix);
    const VolumeGeom& vol = fs.geom;
    const int brick = 1 << vol.refine;  // bricks as wide as the SPH cells: 1 voxel at refine 0, 4 at refine 2
    Occupancy occ{nullptr, (vol.nx + brick - 1) / brick, (vol.ny + brick - 1) / brick, (vol.nz + brick - 1) / brick,
                  brick};
    clock_.start();
    if (rs.skip_empty) {
      const uint32_t bricks = uint32_t(occ.cx) * uint32_t(occ.cy) * uint32_t(occ.cz);
      if (occupancy_.size() < bricks) occupancy_.resize(bricks);
      parallel_for("render_occupancy", bricks,
                   BuildOccupancy{field, vol.nx, vol.ny, vol.nz, brick, fs.shape.iso, raw(occupancy_)});
      occ.occ = raw(occupancy_);
    }
    Tracer<TrilinearField> tracer{TrilinearField{field, vol.nx, vol.ny, vol.nz}, occ,
                                  Vec3f{float(vol.nx), float(vol.ny), float(vol.nz)}, env,
                                  make_trace_settings(rs, fs)};
    parallel_for("render_raycast", PixelTiles{width_, height_}.items(), RaycastPixels<TrilinearField>{cam, tracer, vol.origin, 1.0f / vol.voxel,
                                                      target_ ? target_ : raw(image_)});
    clock_.end_of("render");
    clock_.finish();
    ms_ = clock_.ms("render");
  }

 private:
  Vector<uint32_t> image_;
  Vector<uint8_t> occupancy_;
  uint32_t* target_ = nullptr;
  int width_ = 0, height_ = 0;
  StageClock clock_;
  double ms_ = 0;
};
