// sphray: the command line. Flags become options and one call into the
// library per command (apps/cmd_*.cpp); every user error becomes one line on
// stderr and exit code 2, a failed run exit code 1.
#include <cstdio>
#include <string>

#include "cli.h"
#include "commands.h"
#include "core/background.h"
#include "dist/slab_solver.h"
#include "io/frames_h5.h"
#include "io/scene.h"
#include "sph/solver.h"

using namespace sphray;

int main(int argc, char** argv) {
  CLI::App app{"sphray: SPH liquids on the GPU, rendered as refracting metaballs"};
  app.require_subcommand(1);
  int exit_code = 0;
  const CLI::App* run = cli::add_run_command(app, exit_code);
  cli::add_render_command(app, exit_code);
  cli::add_view_command(app, exit_code);
  cli::add_inspect_command(app, exit_code);
  cli::add_bench_command(app, exit_code);

  // CLI11's own errors (an option's range, a missing value) in sphray's form.
  app.failure_message([](const CLI::App* a, const CLI::Error& e) {
    return "sphray: error: " + CLI::FailureMessage::simple(a, e);
  });
  if (const std::string unknown = cli::unknown_command(app, argc, argv); !unknown.empty()) {
    std::fprintf(stderr, "sphray: error: %s\n", unknown.c_str());
    return 2;
  }
  // Each process of a launcher would run its own copy of any other command.
  if (launcher_size() > 1 && (argc < 2 || (std::string(argv[1]) != "run" && std::string(argv[1]) != "view"))) {
    std::fprintf(stderr, "sphray: error: only 'sphray run' and 'sphray view' run over several ranks (started as one "
                         "of %d)\n", launcher_size());
    return 2;
  }
  // In a run over several ranks (dist/): a failed step is raised on every
  // rank alike (RanksStopped), and rank 0 reports it; any other error may be
  // this rank's alone, so it is reported with the rank and ends every rank.
  auto fail = [&](const char* what, const char* message, int code) {
    if (several_ranks()) {
      std::fprintf(stderr, "sphray: rank %d: %s: %s\n", world_rank(), what, message);
      std::fflush(stderr);
      abort_ranks(code);
    }
    std::fprintf(stderr, "sphray: %s: %s\n", what, message);
    return code;
  };
  try {
    app.parse(argc, argv);  // runs the command's callback
  } catch (const CLI::ParseError& e) {
    const int rc = app.exit(e);
    return rc == 0 ? 0 : 2;
  } catch (const FrameFileError& e) {
    return fail("error", e.what(), run->parsed() ? 1 : 2);  // a failed write during a run; a bad file given to read
  } catch (const OutputError& e) {  // PNG, CSV or JSON not written after the run began (a full disk)
    return fail("error", e.what(), 1);
  } catch (const SceneError& e) {
    return fail("error", e.what(), 2);
  } catch (const RanksStopped& e) {
    if (world_rank() == 0) std::fprintf(stderr, "sphray: simulation stopped: %s\n", e.what());
    return 1;
  } catch (const SimulationError& e) {
    return fail("simulation stopped", e.what(), 1);
  } catch (const std::exception& e) {
    return fail("error", e.what(), 2);
  }
  return exit_code;
}
