// The wall particles of a solver, written once for both backends: WCSPH's
// (the tank's layers and the obstacles' skins, boundary.h) and PBF's and
// DFSPH's (the obstacles' skins only, mesh_walls.h). Included by
// solver_impl.inl inside the backend namespace.

// The wall particles of moving obstacles into their pose at the step's end
// (the obstacles' Motion at time + dt, dt from the device's choice; Control:
// StepControl or FlowControl).
template <class Control>
struct MoveWalls {
  Obstacles obstacles;
  const Control* control;  // null: at obstacles.time itself
  const Float4* body;      // each wall particle at t = 0
  const uint8_t* owner;    // its moving obstacle, or kStaticWall
  Float4* pos;
  Float4* vel;  // the velocity over the step (static walls: zero, set once)
  SPHRAY_HD void operator()(uint32_t b) const {
    const uint8_t k = owner[b];
    if (k == kStaticWall) return;
    const float dt = control ? float(control->limits.dt) : 0.0f;
    const Float4 p = body[b];
    const Motion& m = obstacles.motion[k];
    const Vec3f w = m.at(obstacles.time + dt).to_world(xyz(p));
    const Vec3f v = dt > 0.0f ? (w - m.at(obstacles.time).to_world(xyz(p))) * (1.0f / dt) : Vec3f{0, 0, 0};
    pos[b] = {w.x, w.y, w.z, p.w};
    vel[b] = {v.x, v.y, v.z, 0.0f};
  }
};

// The wall particles sorted by the solver's grid, with what they carry
// (WCSPH's viscosity per particle; where obstacles move, each one's t = 0
// pose, owner and velocity), their slab table and cell flags (CellsNear).
// Sorted once unless obstacles move them (move()).
class WallParticles {
 public:
  WallParticles(const SolverInput& in, const GridGeom& grid) : grid_(grid) {
    const uint32_t nb = uint32_t(in.boundary.size());
    upload(pos_, in.boundary);
    if (!in.boundary_alpha.empty()) upload(alpha_, in.boundary_alpha);
    offsets_.assign(size_t(grid_.num_fine_cells()) + 1, 0u);  // as they stay without walls
    near_.assign(grid_.num_cells(), uint8_t(0));
    if (!in.boundary_obstacle.empty()) {
      upload(owner_, in.boundary_obstacle);
      moving_ = thrust::count(policy(), owner_.begin(), owner_.end(), kStaticWall) != ptrdiff_t(nb);
    }
    if (moving_) {
      body_ = pos_;
      vel_.assign(nb, Float4{0, 0, 0, 0});
    } else {
      owner_ = {};
    }
    sort();
    if (!moving_) {  // the scratch of the sort is not needed again
      keys_ = {}; order_ = {}; pos_tmp_ = {}; alpha_tmp_ = {};
    }
  }

  uint32_t size() const { return uint32_t(pos_.size()); }
  const Float4* pos() const { return raw(pos_); }
  const float* alpha() const { return raw(alpha_); }
  const uint32_t* offsets() const { return raw(offsets_); }
  const uint8_t* near() const { return raw(near_); }
  const Float4* vel() const { return moving_ ? raw(vel_) : nullptr; }
  // The incompressible solvers' view (mesh_walls.h): no flags where there are no walls.
  WallsView view() const { return {grid_, raw(offsets_), raw(pos_), vel(), size() ? raw(near_) : nullptr}; }
  std::vector<Vec3f> positions() const { return download_positions(pos_); }

  // The walls of moving obstacles to their pose at obstacles.time + the
  // step's dt (control), then sorted again; nothing where none moves.
  template <class Control>
  void move(const Obstacles& obstacles, const Control* control) {
    if (!moving_) return;
    parallel_for("wall_motion", size(), MoveWalls<Control>{obstacles, control, raw(body_), raw(owner_), raw(pos_), raw(vel_)});
    sort();
  }

  size_t bytes() const {
    auto b = [](const auto& v) { return v.size() * sizeof(typename std::decay_t<decltype(v)>::value_type); };
    return b(pos_) + b(alpha_) + b(offsets_) + b(near_) + b(body_) + b(vel_) + b(owner_) + b(pos_tmp_) +
           b(alpha_tmp_) + b(body_tmp_) + b(vel_tmp_) + b(owner_tmp_) + b(keys_) + b(order_);
  }

 private:
  void sort() {
    const uint32_t nb = size();
    if (nb == 0) return;
    keys_.resize(nb);
    order_.resize(nb);
    parallel_for("wall_keys", nb, KeyOf<Float4>{grid_, raw(pos_), raw(keys_)});
    sort_and_offsets(grid_, nb, keys_, order_, offsets_, nullptr);
    auto regather = [&](auto& v, auto& tmp) {
      if (v.empty()) return;
      tmp.resize(nb);
      thrust::gather(policy(), order_.begin(), order_.end(), v.begin(), tmp.begin());
      v.swap(tmp);
    };
    regather(pos_, pos_tmp_);
    regather(alpha_, alpha_tmp_);
    if (moving_) {
      regather(body_, body_tmp_);
      regather(owner_, owner_tmp_);
      regather(vel_, vel_tmp_);
    }
    parallel_for("wall_cells_near", grid_.num_cells(), CellsNear{grid_, raw(offsets_), raw(near_)});
  }

  GridGeom grid_;
  bool moving_ = false;
  Vector<Float4> pos_, pos_tmp_, body_, body_tmp_, vel_, vel_tmp_;  // pos_: x, y, z, volume
  Vector<float> alpha_, alpha_tmp_;                                 // WCSPH: wall viscosity per particle
  Vector<uint8_t> owner_, owner_tmp_, near_;
  Vector<uint32_t> keys_, order_, offsets_;
};
