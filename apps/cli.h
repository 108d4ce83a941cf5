// What every sphray command shares: flags turned into scene overrides, output
// files opened and checked before the work, and the checks that keep a
// command from writing over its input. Errors are std::runtime_error (bad
// input, exit 2) or OutputError (a write that failed after the run began, exit 1).
#pragma once

#include <fstream>
#include <string>
#include <utility>
#include <vector>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include "pipeline/sinks.h"  // open_output, write_failure

namespace sphray::cli {

// "125k,1M,4000" -> particle counts.
std::vector<size_t> parse_sizes(const std::string& text);

struct FrameArgs {
  std::string dir;   // --frames-dir
  std::string size;  // --size WxH
  int every = 0;     // --frames-every (0: the scene's render.frames_every)
};

// "WIDTHxHEIGHT" -> {w, h}; the range is checked by whoever uses it.
std::pair<int, int> parse_wxh(const std::string& text, const char* option);
// --size WxH and --frames-every as scene overrides (so the run's scene records them).
void add_frame_overrides(const FrameArgs& fa, std::vector<std::string>& sets);

// Writes j and closes the file, checking both: an ofstream's write error
// shows only when its buffer reaches the disk, here at close.
void write_json(std::ofstream& f, const nlohmann::json& j, const std::string& flag, const std::string& path);
// The files a command writes must be neither its input nor each other. Each
// pair is {flag, path}; the first is the input.
void check_distinct_files(const std::vector<std::pair<std::string, std::string>>& files);

bool is_png_path(const std::string& p);
// sphray writes PNG only: an image name of another format is refused.
// `or_else`: what else the option accepts, for the message.
void check_not_other_image(const std::string& path, const char* flag, const char* or_else = "");
// A file we are about to write after a long computation: fail now if we cannot.
void check_writable(const std::string& path, const char* flag = "--out");

// Names the word of a mistyped command and the commands there are; empty
// when the command words are all known.
std::string unknown_command(CLI::App& app, int argc, char** argv);

}  // namespace sphray::cli
