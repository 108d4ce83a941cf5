#include "driven.h"

#include <cstring>
#include <stdexcept>
#include <string>

#include "slab_solver.h"
#include "sph/forwarding_solver.h"

namespace sphray {

namespace {

// One call, as rank 0 broadcasts it: an opcode and its argument's bytes.
enum Op : char { kStep = 's', kGather = 'g', kPresence = 'p', kNew = 'n', kQuit = 'q' };

std::string encode(Op op, double arg = 0.0) {
  std::string m(1 + sizeof(double), '\0');
  m[0] = op;
  std::memcpy(&m[1], &arg, sizeof(double));
  return m;
}

double argument(const std::string& m) {
  double v = 0;
  if (m.size() == 1 + sizeof(double)) std::memcpy(&v, &m[1], sizeof(double));
  return v;
}

void tell(Comm& comm, Op op, double arg = 0.0) {
  std::string m = encode(op, arg);
  comm.broadcast(m, 0);
}

class DrivingSolver final : public ForwardingSolver {
 public:
  DrivingSolver(std::unique_ptr<Solver> inner, Comm& comm) : ForwardingSolver(std::move(inner)), comm_(comm) {}

  void step(double until) override {
    tell(comm_, kStep, until);
    inner_->step(until);
  }
  void gather_frame() override {
    tell(comm_, kGather);
    inner_->gather_frame();
  }
  void set_presence(PresenceMode mode) override {
    tell(comm_, kPresence, double(int(mode)));
    inner_->set_presence(mode);
  }
  // Rank 0 cannot change the cut alone.
  void set_slab(const SlabBounds&) override { throw std::logic_error("a driven run's cuts are the slab solver's"); }

 private:
  Comm& comm_;
};

}  // namespace

std::unique_ptr<Solver> drive_from_root(std::unique_ptr<Solver> slab, Comm& comm) {
  if (comm.rank() != 0) throw std::logic_error("drive_from_root on a rank other than 0");
  return std::make_unique<DrivingSolver>(std::move(slab), comm);
}

void tell_new_solver(Comm& comm) { tell(comm, kNew); }

void tell_quit(Comm& comm) { tell(comm, kQuit); }

void serve_root(Comm& comm, const std::function<std::unique_ptr<Solver>()>& make) {
  if (comm.rank() == 0) throw std::logic_error("serve_root on rank 0");
  std::unique_ptr<Solver> solver = make();
  for (;;) {
    std::string m;
    comm.broadcast(m, 0);
    if (m.empty()) throw std::runtime_error("rank " + std::to_string(comm.rank()) + ": an empty call from rank 0");
    switch (m[0]) {
      case kStep:
        try {
          solver->step(argument(m));
        } catch (const RanksStopped&) {
          // Rank 0 reports it and decides what follows (the viewer pauses).
        }
        break;
      case kGather: solver->gather_frame(); break;
      case kPresence: solver->set_presence(PresenceMode(int(argument(m)))); break;
      case kNew:
        solver.reset();  // its buffers first
        solver = make();
        break;
      case kQuit: return;
      default: throw std::runtime_error("rank " + std::to_string(comm.rank()) + ": an unknown call from rank 0");
    }
  }
}

}  // namespace sphray
