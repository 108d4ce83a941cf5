// What the two incompressible solvers (pbf_solver.inl, dfsph_solver.inl) do
// alike with their particle arrays: the sort by cell, and the guards' reports.
// Included inside a backend namespace (Vector, raw, read_one, parallel_for,
// sort_and_offsets, GatherParticles) after solver_impl.inl.

// A solver's sorted particle arrays and their scratch twins; `flow` is its
// own per-particle Float4 (PBF: x*, lambda; DFSPH: the warm-start pressures).
struct FlowArrays {
  Vector<Float4>&pos, &vel, &flow, &pos_tmp, &vel_tmp, &flow_tmp;
  Vector<uint32_t>&id, &id_tmp;
  Vector<uint8_t>&status, &status_tmp;
  Vector<float>&presence, &presence_tmp;
};

// Sorts every array by the cell of `by` (one of them, read before the
// gather), carrying presence when `carry_presence`, and drops the particles
// outside the grid (an open top only). Returns how many stay.
inline uint32_t sort_flow_particles(const char* const (&names)[2], const GridGeom& grid, bool open_top, uint32_t n,
                                    const Vector<Float4>& by, bool carry_presence, FlowArrays a, Vector<uint32_t>& keys,
                                    Vector<uint32_t>& order, Vector<uint32_t>& fine_offsets, Vector<uint32_t>& offsets) {
  parallel_for(names[0], n, KeyOf<Float4>{grid, raw(by), raw(keys)});
  sort_and_offsets(grid, n, keys, order, fine_offsets, &offsets);
  const uint32_t active = open_top ? read_one(offsets, grid.num_cells()) : n;
  const ConstParticleArrays in{raw(a.pos), raw(a.vel), raw(a.flow), raw(a.id), raw(a.status),
                               carry_presence ? raw(a.presence) : nullptr};
  const ParticleArrays out{raw(a.pos_tmp), raw(a.vel_tmp), raw(a.flow_tmp), raw(a.id_tmp), raw(a.status_tmp),
                           raw(a.presence_tmp)};
  parallel_for(names[1], active, GatherParticles{raw(order), in, n, out, active});
  a.pos.swap(a.pos_tmp); a.vel.swap(a.vel_tmp); a.flow.swap(a.flow_tmp); a.id.swap(a.id_tmp);
  a.status.swap(a.status_tmp);
  if (carry_presence) a.presence.swap(a.presence_tmp);
  return active;
}

// A non-finite value, or a density error that no longer means anything (the
// liquid compressed to twice its rest density on average), ends the run:
// throws SimulationError naming the step (and the particle), with `remedy`.
inline void check_flow_state(const char* solver, const char* remedy, const FlowStats& s, uint32_t n, uint64_t steps,
                             double t, const Vector<Float4>& pos, const Vector<Float4>& vel, const Vector<uint32_t>& id) {
  constexpr double kDivergedError = 1.0;
  const double mean = n ? s.error_sum / n : 0.0;
  if (s.first_bad == kNoBadParticle && mean <= kDivergedError) return;
  std::ostringstream os;
  if (s.first_bad != kNoBadParticle) {
    const uint32_t i = s.first_bad;
    const Float4 p = read_one(pos, i), v = read_one(vel, i);
    os << "non-finite position, density or velocity at step " << steps << " (t = " << t << " s) in particle "
       << read_one(id, i) << " (initial index): position (" << p.x << ", " << p.y << ", " << p.z << "), density "
       << p.w << ", velocity (" << v.x << ", " << v.y << ", " << v.z << ").";
  } else {
    os << "the " << solver << " density error diverged at step " << steps << " (t = " << t << " s): mean compression "
       << 100 * mean << "% (largest " << 100 * s.error_max << "%), above " << 100 * kDivergedError << "%.";
  }
  os << " The run is stopped rather than continued with garbage; " << remedy << ".";
  throw SimulationError(os.str());
}

// The three launches of a neighbour pass (mirror_walls.h, MirrorPass), each
// particle served by one; the near-walls launch with the obstacles' wall
// terms where the scene has obstacles' wall particles (`mesh`).
template <template <int> class Pass, class... Args>
void mirror_pass_launches(const char* const (&names)[4], uint32_t n, bool mesh, Args... args) {
  parallel_for(names[kInterior], n, Pass<kInterior>{args...});
  if (mesh) parallel_for(names[kNearMesh], n, Pass<kNearMesh>{args...});
  else parallel_for(names[kNearWalls], n, Pass<kNearWalls>{args...});
  parallel_for(names[kDirect], n, Pass<kDirect>{args...});
}

// The message of a step below run.min_dt.
inline std::string describe_flow_dt_floor(const StepLimits& l, double min_dt, double cfl, double t, uint64_t steps) {
  std::ostringstream os;
  os << "time step " << l.dt << " s fell below the floor run.min_dt = " << min_dt << " s at t = " << t << " s (step "
     << steps << "): max speed " << l.max_speed << " m/s at sph.cfl = " << cfl
     << ". The flow is too fast for this resolution; raise sph.spacing or check the initial state.";
  return os.str();
}
