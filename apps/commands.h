// The commands of `sphray`, one file each: each adds its subcommand to the
// application and sets the callback that runs it, which leaves the exit code
// in `exit_code` (errors are thrown; main turns them into a message and an
// exit code).
#pragma once

#include <CLI/CLI.hpp>

namespace sphray::cli {

CLI::App* add_run_command(CLI::App& app, int& exit_code);
CLI::App* add_render_command(CLI::App& app, int& exit_code);
CLI::App* add_view_command(CLI::App& app, int& exit_code);
CLI::App* add_inspect_command(CLI::App& app, int& exit_code);
CLI::App* add_bench_command(CLI::App& app, int& exit_code);

}  // namespace sphray::cli
