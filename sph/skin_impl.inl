// The skins' waves on one backend (sph/skin.h), included by solver_cpu.cpp
// and solver_cuda.cu inside their backend namespace.

class SkinSetImpl final : public SkinSet {
 public:
  SkinSetImpl(std::vector<SkinGeometry> geo, const SphParams& prm) : prm_(prm) {
    geo_ = std::move(geo);
    buf_.resize(geo_.size());
    for (size_t k = 0; k < geo_.size(); ++k) {
      const SkinGeometry& g = geo_[k];
      Buffers& b = buf_[k];
      upload(b.point, g.point);
      upload(b.neighbour, g.neighbour);
      upload(b.coef, g.coef);
      const std::vector<float> zero(g.point.size(), 0.0f);
      upload(b.h, zero);
      upload(b.v, zero);
      upload(b.load, zero);
      upload(b.sum, std::vector<float>(2 * g.point.size(), 0.0f));
    }
  }

  void advance(const ParticleView& p, const float* pressure, double t, double dt) override {
    clock_.start();
    for (size_t k = 0; k < geo_.size(); ++k) {
      const SkinGeometry& g = geo_[k];
      Buffers& b = buf_[k];
      const uint32_t n = uint32_t(g.point.size());
      if (pressure && p.n > 0) {
        parallel_for("skin_load_sums", n * uint32_t(kCandidateRows),
                     SampleSkinLoad{raw(b.point), g.input.motion.at(float(t)), p.grid, p.fine_offsets, p.pos, pressure,
                                    prm_.kernel, prm_.particle_mass, prm_.gravity, raw(b.sum)});
        parallel_for("skin_load", n, SkinLoadOf{raw(b.sum), raw(b.load)});
      }
      if (!(dt > 0.0)) continue;
      const SkinParams& sp = g.input.params;
      const float omega = float(2.0 * M_PI * sp.frequency);
      const int sub = int(std::ceil(dt / g.max_substep));
      const float h = float(dt / sub);
      for (int s = 0; s < sub; ++s) {
        parallel_for("skin_accelerate", n,
                     SkinAccelerate{raw(b.h), raw(b.v), raw(b.load), raw(b.neighbour), raw(b.coef), omega * omega,
                                    omega * omega * sp.compliance, sp.damping, h});
        parallel_for("skin_move", n, SkinMove{raw(b.h), raw(b.v), h});
      }
    }
    clock_.end_of("skin");
    clock_.finish();
    ms_ = clock_.ms("skin");
    if (++advances_ % kSkinCheckEvery == 0) check(t);
  }

  std::vector<float> heights(size_t k) const override { return sphray::SPHRAY_BK::download(buf_[k].h, buf_[k].h.size()); }
  std::vector<float> loads(size_t k) const override {
    return sphray::SPHRAY_BK::download(buf_[k].load, buf_[k].load.size());
  }
  void set_heights(size_t k, const std::vector<float>& h) override {
    if (h.size() != geo_[k].point.size()) throw std::invalid_argument("skin: one height per texel expected");
    upload(buf_[k].h, h);
    upload(buf_[k].v, std::vector<float>(h.size(), 0.0f));
  }
  double last_ms() const override { return ms_; }

 private:
  void check(double t) {
    for (size_t k = 0; k < geo_.size(); ++k) {
      const uint32_t n = uint32_t(geo_[k].point.size());
      transform_reduce_into(n, SkinAbsHeight{raw(buf_[k].h)}, SkinMax(), 0.0f, raw(peak_));
      const float peak = read_one(peak_, 0);
      if (!(peak <= 0.25 * geo_[k].size)) {
        std::ostringstream os;
        os << "obstacles." << geo_[k].input.obstacle << ".skin: its waves grew without bound (|h| = " << peak
           << " m on a mesh " << geo_[k].size << " m across, t = " << t
           << " s): raise its damping, lower its compliance, or use the \"surface\" stencil";
        throw SimulationError(os.str());
      }
    }
  }

  struct Buffers {
    Vector<Vec3f> point;
    Vector<uint32_t> neighbour;
    Vector<float> coef, h, v, load;
    Vector<float> sum;  // 2 per texel: the load's kernel-weighted sums (SampleSkinLoad)
  };
  SphParams prm_;
  std::vector<Buffers> buf_;
  StageClock clock_;
  double ms_ = 0;
  uint64_t advances_ = 0;
  Vector<float> peak_ = Vector<float>(1);
};
