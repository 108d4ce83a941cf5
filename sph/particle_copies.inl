// Host copies of a solver's sorted fluid arrays, written once for both
// solvers and both backends. Included inside a backend namespace (which
// supplies Vector, raw, download, AsyncDownload) by solver_impl.inl.

// The fluid state as HostParticles (solver.h); presence null: none.
inline HostParticles download_particles(const Vector<uint32_t>& id, const Vector<Float4>& pos,
                                        const Vector<Float4>& vel, const Vector<float>* presence, uint32_t n) {
  HostParticles h;
  h.id = sphray::SPHRAY_BK::download(id, n);
  const auto p = sphray::SPHRAY_BK::download(pos, n), v = sphray::SPHRAY_BK::download(vel, n);
  h.pos.resize(n); h.vel.resize(n); h.density.resize(n);
  for (size_t i = 0; i < n; ++i) {
    h.pos[i] = xyz(p[i]);
    h.vel[i] = xyz(v[i]);
    h.density[i] = p[i].w;
  }
  if (presence) {
    const auto pr = sphray::SPHRAY_BK::download(*presence, 6 * size_t(n));
    h.presence.resize(n);
    for (size_t i = 0; i < n; ++i)
      for (size_t k = 0; k < 6; ++k) h.presence[i][k] = pr[k * n + i];
  }
  return h;
}

// FlowSums (solver.h) over the first n particles, on the backend; status
// (or null) marks a decomposed run's ghosts, which are left out.
struct FlowSumsOf {
  const Float4* pos;
  const Float4* vel;
  const uint8_t* status;
  SPHRAY_HD FlowSums operator()(uint32_t i) const {
    if (status && status[i] == kStatusGhost) return FlowSums{};
    const Float4 v = vel[i];
    return {double(pos[i].x), double(v.x) * v.x + double(v.y) * v.y + double(v.z) * v.z};
  }
};
struct CombineFlowSums {
  SPHRAY_HD FlowSums operator()(const FlowSums& a, const FlowSums& b) const {
    return {a.max_x > b.max_x ? a.max_x : b.max_x, a.speed2_sum + b.speed2_sum};
  }
};
inline FlowSums reduce_flow_sums(uint32_t n, const Vector<Float4>& pos, const Vector<Float4>& vel,
                                 const Vector<uint8_t>& status) {
  Vector<FlowSums> out(1);
  transform_reduce_into(n, FlowSumsOf{raw(pos), raw(vel), raw(status)}, CombineFlowSums(), FlowSums{}, raw(out));
  return read_one(out, 0);
}

// download_raw's copies (solver.h, RawParticles): on CUDA they run behind the
// next steps (AsyncDownload), and out.ready waits for them. The staging
// buffers are allocated by the first export.
class RawCopies {
 public:
  void take(RawParticles& out, const Vector<Float4>& pos, const Vector<Float4>& vel, const Vector<uint32_t>& id,
            const Vector<float>* presence, uint32_t n, bool velocity) {
    snapshot_.begin();
    auto copy = [&](const auto& src, auto& staging, auto& dst, size_t count) {
      dst.resize(count);  // pinned memory on CUDA (host_memory.h)
      if (count) snapshot_.copy(src, count, staging, dst.data());
    };
    copy(pos, pos_, out.pos, n);
    copy(id, id_, out.id, n);
    if (velocity) copy(vel, vel_, out.vel, n);
    else out.vel.clear();
    if (presence) copy(*presence, presence_, out.presence, 6 * size_t(n));
    else out.presence.clear();
    out.ready = snapshot_.done();
  }
  size_t bytes() const {
    return (pos_.size() + vel_.size()) * sizeof(Float4) + id_.size() * sizeof(uint32_t) + presence_.size() * sizeof(float);
  }

 private:
  AsyncDownload snapshot_;
  Vector<Float4> pos_, vel_;
  Vector<uint32_t> id_;
  Vector<float> presence_;
};

// The static wall particles' positions.
inline std::vector<Vec3f> download_positions(const Vector<Float4>& pts) {
  const auto b = sphray::SPHRAY_BK::download(pts, pts.size());
  std::vector<Vec3f> out(b.size());
  for (size_t k = 0; k < b.size(); ++k) out[k] = xyz(b[k]);
  return out;
}
