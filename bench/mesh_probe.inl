// bench mesh's timed work, written once for both backends (bench/mesh.h).

struct CollidePaths {
  Obstacles obstacles;
  const Float4* from;
  const Float4* to;
  Float4* out;
  uint32_t* stopped;
  SPHRAY_HD void operator()(uint32_t i) const {
    Vec3f x = xyz(to[i]);
    const Stop stop = stop_at_obstacles(obstacles, xyz(from[i]), x, 0.0f, 0.0f);
    out[i] = {x.x, x.y, x.z, 0.0f};
    stopped[i] = stop.hit() ? 1u : 0u;
  }
};

class MeshProbeImpl final : public MeshProbe {
 public:
  double build(const std::vector<Vec3f>& vertices, const std::vector<uint32_t>& indices) override {
    bvh_ = make_bvh(kBackend, vertices, indices);
    return bvh_->last_ms();
  }
  double refit(const std::vector<Vec3f>& vertices) override {
    bvh_->refit(vertices);
    return bvh_->last_ms();
  }
  void set_paths(const std::vector<Vec3f>& from, const std::vector<Vec3f>& to) override {
    auto f4 = [](const std::vector<Vec3f>& v) {
      std::vector<Float4> o(v.size());
      for (size_t i = 0; i < v.size(); ++i) o[i] = {v[i].x, v[i].y, v[i].z, 0.0f};
      return o;
    };
    upload(from_, f4(from));
    upload(to_, f4(to));
    out_.resize(from.size());
    stopped_.resize(from.size());
  }
  double collide(uint32_t& stopped) override {
    Obstacles obs;
    obs.mesh[0] = bvh_->view();
    obs.count = 1;
    obs.offset = 1e-4f;
    const uint32_t n = uint32_t(from_.size());
    clock_.start();
    parallel_for("bench_collide", n, CollidePaths{obs, raw(from_), raw(to_), raw(out_), raw(stopped_)});
    clock_.end_of("collide");
    clock_.finish();
    stopped = thrust::reduce(policy(), stopped_.begin(), stopped_.end(), 0u);
    return clock_.ms("collide");
  }

 private:
  std::unique_ptr<Bvh> bvh_;
  Vector<Float4> from_, to_, out_;
  Vector<uint32_t> stopped_;
  StageClock clock_;
};
