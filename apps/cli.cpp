#include "cli.h"

#include <cctype>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <sstream>
#include <stdexcept>

#include "core/background.h"

namespace sphray::cli {

std::vector<size_t> parse_sizes(const std::string& text) {
  std::vector<size_t> out;
  std::stringstream ss(text);
  for (std::string item; std::getline(ss, item, ',');) {
    double mult = 1;
    if (!item.empty() && (item.back() == 'k' || item.back() == 'K')) { mult = 1e3; item.pop_back(); }
    else if (!item.empty() && (item.back() == 'm' || item.back() == 'M')) { mult = 1e6; item.pop_back(); }
    size_t used = 0;
    double v = 0;
    try { v = std::stod(item, &used); } catch (...) { used = 0; }
    if (used != item.size() || !(v > 0) || v * mult > 1e9)
      throw std::runtime_error("--sizes: '" + item + "' is not a particle count (e.g. 125k,1M)");
    out.push_back(size_t(v * mult));
  }
  if (out.empty()) throw std::runtime_error("--sizes: empty list");
  return out;
}

std::pair<int, int> parse_wxh(const std::string& text, const char* option) {
  const size_t x = text.find('x');
  int w = 0, h = 0;
  size_t uw = 0, uh = 0;
  try {
    w = std::stoi(text.substr(0, x), &uw);
    h = std::stoi(text.substr(x + 1), &uh);
  } catch (...) {
    uw = 0;
  }
  if (x == std::string::npos || uw != x || uh != text.size() - x - 1)
    throw std::runtime_error(std::string(option) + " '" + text + "': must be WIDTHxHEIGHT, e.g. 1280x720");
  return {w, h};
}

void add_frame_overrides(const FrameArgs& fa, std::vector<std::string>& sets) {
  if (!fa.size.empty()) {
    const auto [w, h] = parse_wxh(fa.size, "--size");
    sets.push_back("render.width=" + std::to_string(w));
    sets.push_back("render.height=" + std::to_string(h));
  }
  if (fa.every > 0) sets.push_back("render.frames_every=" + std::to_string(fa.every));
}

// Writes j and closes the file, checking both: an ofstream's write error
// shows only when its buffer reaches the disk, here at close.
void write_json(std::ofstream& f, const nlohmann::json& j, const std::string& flag, const std::string& path) {
  errno = 0;
  f << j.dump(2) << "\n";
  f.close();
  if (!f) throw OutputError(write_failure(flag, path));
}

// The files a command writes must be neither its input nor each other: `run
// dam.json --export dam.json` replaced the scene with the export, and two
// outputs on one path would interleave. Each pair is {flag, path}; the first
// is the input. Paths compare after resolving symbolic links and `..`, and
// existing files also by identity (hard links).
void check_distinct_files(const std::vector<std::pair<std::string, std::string>>& files) {
  namespace fs = std::filesystem;
  auto same = [](const std::string& a, const std::string& b) {
    std::error_code e1, e2, e3;
    if (fs::weakly_canonical(a, e1) == fs::weakly_canonical(b, e2) && !e1 && !e2) return true;
    return fs::exists(a, e1) && fs::exists(b, e2) && fs::equivalent(a, b, e3) && !e3;
  };
  for (size_t i = 1; i < files.size(); ++i) {
    if (files[i].second.empty()) continue;
    for (size_t k = 0; k < i; ++k)
      if (!files[k].second.empty() && same(files[i].second, files[k].second))
        throw std::runtime_error(files[i].first + ": '" + files[i].second + "' is " +
                                 (k == 0 ? "the " + files[0].first + " itself" : "also " + files[k].first) +
                                 "; not overwritten");
  }
}

bool is_png_path(const std::string& p) {
  return p.size() > 4 && (p.compare(p.size() - 4, 4, ".png") == 0 || p.compare(p.size() - 4, 4, ".PNG") == 0);
}

// sphray writes PNG only: an image name of another format would have become a
// directory of PNGs (--out) or PNG bytes under a .jpg name (--screenshot).
// `or_else`: what else the option accepts, for the message.
void check_not_other_image(const std::string& path, const char* flag, const char* or_else) {
  std::string ext = std::filesystem::path(path).extension().string();
  for (char& c : ext) c = char(std::tolower(static_cast<unsigned char>(c)));
  for (const char* other : {".jpg", ".jpeg", ".bmp", ".tga", ".gif", ".tif", ".tiff", ".exr", ".hdr", ".ppm", ".webp"})
    if (ext == other)
      throw std::runtime_error(std::string(flag) + " '" + path + "': sphray writes PNG images; give a .png name" +
                               or_else);
}

// A file we are about to write after a long computation: fail now if we cannot.
void check_writable(const std::string& path, const char* flag) {
  const bool existed = std::filesystem::exists(path);
  errno = 0;
  std::FILE* f = std::fopen(path.c_str(), "ab");
  if (!f) throw std::runtime_error(write_failure(flag, path));
  std::fclose(f);
  if (!existed) std::remove(path.c_str());
}

// CLI11 answers a mistyped command ("sphray rnu x.json", "sphray bench simm")
// with "A subcommand is required". Names the word it did not know and the
// commands there are; empty when the command words are all known.
std::string unknown_command(CLI::App& app, int argc, char** argv) {
  CLI::App* level = &app;
  for (int i = 1; i < argc; ++i) {
    const std::string word = argv[i];
    const std::vector<CLI::App*> subs = level->get_subcommands([](CLI::App*) { return true; });
    if (word.empty() || word[0] == '-' || subs.empty()) return "";  // options, or a command's own arguments
    CLI::App* next = nullptr;
    std::string names;
    for (CLI::App* s : subs) {
      names += (names.empty() ? "" : ", ") + s->get_name();
      if (s->check_name(word)) next = s;
    }
    if (!next)
      return "unknown command '" + word + "'" + (level == &app ? "" : " after '" + level->get_name() + "'") +
             ": one of " + names;
    level = next;
  }
  return "";
}

}  // namespace sphray::cli
